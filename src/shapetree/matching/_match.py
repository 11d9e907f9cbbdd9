"""Elastic matching of curves by dynamic programming over the shape-tree (paper §3)."""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from shapetree._errors import ShapeTreeError
from shapetree.curves import point_at
from shapetree.geometry._dif import weighted_dif_many
from shapetree.matching._kernels import closed_root_min, fill_tables, finite_or_inf
from shapetree.matching._prepare import (
    Model,
    Target,
    TreeData,
    prepare_model,
    prepare_target,
    tree_data,
)
from shapetree.tree import ShapeTree


@dataclass(frozen=True)
class MatchParams:
    """Parameters of eq. (1).

    Attributes
    ----------
    occlusion : float or None
        Replacement-cost factor κ: every ψ(A', B') is bounded above by
        ``κ λ_{A'} (|A'| + |B'|)``, lengths relative to the curves' total lengths
        (§3, occlusion). ``None`` disables replacement.
    band : float or None
        Pruned mode (not in the paper): a subcurve of ``A`` spanning ``k`` segments may
        only map to target subcurves of ``L`` segments with
        ``k ρ / band - 1 <= L <= k ρ band + 1`` where ``ρ = m / n`` (``(m-1)/(n-1)`` for
        open curves), i.e. stretch by at most a factor ``band``. ``None`` (default):
        exact matching over all ``L``.
    segment_weight : float
        Factor on the base case "a segment of ``A`` against a target subcurve of ``L > 1``
        segments" (the paper: 1, the cost of the segment subdivided to ``L + 1`` points).
        ``0`` makes the detail of ``B`` finer than ``A``'s sampling free: with a target
        sampled more densely than the model (``m = 2 n``, say), ``A``'s points may then
        land anywhere along ``B`` and only ``A``'s own triangles are compared. Not in the
        paper.
    dif : {"procrustes", "hyperbolic"}
        The triangle dissimilarity (``MatchConfig.dif``); models must be prepared with the
        same (:func:`prepare_model`), targets carry the base-case tables of both.
    tree_combine : {"min", "mean"}
        How the costs of a model's shape-trees combine (``MatchConfig.tree_combine``): the
        best tree (the paper) or their mean.
    """

    occlusion: float | None = None
    band: float | None = None
    segment_weight: float = 1.0
    dif: str = "procrustes"
    tree_combine: str = "min"

    def __post_init__(self) -> None:
        occ = self.occlusion
        if occ is not None and not (np.isfinite(occ) and occ > 0):
            raise ShapeTreeError(f"occlusion must be a positive number or None, got {occ}")
        if self.band is not None and not (np.isfinite(self.band) and self.band >= 1):
            raise ShapeTreeError(f"band must be a number >= 1 or None, got {self.band}")
        sw = self.segment_weight
        if isinstance(sw, bool) or not (
            isinstance(sw, int | float) and np.isfinite(sw) and sw >= 0
        ):
            raise ShapeTreeError(f"segment_weight must be a number >= 0, got {sw!r}")
        if self.dif not in ("procrustes", "hyperbolic"):
            raise ShapeTreeError(f"dif must be 'procrustes' or 'hyperbolic', got {self.dif!r}")
        if self.tree_combine not in ("min", "mean"):
            raise ShapeTreeError(f"tree_combine must be 'min' or 'mean', got {self.tree_combine!r}")

    @property
    def hyper(self) -> bool:
        """Whether the kernel runs the pseudo-hyperbolic ``dif``."""
        return self.dif == "hyperbolic"

    @property
    def kernel_occlusion(self) -> float:
        return -1.0 if self.occlusion is None else float(self.occlusion)

    def combine_trees(self, costs: np.ndarray) -> np.ndarray:
        """ψ from the costs of each shape-tree along the last axis: their minimum
        (``tree_combine="min"``) or mean. ``inf`` (no admissible matching with a tree)
        stays ``inf`` under the mean."""
        costs = np.asarray(costs, dtype=np.float64)
        return costs.min(axis=-1) if self.tree_combine == "min" else costs.mean(axis=-1)


