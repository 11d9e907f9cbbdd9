"""The shape-tree of an open or closed curve (paper §2) and random deformations (§2.1).

Indexing convention
-------------------
A curve with ``n`` sample points ``a_0 .. a_{n-1}`` is *unrolled* into a sequence ``U``:
for an open curve ``U = (a_0, ..., a_{n-1})``; for a closed curve the first point is
repeated at the end, ``U = (a_0, ..., a_{n-1}, a_0)`` (the paper's ``a_n = a_1``).
Every node of the tree covers a subcurve ``U[start..end]`` (``end - start >= 2``) and
stores the Bookstein coordinate of ``U[mid]`` relative to ``U[start]`` and ``U[end]``.
Subcurves with ``end - start == 1`` are line segments: they are not nodes.

An open curve has one root covering ``U[0..n-1]``. A closed curve is cut at ``a_0`` and
a midpoint ``a_k`` into two open halves ``U[0..k]`` and ``U[k..n]``, each with its own
shape-tree (two roots); it is reconstructed from the two anchors ``a_0`` and ``a_k``.
Nodes are stored in post-order (children before parents), the order in which the
matching tables are filled.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike

from shapetree._errors import CurveError, ShapeTreeError
from shapetree.curves import as_curve

SPLITS = ("half", "best")


@dataclass(frozen=True, eq=False)
class ShapeTree:
    """Shape-tree of a curve.

    Attributes
    ----------
    points : ndarray, shape (n, 2)
        The curve's sample points (closed curves: without the repeated first point).
    closed : bool
    split : str
        Midpoint rule, ``"half"`` (``mid = start + (end - start) // 2``) or ``"best"``.
    offset : int
        For closed curves, the index of ``points`` that the tree treats as ``a_0`` (trees
        with different offsets split the curve differently; §3 "several shape-trees").
        ``points`` is already rolled by this offset.
    start, mid, end : ndarray of int, shape (K,)
        Indices into the unrolled sequence for each node (post-order).
    left, right : ndarray of int, shape (K,)
        Child node indices, ``-1`` where the child is a line segment.
    depth : ndarray of int, shape (K,)
        Depth of each node (roots have depth 0).
    coords : ndarray, shape (K, 2)
        Bookstein coordinate ``L(U[mid] | U[start], U[end])`` of each node.
    roots : tuple of int
        ``(root,)`` for open curves, ``(root_1, root_2)`` for closed ones (a root is ``-1``
        when that half is a single segment).
    split_index : int
        Closed curves: index ``k`` of the first midpoint ``a_k`` where the curve is cut into
        its two halves ``U[0..k]`` and ``U[k..n]``. Open curves: ``n - 1``.
    """

    points: np.ndarray
    closed: bool
    split: str
    offset: int
    start: np.ndarray
    mid: np.ndarray
    end: np.ndarray
    left: np.ndarray
    right: np.ndarray
    depth: np.ndarray
    coords: np.ndarray
    roots: tuple[int, ...]
    split_index: int

    @property
    def n_points(self) -> int:
        """Number of sample points ``n``."""
        return int(self.points.shape[0])

    @property
    def n_nodes(self) -> int:
        """Number of nodes (midpoints) in the tree: ``n - 2`` for every curve."""
        return int(self.start.shape[0])

    @property
    def unrolled(self) -> np.ndarray:
        """The unrolled point sequence ``U``, shape (n, 2) open or (n + 1, 2) closed."""
        if self.closed:
            return np.vstack([self.points, self.points[:1]])
        return self.points

    @property
    def anchor_indices(self) -> tuple[int, int]:
        """Indices (into ``points``) of the anchors that reconstruction needs."""
        return 0, self.split_index

    @property
    def max_depth(self) -> int:
        """Depth of the deepest node."""
        return int(self.depth.max()) if self.n_nodes else 0

    def levels(self) -> list[np.ndarray]:
        """Node indices grouped by depth, from the roots down."""
        return [np.flatnonzero(self.depth == d) for d in range(self.max_depth + 1)]


def _best_mid(u: np.ndarray, s: int, e: int) -> int:
    """Index in (s, e) whose coarse curve (u_s, u_i, u_e) best approximates U[s..e]."""
    pts = u[s : e + 1]
    errs = np.array(
        [
            _seg_sqdist(pts[1:i], pts[0], pts[i]).sum()
            + _seg_sqdist(pts[i + 1 : -1], pts[i], pts[-1]).sum()
            for i in range(1, e - s)
        ]
    )
    # among (numerically) equal errors prefer the most balanced split: keeps trees shallow
    near = np.flatnonzero(errs <= errs.min() + 1e-12 * (1.0 + errs.min()))
    centre = (e - s) / 2.0
    best_i = s + 1 + int(near[np.argmin(np.abs(near + 1 - centre))])
    return best_i


def _seg_sqdist(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = b - a
    dd = float(d @ d)
    if p.shape[0] == 0:
        return np.zeros(0)
    if dd == 0:
        return np.sum((p - a) ** 2, axis=1)
    t = np.clip(((p - a) @ d) / dd, 0.0, 1.0)
    return np.sum((p - a - t[:, None] * d) ** 2, axis=1)


def _mid(u: np.ndarray, s: int, e: int, split: str) -> int:
    if split == "half":
        return s + (e - s) // 2
    return _best_mid(u, s, e)


def build_shape_tree(
    points: ArrayLike,
    *,
    closed: bool,
    split: str = "half",
    offset: int = 0,
) -> ShapeTree:
    """Build the shape-tree of a curve (paper §2).

    Parameters
    ----------
    points : array_like, shape (n, 2)
        Sample points, ``n >= 3`` (closed curves without a repeated first point).
    closed : bool
        Whether the curve is closed.
    split : {"half", "best"}
        Midpoint rule. ``"half"``: ``mid = start + floor((end - start) / 2)``, the paper's
        ``i = floor(n/2)`` counted in segments (every node halves its subcurve).
        ``"best"``: the sample point whose coarse curve ``(a_start, a_mid, a_end)``
        approximates the subcurve best (least sum of squared distances of the subcurve's
        points to the two-segment polyline); the paper's second option.
    offset : int
        Closed curves only: start the curve at ``points[offset]`` (a different shape-tree
        of the same curve).

    Returns
    -------
    ShapeTree
    """
    if split not in SPLITS:
        raise ShapeTreeError(f"unknown midpoint rule split={split!r}; use one of {SPLITS}")
    pts = as_curve(points, closed=closed, name="shape-tree curve")
    n = pts.shape[0]
    if closed:
        pts = np.roll(pts, -int(offset) % n, axis=0)
    elif offset:
        raise ShapeTreeError("offset is only defined for closed curves")
    u = np.vstack([pts, pts[:1]]) if closed else pts
    last = u.shape[0] - 1
    if split == "best" and n > sys.getrecursionlimit() // 2:
        raise CurveError(f"curve has too many points ({n}) for split='best'; resample it first")

    start: list[int] = []
    mid: list[int] = []
    end: list[int] = []
    left: list[int] = []
    right: list[int] = []
    depth: list[int] = []

    def build(s: int, e: int, d: int) -> int:
        # iterative post-order would avoid recursion; depth is O(log n) for "half" and at
        # most n for "best", well below Python's limit for the curve sizes we use.
        if e - s < 2:
            return -1
        i = _mid(u, s, e, split)
        lc = build(s, i, d + 1)
        rc = build(i, e, d + 1)
        start.append(s)
        mid.append(i)
        end.append(e)
        left.append(lc)
        right.append(rc)
        depth.append(d)
        return len(start) - 1

    if closed:
        if split == "half":
            k = n // 2
        else:
            # the coarse closed curve (a_0, a_k, a_0) approximates best
            k = _best_mid(u, 0, last)
        roots: tuple[int, ...] = (build(0, k, 0), build(k, last, 0))
    else:
        k = last
        roots = (build(0, last, 0),)
    s_a = np.asarray(start, dtype=np.int64)
    m_a = np.asarray(mid, dtype=np.int64)
    e_a = np.asarray(end, dtype=np.int64)
    zs = u[s_a, 0] + 1j * u[s_a, 1]
    zm = u[m_a, 0] + 1j * u[m_a, 1]
    ze = u[e_a, 0] + 1j * u[e_a, 1]
    base = ze - zs
    if np.any(base == 0):
        bad = int(np.flatnonzero(base == 0)[0])
        raise CurveError(
            f"curve passes through the same point twice (indices {s_a[bad]} and {e_a[bad]});"
            " the shape-tree needs distinct subcurve endpoints"
        )
    w = (zm - 0.5 * (zs + ze)) / base
    coords = np.stack([w.real, w.imag], axis=1)
    return ShapeTree(
        points=pts,
        closed=closed,
        split=split,
        offset=int(offset) % n if closed else 0,
        start=s_a,
        mid=m_a,
        end=e_a,
        left=np.asarray(left, dtype=np.int64),
        right=np.asarray(right, dtype=np.int64),
        depth=np.asarray(depth, dtype=np.int64),
        coords=coords,
        roots=roots,
        split_index=int(k),
    )


def reconstruct(
    tree: ShapeTree,
    anchors: ArrayLike | None = None,
    coords: ArrayLike | None = None,
) -> np.ndarray:
    """Rebuild the curve from its shape-tree and anchor points (paper §2).

    Parameters
    ----------
    tree : ShapeTree
    anchors : array_like, shape (2, 2), optional
        Positions of the anchors: open curves ``(a_0, a_{n-1})``; closed curves ``(a_0, a_k)``
        with ``a_k`` the first midpoint (``tree.anchor_indices``). Default: the original
        positions. Moving the anchors gives a similarity-transformed curve.
    coords : array_like, shape (K, 2), optional
        Bookstein coordinates to use instead of ``tree.coords`` (e.g. perturbed ones).

    Returns
    -------
    ndarray, shape (n, 2)
        The curve's points, in the tree's order (rolled by ``tree.offset`` for closed curves).
    """
    n = tree.n_points
    i0, i1 = tree.anchor_indices
    if anchors is None:
        anchors = tree.points[[i0, i1]]
    anc = np.asarray(anchors, dtype=float)
    if anc.shape != (2, 2):
        raise ShapeTreeError(f"anchors must have shape (2, 2), got {anc.shape}")
    if np.allclose(anc[0], anc[1]):
        raise ShapeTreeError("the two anchors must be distinct points")
    c = tree.coords if coords is None else np.asarray(coords, dtype=float)
    if c.shape != (tree.n_nodes, 2):
        raise ShapeTreeError(f"coords must have shape ({tree.n_nodes}, 2), got {c.shape}")
    size = n + 1 if tree.closed else n
    z = np.zeros(size, dtype=complex)
    z[i0] = anc[0, 0] + 1j * anc[0, 1]
    z[i1] = anc[1, 0] + 1j * anc[1, 1]
    if tree.closed:
        z[n] = z[0]
    w = c[:, 0] + 1j * c[:, 1]
    # parents come after children in post-order: walk it backwards (roots first)
    for v in range(tree.n_nodes - 1, -1, -1):
        s, e = tree.start[v], tree.end[v]
        z[tree.mid[v]] = 0.5 * (z[s] + z[e]) + w[v] * (z[e] - z[s])
    z = z[:n]
    return np.stack([z.real, z.imag], axis=1)


def deform(
    tree: ShapeTree,
    scale: float | ArrayLike = 0.1,
    *,
    rng: np.random.Generator | int | None = None,
    anchors: ArrayLike | None = None,
) -> np.ndarray:
    """Random deformation by independent noise on the nodes' Bookstein coordinates (§2.1).

    Each node's Bookstein coordinate gets isotropic Gaussian noise with standard deviation
    ``scale[depth]`` (a single float applies to every depth), then the curve is
    reconstructed from the anchors (paper Fig. 4).

    Parameters
    ----------
    tree : ShapeTree
    scale : float or array_like of shape (max_depth + 1,)
        Noise standard deviation per depth, in Bookstein units (the distance between the
        subcurve's endpoints is 1).
    rng : numpy Generator or int seed, optional
    anchors : array_like, shape (2, 2), optional
        See :func:`reconstruct`.

    Returns
    -------
    ndarray, shape (n, 2)
    """
    gen = np.random.default_rng(rng)
    sc = np.asarray(scale, dtype=float)
    if sc.ndim == 0:
        sigma = np.full(tree.n_nodes, float(sc))
    else:
        if sc.shape[0] < tree.max_depth + 1:
            raise ShapeTreeError(
                f"scale has {sc.shape[0]} depths but the tree has {tree.max_depth + 1}"
            )
        sigma = sc[tree.depth]
    if np.any(sigma < 0) or not np.all(np.isfinite(sigma)):
        raise ShapeTreeError("deformation scale must be finite and non-negative")
    noisy = tree.coords + gen.normal(size=tree.coords.shape) * sigma[:, None]
    return reconstruct(tree, anchors=anchors, coords=noisy)


def with_coords(tree: ShapeTree, coords: ArrayLike) -> ShapeTree:
    """A copy of ``tree`` whose points are reconstructed from new Bookstein coordinates."""
    pts = reconstruct(tree, coords=coords)
    return replace(tree, points=pts, coords=np.asarray(coords, dtype=float))
