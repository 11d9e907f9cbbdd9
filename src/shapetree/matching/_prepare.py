"""Per-curve precomputation: :class:`Model` (shape-trees of A) and :class:`Target` (B).

Both are computed once per curve and reused for every matching the curve takes part in
(one-vs-many retrieval, contour-vs-model tables in detection).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from shapetree._errors import ShapeTreeError
from shapetree.curves import as_curve
from shapetree.geometry._dif import triangle_dif_many, unit_helmert_many
from shapetree.matching._kernels import target_tables
from shapetree.tree import SPLITS, ShapeTree, build_shape_tree


@dataclass(frozen=True, eq=False)
class Target:
    """Precomputed data of a target curve ``B`` (the curve a model is deformed onto).

    Attributes
    ----------
    points : ndarray, shape (m, 2)
    closed : bool
        Closed targets have cyclic subcurves.
    tri : ndarray, shape (m, m, 3, m)
        The triangles ``(b_s, b_{s+k}, b_{s+L})``, indexed ``[L, k, c, s]``: their unit
        Helmert coordinates ``z1`` (``c = 0``, real, rotated so) and ``z2`` (``c = 1, 2``:
        real and imaginary part); see :mod:`shapetree.matching._kernels`. A triangle of
        zero size (three coincident points) is stored as ``(0, 0, 0)``.
    deg : ndarray of uint8, shape (m, m), or None
        ``deg[L, k]``: 1 when some triangle ``(b_s, b_{s+k}, b_{s+L})`` has zero size (its
        ``dif`` is then :data:`shapetree.geometry.DEGENERATE_DIF`); such planes take the
        kernel's slower, branching path. ``None`` when no triangle has zero size (a curve
        that never passes through one point three times; the kernel then runs its
        specialisation without that path).
    g : ndarray, shape (m, m)
        ``g[L, s]``: base-case cost per unit λ of a straight segment subdivided into
        ``L + 1`` points and matched point for point to ``B[s..s+L]``.
    blen : ndarray, shape (m, m)
        ``blen[L, s]``: arclength of ``B[s..s+L]`` relative to the length of ``B``.
    length_power : float
        λ exponent the base-case table ``g`` was made for (see :func:`prepare_model`).
    g_hyp : ndarray, shape (m, m)
        ``g`` with the pseudo-hyperbolic ``dif`` (``MatchParams(dif="hyperbolic")``; the
        kernel picks the table of its ``dif``, :meth:`base_table`).

    The tables are float64, or float32 with ``prepare_target(..., dtype=np.float32)``
    (the retrieval engine's precision; the kernel then runs in float32).
    """

    points: np.ndarray
    closed: bool
    tri: np.ndarray
    deg: np.ndarray | None
    g: np.ndarray
    blen: np.ndarray
    length_power: float = 1.0
    g_hyp: np.ndarray | None = None

    @property
    def n_points(self) -> int:
        return int(self.points.shape[0])

    def base_table(self, dif: str) -> np.ndarray:
        """The base-case table ``g`` of ``dif`` (``"procrustes"`` or ``"hyperbolic"``)."""
        if dif == "procrustes":
            return self.g
        if dif == "hyperbolic" and self.g_hyp is not None:
            return self.g_hyp
        raise ShapeTreeError(f"this target has no base-case table for dif={dif!r}")


def prepare_target(
    points: ArrayLike,
    *,
    closed: bool = True,
    length_power: float = 1.0,
    dtype: type = np.float64,
) -> Target:
    """Precompute the target-side data of eq. (1) for curve ``B``.

    Parameters
    ----------
    points : array_like, shape (m, 2)
        Sample points of ``B`` (``m >= 3``).
    closed : bool
        Whether ``B`` is closed (its subcurves then wrap around).
    length_power : float
        Must equal the model's (:func:`prepare_model`); it shapes the base-case table.
    dtype : {numpy.float64, numpy.float32}
        Precision of the tables (computed in float64 either way).

    Returns
    -------
    Target
    """
    b = as_curve(points, closed=closed, name="target curve")
    if not (np.isfinite(length_power) and length_power >= 0):
        raise ShapeTreeError(f"length_power must be a number >= 0, got {length_power}")
    dt = np.dtype(dtype)
    if dt not in (np.float64, np.float32):
        raise ShapeTreeError(f"dtype must be float64 or float32, got {dt}")
    m = b.shape[0]
    tri = np.empty((m, m, 3, m), dtype=dt)
    deg = np.zeros((m, m), dtype=np.uint8)
    g = np.zeros((m, m), dtype=dt)
    blen = np.zeros((m, m), dtype=dt)
    g_hyp = np.zeros((m, m), dtype=dt)
    target_tables(
        np.ascontiguousarray(b[:, 0]),
        np.ascontiguousarray(b[:, 1]),
        closed,
        float(length_power),
        tri,
        deg,
        g,
        blen,
        g_hyp,
    )
    return Target(
        points=b,
        closed=closed,
        tri=tri,
        deg=deg if deg.any() else None,
        g=g,
        blen=blen,
        length_power=float(length_power),
        g_hyp=g_hyp,
    )


@dataclass(frozen=True, eq=False)
class TreeData:
    """Per-node constants of one shape-tree, laid out for the kernel."""

    tree: ShapeTree
    left_tab: np.ndarray
    right_tab: np.ndarray
    lam: np.ndarray
    ra1: np.ndarray
    ra2r: np.ndarray
    ra2i: np.ndarray
    flat: np.ndarray
    alen: np.ndarray
    seg_start: np.ndarray
    seg_lam: np.ndarray
    seg_alen: np.ndarray
    band_cache: dict = field(default_factory=dict, repr=False)
    dtype_cache: dict = field(default_factory=dict, repr=False)

    def kernel_arrays(self, dtype: np.dtype) -> tuple[np.ndarray, ...]:
        """``(lam, ra1, ra2r, ra2i, flat, alen, seg_lam, seg_alen)`` in ``dtype`` (the
        tables' precision), as :func:`._kernels.fill_tables` takes them."""
        dt = np.dtype(dtype)
        if dt not in self.dtype_cache:
            names = ("lam", "ra1", "ra2r", "ra2i", "flat", "alen", "seg_lam", "seg_alen")
            self.dtype_cache[dt] = tuple(
                np.ascontiguousarray(getattr(self, k), dtype=dt) for k in names
            )
        return self.dtype_cache[dt]

    @property
    def n_tables(self) -> int:
        return int(self.lam.shape[0] + self.seg_lam.shape[0])

    def table_of_root(self, r: int, half: int) -> int:
        """Table index of a root (a half that is a single segment has no node)."""
        if r >= 0:
            return r
        t = self.tree
        seg = 0 if half == 0 else t.split_index
        return int(self.lam.shape[0] + np.searchsorted(self.seg_start, seg))


def tree_data(
    tree: ShapeTree,
    *,
    weight: float,
    length_scale: float | None,
    power: float = 1.0,
    dif: str = "procrustes",
) -> TreeData:
    """Lay out the per-node constants of ``tree`` for :func:`fill_tables`.

    λ of a node is ``weight * (arclength / length_scale) ** power`` (the paper: power 1);
    ``dif`` (``"procrustes"`` or ``"hyperbolic"``) is the ``dif`` of the base-case
    constants ``flat``.
    """
    if dif not in ("procrustes", "hyperbolic"):
        raise ShapeTreeError(f"dif must be 'procrustes' or 'hyperbolic', got {dif!r}")
    u = tree.unrolled
    seglen = np.hypot(*np.diff(u, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seglen)])
    scale = float(cum[-1]) if length_scale is None else float(length_scale)
    if not scale > 0:
        raise ShapeTreeError("length_scale must be positive")
    k = tree.n_nodes
    n_seg = u.shape[0] - 1
    seg_start = np.arange(n_seg)
    alen = (cum[tree.end] - cum[tree.start]) / scale
    lam = weight * alen**power
    # each node's triangle (a_start, a_mid, a_end) in its Bookstein frame, and the straight
    # evenly subdivided segment with the same split
    tri_a = np.zeros((k, 3, 2))
    tri_a[:, 0, 0], tri_a[:, 2, 0] = -0.5, 0.5
    even = tri_a.copy()
    tri_a[:, 1] = tree.coords
    even[:, 1, 0] = (tree.mid - tree.start) / (tree.end - tree.start) - 0.5
    z = np.empty((k, 3))
    unit_helmert_many(tri_a, z)  # z1 = 1/sqrt(2)/N > 0: the frame needs no rotation
    a1, a2r, a2i = z[:, 0], z[:, 1], z[:, 2]
    # cost of each node's own triangle against a straight, evenly subdivided segment
    dif_flat = np.empty(k)
    triangle_dif_many(tri_a, even, dif_flat, dif == "hyperbolic")
    own = lam * dif_flat
    flat = own.copy()
    for v in range(k):  # post-order: children first
        for c in (tree.left[v], tree.right[v]):
            if c >= 0:
                flat[v] += flat[c]
    left_tab = np.where(tree.left >= 0, tree.left, k + tree.start)
    right_tab = np.where(tree.right >= 0, tree.right, k + tree.mid)
    seg_alen = seglen / scale
    return TreeData(
        tree=tree,
        left_tab=left_tab.astype(np.int64),
        right_tab=right_tab.astype(np.int64),
        lam=np.ascontiguousarray(lam),
        # λ dif = |sqrt(λ) (a1 z2 - a2 z1)|^2 (see ._kernels)
        ra1=np.ascontiguousarray(np.sqrt(lam) * a1),
        ra2r=np.ascontiguousarray(np.sqrt(lam) * a2r),
        ra2i=np.ascontiguousarray(np.sqrt(lam) * a2i),
        flat=flat,
        alen=alen,
        seg_start=seg_start,
        seg_lam=weight * seg_alen**power,
        seg_alen=seg_alen,
    )


@dataclass(frozen=True, eq=False)
class Model:
    """Shape-trees of a curve ``A`` (the curve that is deformed), ready for matching.

    Attributes
    ----------
    points : ndarray, shape (n, 2)
    closed : bool
    trees : list of TreeData
        One entry per shape-tree (§3: "we usually compute matchings using 2 to 4
        different shape-trees and pick the best one").
    weight : float
    """

    points: np.ndarray
    closed: bool
    trees: list[TreeData]
    weight: float
    length_power: float = 1.0
    dif: str = "procrustes"


def tree_variants(n: int, closed: bool, n_trees: int, split: str) -> list[dict]:
    """Keyword arguments of :func:`build_shape_tree` for ``n_trees`` different trees.

    Closed curves: the same midpoint rule started at ``n_trees`` different points. A closed
    tree is cut at ``a_0`` and ``a_{n/2}``, so starting half-way round gives the same cut:
    the offsets ``t n / (2 n_trees)``, ``t = 0 .. n_trees - 1``, spread the cuts over half
    the curve, which makes every tree different.
    Open curves (endpoints are fixed): the alternative midpoint rule(s).
    """
    if n_trees < 1:
        raise ShapeTreeError(f"n_trees must be at least 1, got {n_trees}")
    if split not in SPLITS:
        raise ShapeTreeError(f"unknown midpoint rule split={split!r}; use one of {SPLITS}")
    if closed:
        offsets = sorted({(t * n) // (2 * n_trees) for t in range(n_trees)})
        if len(offsets) < n_trees:
            raise ShapeTreeError(f"a closed curve of {n} points has fewer than {n_trees} trees")
        return [{"split": split, "offset": o} for o in offsets]
    rules = [split] + [s for s in SPLITS if s != split]
    if n_trees > len(rules):
        raise ShapeTreeError(
            f"open curves support at most {len(rules)} shape-trees (one per midpoint rule)"
        )
    return [{"split": r} for r in rules[:n_trees]]


def prepare_model(
    points: ArrayLike,
    *,
    closed: bool = True,
    n_trees: int = 1,
    split: str = "half",
    weight: float = 1.0,
    length_scale: float | None = None,
    length_power: float = 1.0,
    dif: str = "procrustes",
) -> Model:
    """Build the shape-tree(s) of curve ``A`` and their kernel constants.

    Parameters
    ----------
    points : array_like, shape (n, 2)
    closed : bool
    n_trees : int
        Number of different shape-trees (closed: start offsets ``t n / (2 n_trees)``).
    split : {"half", "best"}
        Midpoint rule (see :func:`shapetree.tree.build_shape_tree`).
    weight : float
        λ of a node is ``weight * arclength(A') / length_scale``.
    length_scale : float, optional
        Length that normalises λ; default the length of ``A``, which makes costs
        invariant to scaling ``A``.
    length_power : float
        λ of a node is ``weight * (arclength(A') / length_scale) ** length_power``. The
        paper uses 1 (λ proportional to the subcurve's length); larger values weigh the
        coarse, global nodes more against the fine ones.
    dif : {"procrustes", "hyperbolic"}
        The ``dif`` the model's base-case constants are made for; it must equal the
        ``MatchParams.dif`` it is matched with.

    Returns
    -------
    Model
    """
    a = as_curve(points, closed=closed, name="model curve")
    if not (np.isfinite(weight) and weight > 0):
        raise ShapeTreeError(f"weight must be a positive number, got {weight}")
    if not (np.isfinite(length_power) and length_power >= 0):
        raise ShapeTreeError(f"length_power must be a number >= 0, got {length_power}")
    trees = [
        tree_data(
            build_shape_tree(a, closed=closed, **kw),
            weight=weight,
            length_scale=length_scale,
            power=length_power,
            dif=dif,
        )
        for kw in tree_variants(a.shape[0], closed, n_trees, split)
    ]
    return Model(
        points=a,
        closed=closed,
        trees=trees,
        weight=float(weight),
        length_power=float(length_power),
        dif=dif,
    )