@dataclass
class MatchResult:
    """Result of matching curve ``A`` (deformed) to curve ``B``.

    Attributes
    ----------
    cost : float
        ψ(A, B) (over the shape-trees tried: the minimum, or their mean with
        ``tree_combine="mean"``); from :func:`shapetree.matching.match`, the configured
        distance of the pair (``symmetrize``, ``height_weight``).
    a, b : ndarray, shape (n, 2) and (m, 2)
        The matched sample points.
    closed : bool
    a_to_b : ndarray, shape (n,)
        For each point of ``A``, its position along ``B`` as a fractional index
        (``j + t`` is between ``b_j`` and ``b_{j+1}``; modulo ``m`` for closed curves);
        NaN inside replaced parts.
    b_to_a : ndarray, shape (m,)
        Likewise for each point of ``B``.
    replaced : list of tuple
        ``(a_start, a_end, b_start, b_end)`` index ranges (modulo n, m when closed) of
        subcurves that were replaced rather than deformed (occlusion).
    tree_index : int
        Which of the model's shape-trees gave the cheapest cost (the correspondence is
        that tree's, also when ``cost`` is the mean over the trees).
    costs : ndarray, shape (n_trees,)
        Cost with each shape-tree.
    mirrored : bool
        Whether the mirrored model gave the cost (:func:`match` with ``mirror``); the
        correspondence is then still given in the indices of ``a``.
    phase : int
        Which target phase gave the cost (``b`` holds that sampling).
    forward_cost, backward_cost : float
        ψ(A, B), and ψ(B, A) when the configuration's ``symmetrize`` needed it.
    height_cost : float or None
        The height-function distance ``h(A, B)`` when ``height_weight > 0`` (then
        ``cost = ψ^(1 - w) h^w``).
    """

    cost: float
    a: np.ndarray
    b: np.ndarray
    closed: bool
    a_to_b: np.ndarray
    b_to_a: np.ndarray
    replaced: list[tuple[int, int, int, int]] = field(default_factory=list)
    tree_index: int = 0
    costs: np.ndarray = field(default_factory=lambda: np.zeros(0))
    mirrored: bool = False
    phase: int = 0
    forward_cost: float = float("nan")
    backward_cost: float | None = None
    height_cost: float | None = None

    def pairs(self) -> np.ndarray:
        """Matched point pairs ``(x_a, y_a, x_b, y_b)`` for every non-replaced ``A`` point."""
        ok = np.isfinite(self.a_to_b)
        return np.hstack([self.a[ok], point_at(self.b, self.a_to_b[ok], closed=self.closed)])


_workspace = threading.local()


def _buffers(n_tables: int, m: int, dtype: type = np.float64) -> np.ndarray:
    """This thread's reusable table buffer (fresh memory costs page faults on every call)."""
    bufs = getattr(_workspace, "bufs", None)
    if bufs is None:
        bufs = _workspace.bufs = {}
    buf = bufs.get(np.dtype(dtype))
    if buf is None or buf.shape[0] < n_tables or buf.shape[1] != m:
        buf = bufs[np.dtype(dtype)] = np.empty((n_tables, m, 2 * m), dtype=dtype)
    return buf[:n_tables]


def _bands(td: TreeData, m: int, band: float | None) -> tuple[np.ndarray, np.ndarray]:
    """Allowed target lengths ``[lmin, lmax]`` of every table (nodes first, then segments)."""
    key = (m, band)
    if key not in td.band_cache:
        td.band_cache[key] = _compute_bands(td, m, band)
    return td.band_cache[key]


def _compute_bands(td: TreeData, m: int, band: float | None) -> tuple[np.ndarray, np.ndarray]:
    tree = td.tree
    k_nodes = tree.end - tree.start
    k = np.concatenate([k_nodes, np.ones(td.seg_lam.shape[0], dtype=np.int64)])
    if band is None:
        return np.ones_like(k), np.full_like(k, m - 1)
    n_seg = tree.unrolled.shape[0] - 1
    rho = m / n_seg if tree.closed else (m - 1) / n_seg
    lmin = np.maximum(np.floor(k * rho / band) - 1, 1).astype(np.int64)
    lmax = np.minimum(np.ceil(k * rho * band) + 1, m - 1).astype(np.int64)
    return lmin, lmax


def _fill(td: TreeData, target: Target, params: MatchParams, *, reuse: bool = False) -> np.ndarray:
    """Fill the tables of one tree (doubled, by start; see :mod:`._kernels`); ``reuse``
    writes into this thread's workspace (the result is then only valid until the next
    reusing call). Only the rows inside each table's band are written; unreachable entries
    hold :data:`._kernels.SENTINEL` (map them with :func:`._kernels.finite_or_inf`)."""
    m = target.n_points
    lmin, lmax = _bands(td, m, params.band)
    dt = target.tri.dtype
    tab = _buffers(td.n_tables, m, dt) if reuse else np.empty((td.n_tables, m, 2 * m), dt)
    fill_tables(
        td.left_tab,
        td.right_tab,
        *td.kernel_arrays(dt),
        target.tri,
        target.deg,
        target.base_table(params.dif),
        target.blen,
        target.closed,
        params.kernel_occlusion,
        float(params.segment_weight),
        lmin,
        lmax,
        tab,
        params.hyper,
    )
    return tab


def _root_cost(
    td: TreeData, tab: np.ndarray, closed: bool, band: float | None
) -> tuple[float, int, int]:
    """ψ of the whole model, and the alignment ``(s, L)`` of a closed one; ``inf`` when no
    matching is admissible (the kernel's sentinel mapped back)."""
    m = tab.shape[1]
    if closed:
        lmin, lmax = _bands(td, m, band)
        r1 = td.table_of_root(td.tree.roots[0], 0)
        r2 = td.table_of_root(td.tree.roots[1], 1)
        c, s0, l1 = closed_root_min(tab[r1], tab[r2], lmin[r1], lmax[r1], lmin[r2], lmax[r2])
        return finite_or_inf(c), int(s0), int(l1)
    return finite_or_inf(tab[td.tree.roots[0], m - 1, 0]), 0, m - 1


class _Traceback:
    """Recover the correspondence from filled tables by re-deriving each argmin."""

    def __init__(
        self,
        td: TreeData,
        target: Target,
        params: MatchParams,
        tab: np.ndarray,
    ) -> None:
        self.td, self.t, self.p = td, target, params
        self.tab = tab
        self.m = target.n_points
        self.lmin, self.lmax = _bands(td, self.m, params.band)
        n_u = td.tree.unrolled.shape[0]
        self.pos_a = np.full(n_u, np.nan)  # B position of each unrolled A point
        self.pos_b = np.full(2 * self.m + 1, np.nan)  # A position of each unrolled B point
        self.replaced: list[tuple[int, int, int, int]] = []
        self.n_nodes = td.lam.shape[0]

    def _replace_cost(self, lam: float, alen: float, s: int, length: int) -> float:
        if self.p.occlusion is None:
            return np.inf
        return self.p.occlusion * lam * (alen + self.t.blen[length, s % self.m])

    def assign(self, ia: int, jb: float) -> None:
        self.pos_a[ia] = jb
        if float(jb).is_integer():
            self.pos_b[int(jb)] = ia

    def segment(self, seg: int, s: int, length: int) -> None:
        td = self.td
        lam, alen = td.seg_lam[seg], td.seg_alen[seg]
        cost = lam * self.p.segment_weight * self.t.base_table(self.p.dif)[length, s % self.m]
        if self._replace_cost(lam, alen, s, length) < cost:
            self.replaced.append((seg, seg + 1, s, s + length))
            self.pos_b[s + 1 : s + length] = np.nan
            return
        for q in range(1, length):
            self.pos_b[s + q] = seg + q / length

    def node(self, v: int, s: int, length: int) -> None:
        """Visit node ``v`` matched to the unrolled target range ``[s, s + length]``."""
        td, tr = self.td, self.td.tree
        if v >= self.n_nodes:
            self.segment(v - self.n_nodes, s, length)
            return
        sa, ia, ea = int(tr.start[v]), int(tr.mid[v]), int(tr.end[v])
        m = self.m
        if length == 1:
            best, k = td.flat[v], -1
        else:
            lt, rt = int(td.left_tab[v]), int(td.right_tab[v])
            lmin, lmax = self.lmin, self.lmax
            # the splits the kernel considered (both halves inside their children's bands)
            k0 = max(1, lmin[lt], length - lmax[rt])
            k1 = min(length - 1, lmax[lt], length - lmin[rt])
            ks = np.arange(k0, k1 + 1)
            ss = s % m
            left = self.tab[lt, ks, ss]
            right = self.tab[rt, length - ks, ss + ks]
            tri = np.asarray(self.t.tri[length, ks, :, ss], dtype=np.float64)
            # λ dif, evaluated as the kernel does (sqrt(λ)-scaled model coordinates; a
            # zero-size target triangle costs λ)
            lam_dif = np.empty(ks.size)
            weighted_dif_many(
                float(td.lam[v]),
                float(td.ra1[v]),
                float(td.ra2r[v]),
                float(td.ra2i[v]),
                np.ascontiguousarray(tri[:, 0]),
                np.ascontiguousarray(tri[:, 1]),
                np.ascontiguousarray(tri[:, 2]),
                lam_dif,
                self.p.hyper,
            )
            tot = left + right + lam_dif
            if tot.size == 0:  # no admissible split: only a replacement can cover (s, L)
                best, k = np.inf, -1
            else:
                i = int(np.argmin(tot))
                best, k = finite_or_inf(tot[i]), int(ks[i])
        if self._replace_cost(td.lam[v], td.alen[v], s, length) < best:
            self.replaced.append((sa, ea, s, s + length))
            self.pos_a[sa + 1 : ea] = np.nan
            self.pos_b[s + 1 : s + length] = np.nan
            return
        if k < 0:  # target segment: A' lies along it, evenly subdivided
            for i in range(sa + 1, ea):
                self.pos_a[i] = s + (i - sa) / (ea - sa)
            return
        self.assign(ia, s + k)
        self.node(int(td.left_tab[v]), s, k)
        self.node(int(td.right_tab[v]), s + k, length - k)


def _traceback(
    td: TreeData,
    target: Target,
    params: MatchParams,
    tab: np.ndarray,
    s0: int,
    l1: int,
    n_a: int,
) -> tuple:
    tb = _Traceback(td, target, params, tab)
    tree = td.tree
    m = target.n_points
    if tree.closed:
        k = tree.split_index
        tb.assign(0, s0)
        tb.assign(k, s0 + l1)
        tb.assign(tree.n_points, s0 + m)
        tb.node(td.table_of_root(tree.roots[0], 0), s0, l1)
        tb.node(td.table_of_root(tree.roots[1], 1), s0 + l1, m - l1)
    else:
        tb.assign(0, 0)
        tb.assign(n_a - 1, m - 1)
        tb.node(tree.roots[0], 0, m - 1)
    n = tree.n_points
    pos_a = tb.pos_a[:n]
    if tree.closed:
        # undo the tree's rotation of A and fold the target's unrolled indices
        pos_a = np.mod(pos_a, m)
        a_to_b = np.empty(n)
        a_to_b[(np.arange(n) + tree.offset) % n] = pos_a
        pb = tb.pos_b[s0 : s0 + m]
        idx = (np.arange(s0, s0 + m)) % m
        b_to_a = np.empty(m)
        b_to_a[idx] = np.mod(pb + tree.offset, n)
        replaced = [
            ((a0 + tree.offset) % n, (a1 + tree.offset) % n, b0 % m, b1 % m)
            for a0, a1, b0, b1 in tb.replaced
        ]
    else:
        a_to_b = pos_a
        b_to_a = tb.pos_b[:m]
        replaced = tb.replaced
    return a_to_b, b_to_a, sorted(replaced)


def match_prepared(
    model: Model,
    target: Target,
    params: MatchParams | None = None,
    *,
    correspondence: bool = True,
) -> MatchResult:
    """Match a prepared model to a prepared target (reuses all per-curve work).

    Parameters
    ----------
    model : Model
        From :func:`prepare_model`.
    target : Target
        From :func:`prepare_target`; must be closed iff the model is.
    params : MatchParams, optional
    correspondence : bool
        Whether to trace back the point correspondence (skip it for cost-only work).

    Returns
    -------
    MatchResult
        ``cost`` is ``inf``, and the correspondence all NaN, when no matching is
        admissible (see :func:`match_cost`).
    """
    params = params or MatchParams()
    _check_pair(model, target, params)
    costs = np.empty(len(model.trees))
    best = None
    for t, td in enumerate(model.trees):
        tab = _fill(td, target, params)
        c, s0, l1 = _root_cost(td, tab, model.closed, params.band)
        costs[t] = c
        if best is None or c < best[0]:
            best = (c, t, tab, s0, l1)
    assert best is not None
    cost, t, tab, s0, l1 = best
    n, m = model.points.shape[0], target.n_points
    # no admissible matching: no correspondence; else the cheapest tree's
    if correspondence and np.isfinite(cost):
        a_to_b, b_to_a, replaced = _traceback(model.trees[t], target, params, tab, s0, l1, n)
    else:
        a_to_b, b_to_a, replaced = np.full(n, np.nan), np.full(m, np.nan), []
    return MatchResult(
        cost=max(float(params.combine_trees(costs)), 0.0),
        a=model.points,
        b=target.points,
        closed=model.closed,
        a_to_b=a_to_b,
        b_to_a=b_to_a,
        replaced=replaced,
        tree_index=t,
        costs=costs,
    )


def _check_pair(model: Model, target: Target, params: MatchParams | None = None) -> None:
    if model.closed != target.closed:
        raise ShapeTreeError(
            "model and target must both be closed or both open "
            f"(model closed={model.closed}, target closed={target.closed})"
        )
    if model.length_power != target.length_power:
        raise ShapeTreeError(
            f"model and target were prepared with different length_power "
            f"({model.length_power} and {target.length_power})"
        )
    if params is not None and model.dif != params.dif:
        raise ShapeTreeError(
            f"the model was prepared for dif={model.dif!r} but the parameters ask for "
            f"dif={params.dif!r} (prepare_model(..., dif={params.dif!r}))"
        )


def match_cost(model: Model, target: Target, params: MatchParams | None = None) -> float:
    """ψ(A, B) only (no traceback): the fast path for distance matrices.

    ``inf`` when no matching is admissible (only possible with bands that leave a node no
    split, which :func:`_bands` never makes, and no occlusion to replace it).
    """
    params = params or MatchParams()
    _check_pair(model, target, params)
    costs = np.empty(len(model.trees))
    for t, td in enumerate(model.trees):
        tab = _fill(td, target, params, reuse=True)
        costs[t] = _root_cost(td, tab, model.closed, params.band)[0]
    # a sum of difs >= 0; round-off can leave -1e-17
    return max(float(params.combine_trees(costs)), 0.0)


def subcurve_table(
    contour: ArrayLike | ShapeTree,
    target: Target,
    *,
    weight: float = 1.0,
    length_scale: float | None = None,
    split: str = "half",
    occlusion: float | None = None,
) -> np.ndarray:
    """Cost of deforming an open curve to every subcurve of a closed target (§4, stage 3).

    Parameters
    ----------
    contour : array_like, shape (n, 2), or ShapeTree
        Open curve (an image contour); its shape-tree is the one deformed.
    target : Target
        Closed target (the model), from :func:`prepare_target`.
    weight, length_scale : float
        λ of a contour node is ``weight * arclength / length_scale`` (default: the
        contour's own length).
    split : {"half", "best"}
    occlusion : float, optional

    Returns
    -------
    ndarray, shape (m, m)
        ``[s, L]``: the target subcurve from index ``s`` forward ``L`` segments
        (``1 <= L <= m - 1``); column 0 is ``inf``.
    """
    from shapetree.tree import build_shape_tree

    if not target.closed:
        raise ShapeTreeError("subcurve_table needs a closed target (the model)")
    tree = (
        contour
        if isinstance(contour, ShapeTree)
        else build_shape_tree(contour, closed=False, split=split)
    )
    if tree.closed:
        raise ShapeTreeError("subcurve_table needs an open contour")
    td = tree_data(tree, weight=weight, length_scale=length_scale, power=target.length_power)
    tab = _fill(td, target, MatchParams(occlusion=occlusion), reuse=True)
    out = finite_or_inf(tab[tree.roots[0], :, : target.n_points].T)
    out[:, 0] = np.inf
    return out


__all__ = [
    "MatchParams",
    "MatchResult",
    "Model",
    "Target",
    "match_cost",
    "match_prepared",
    "prepare_model",
    "prepare_target",
    "subcurve_table",
]
