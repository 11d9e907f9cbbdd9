"""A cheap lower bound of the shape-tree cost ψ, for exact pruned search.

The bound runs the dynamic program of :func:`._kernels.fill_tables` on part of the model's
shape-tree only: the nodes that are **kept** get their exact tables (the same recursion,
the same bands, the same replacement cost, the same loops); every other node (a
**dropped** node) gets a table of lower bounds that costs one addition per entry instead
of a minimum over splits: its own ``λ dif`` term is left out and its two children are
placed independently, the left one by where it starts, the right one by where it ends.

Which nodes are kept
--------------------
``keep_from = d``: the nodes of depth ``>= d`` (the small, deep subtrees) are kept and the
``d`` top levels are dropped; ``keep_top = t`` keeps the ``t`` top levels too. Under a
band (:func:`._match._bands`) a node's work grows with its size, so the deep levels are
cheap and the top ones dominate (``keep_from`` is the knob); without a band every node
costs about ``m^3 / 6`` whatever its size, and keeping a few top levels (``keep_top``,
with ``keep_from=None``) is the cheap choice.

The bound and its proof
-----------------------
Write ``T_v[L, s]`` for the exact table of node (or model segment) ``v``: the cost of
deforming the model subcurve of ``v`` onto the target subcurve from ``s`` to ``s + L``
(mod ``m``), for ``L`` in ``v``'s band. Its recursion is

    T_v[L, s] = min( min_k T_l[k, s] + T_r[L - k, s + k] + λ_v dif_v(s, k, L),  R_v[L, s] )

over the splits ``k`` with both halves in their children's bands (``L >= 2``); ``T_v[1, s]
= min(flat_v, R_v[1, s])``; ``R_v[L, s] = κ λ_v (|A_v| + |B(s, L)|)`` is the replacement
cost (occlusion; ``+inf`` without it). Every term is ``>= 0``: ``λ >= 0``, ``dif`` is in
``[0, 1]``, base cases are sums of ``λ dif``, ``R >= 0``; an entry with no admissible
split holds the kernel's sentinel (larger than any cost).

The bound tables ``T'`` are filled leaves up. Segments and kept nodes use the recursion
above with ``T'`` of the children in place of ``T``. A dropped node ``v`` with children
``l``, ``r`` gets, for every ``(L, s)`` of its band,

    T'_v[L, s] = min( P_l[s] + E_r[s + L],  R_v[L, s] )      (``flat_v`` in place of the
                                                              sum at ``L = 1``)

with the *profiles* ``P_l[s] = min_k T'_l[k, s]`` (the left child's best entry starting at
``s``) and ``E_r[e] = min_j T'_r[j, e - j]`` (the right child's best entry ending at
``e``), both over the child's band.

*Claim:* ``T'_v[L, s] <= T_v[L, s]`` for every table and every in-band entry. Induction
leaves up. Segments are exact. A kept node's recursion is non-decreasing in its
children's entries, which are ``<=`` the exact ones. For a dropped node, a split ``k``
costs ``T_l[k, s] + T_r[L - k, s + k] + λ dif >= T'_l[k, s] + T'_r[L - k, s + k] + 0 >=
P_l[s] + E_r[s + L]`` (the left half starts at ``s``, the right half ends at ``s + L``,
both entries are in their bands); the length-1 entry and the replacement term are the
exact ones. So the minimum over the splits and the replacement is ``>= T'_v[L, s]``.

The closed root combination ``min_{s, L} T_1[L, s] + T_2[m - L, s + L]``
(:func:`._kernels.closed_root_min`, with the roots' bands) is non-decreasing in both
tables, so evaluated on ``T'`` it is ``<=`` ψ of the tree. A configuration's directed
cost is the minimum over shape-trees, mirror passes and target phases; the minimum of
the bounds is ``<=`` it. Symmetrized distances (min / mean / max of the two directions)
are non-decreasing in each direction, so combining the two directed bounds the same way
gives a bound. Keeping every node gives ψ itself (the kept loops are the kernel's); each
dropped level leaves out the ``λ dif`` terms of its nodes and the coupling of their
children's split points, so the bound loosens with every level dropped (measured in
``benchmarks/bench_knn.py``).

Rounding
--------
The tables are filled in the configuration's precision (float32 by default), as in the
full matching. Float rounding is monotone, so the induction holds for the computed values
too up to the rounding of a float32 sum (the full cost may round down where the bound's
sum, over other operands, does not): a few units of ``2^-24`` relative per level.
:data:`BOUND_SLACK` (``1e-5`` relative) is subtracted from every bound so that ``bound <=
cost`` holds for the computed numbers, not only for the real ones (tested on thousands of
pairs with a zero tolerance).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from shapetree.geometry._dif import FASTMATH
from shapetree.matching._batch import ModelStack
from shapetree.matching._kernels import (
    SENTINEL,
    closed_root_min,
    finite_or_inf,
    node_row,
    replace_row,
)
from shapetree.matching._match import MatchParams
from shapetree.matching._prepare import Model, Target, TreeData

__all__ = ["BOUND_SLACK", "BoundStack", "keep_mask", "table_marks"]

#: Relative amount subtracted from every bound (float32 rounding; module docstring).
BOUND_SLACK = 1e-5

_jit = njit(cache=True, nogil=True, fastmath=set(FASTMATH))


def keep_mask(td: TreeData, keep_from: int | None, keep_top: int = 0) -> np.ndarray:
    """Which nodes of a tree the bound computes exactly (bool, one per node).

    Parameters
    ----------
    td : TreeData
    keep_from : int or None
        Nodes of depth ``>= keep_from`` are kept (``None``: none by this rule).
    keep_top : int
        Nodes of depth ``< keep_top`` are kept too.
    """
    depth = td.tree.depth
    keep = depth < int(keep_top)
    if keep_from is not None:
        keep |= depth >= int(keep_from)
    return keep


def table_marks(td: TreeData, keep_from: int | None, keep_top: int = 0) -> np.ndarray:
    """Per table (nodes, then segments) the flags :func:`fill_bound_tables` reads: 1 kept
    (segments always), 2 its profiles are read by a dropped parent, 4 dropped and read
    entry by entry (a root of the closed tree, or the child of a kept node)."""
    keep = keep_mask(td, keep_from, keep_top)
    k = keep.shape[0]
    mark = np.zeros(td.n_tables, dtype=np.uint8)
    mark[:k][keep] |= 1
    mark[k:] |= 1
    for v in range(k):
        for c in (td.left_tab[v], td.right_tab[v]):
            if keep[v]:
                if c < k and not keep[c]:
                    mark[c] |= 4
            else:
                mark[c] |= 2
    for half, r in enumerate(td.tree.roots):
        t = td.table_of_root(r, half)
        if t < k and not keep[t]:
            mark[t] |= 4
    return mark


@_jit
def fill_bound_tables(
    left_tab: np.ndarray,
    right_tab: np.ndarray,
    lam: np.ndarray,
    ra1: np.ndarray,
    ra2r: np.ndarray,
    ra2i: np.ndarray,
    flat: np.ndarray,
    alen: np.ndarray,
    seg_lam: np.ndarray,
    seg_alen: np.ndarray,
    mark: np.ndarray,
    tri: np.ndarray,
    deg: np.ndarray | None,
    g: np.ndarray,
    blen: np.ndarray,
    occlusion: float,
    seg_weight: float,
    lmin: np.ndarray,
    lmax: np.ndarray,
    tab: np.ndarray,
    prof: np.ndarray,
    hyper: bool = False,
) -> None:
    """The bound tables ``T'`` of one closed shape-tree (module docstring).

    The arguments are those of :func:`._kernels.fill_tables` (cyclic target) plus
    ``mark`` (uint8, one per table, :func:`table_marks`: 1 kept, 2 its profiles are read
    by a dropped parent, 4 a dropped table read entry by entry) and ``prof`` (n_tables, 2,
    2 m) scratch of the tables' dtype for the profiles. Kept nodes and segments run the
    loops of :func:`._kernels.fill_tables`; a dropped node ``v`` gets ``T'_v[L, s] =
    P_l[s] + E_r[s + L]`` (``flat_v`` at ``L = 1``), then the replacement cost.
    ``hyper``: the pseudo-hyperbolic ``dif`` in the kept nodes, as the kernel (every
    ``dif`` is ``>= 0`` either way, which is all the proof needs).
    """
    m = g.shape[1]
    n_nodes = lam.shape[0]
    n_seg = seg_lam.shape[0]
    occl = occlusion > 0.0
    for t in range(n_seg + n_nodes):
        is_seg = t < n_seg
        v = t - n_seg
        out = n_nodes + t if is_seg else v
        if is_seg:
            lv = seg_lam[t]
            la = seg_alen[t]
        else:
            lv = lam[v]
            la = alen[v]
        lg = lv * seg_weight
        mk = mark[out]
        dropped = (mk & 1) == 0
        # a dropped node reads its left child's best cost by start and its right child's
        # by end (cyclic indices)
        pl = prof[left_tab[v], 0] if dropped else prof[0, 0]
        pr = prof[right_tab[v], 1] if dropped else prof[0, 1]
        want_prof = (mk & 2) != 0
        # a dropped node's table is only read entry by entry when it is a root or the
        # child of a kept node (bit 4); otherwise only its profiles are needed
        doubled = (mk & 4) != 0 or not dropped
        ps = prof[out, 0]
        pe = prof[out, 1]
        if want_prof:
            # profiles read by a dropped parent: ps[s] = min_L T'[L, s] (by start) and
            # pe[e] = min_L T'[L, e - L] (by end; doubled, so pe[s + L] needs no modulo)
            for s in range(2 * m):
                ps[s] = SENTINEL
                pe[s] = SENTINEL
        for length in range(lmin[out], lmax[out] + 1):
            ns = m
            best = tab[out, length]
            if is_seg:
                grow = g[length]
                for s in range(ns):
                    best[s] = lg * grow[s]
            elif length == 1:
                fl = flat[v]
                for s in range(ns):
                    best[s] = fl
            elif dropped:
                pre = pr[length : length + ns]
                for s in range(ns):
                    best[s] = pl[s] + pre[s]
            else:
                # a kept node: the kernel's own row (the same loops, the same numbers)
                node_row(
                    tab,
                    v,
                    length,
                    ns,
                    left_tab,
                    right_tab,
                    ra1,
                    ra2r,
                    ra2i,
                    flat,
                    lam,
                    tri,
                    deg,
                    lmin,
                    lmax,
                    hyper,
                )
            if occl:
                replace_row(best, lv, la, blen[length], ns, occlusion)
            if doubled:
                for s in range(m):
                    best[m + s] = best[s]
            if want_prof:
                for s in range(m):
                    ps[s] = np.minimum(ps[s], best[s])
                seg = pe[length : length + m]
                for s in range(m):
                    seg[s] = np.minimum(seg[s], best[s])
        if want_prof:
            for s in range(m):
                a = pe[s]
                b = pe[s + m]
                c = a if a < b else b
                pe[s] = c
                pe[s + m] = c


@_jit
def closed_bounds(
    left_tab: np.ndarray,
    right_tab: np.ndarray,
    lam: np.ndarray,
    ra1: np.ndarray,
    ra2r: np.ndarray,
    ra2i: np.ndarray,
    flat: np.ndarray,
    alen: np.ndarray,
    seg_lam: np.ndarray,
    seg_alen: np.ndarray,
    lmin: np.ndarray,
    lmax: np.ndarray,
    root1: np.ndarray,
    root2: np.ndarray,
    mark: np.ndarray,
    tri: np.ndarray,
    deg: np.ndarray | None,
    g: np.ndarray,
    blen: np.ndarray,
    occlusion: float,
    seg_weight: float,
    tab: np.ndarray,
    out: np.ndarray,
    hyper: bool = False,
) -> None:
    """Bounds of many closed shape-trees against one closed target, in one call: the
    arguments of :func:`._kernels.closed_costs` plus ``mark`` (R, n_tables) uint8 from
    :func:`table_marks`."""
    prof = np.empty((mark.shape[1], 2, tab.shape[2]), dtype=tab.dtype)
    for r in range(lam.shape[0]):
        fill_bound_tables(
            left_tab[r],
            right_tab[r],
            lam[r],
            ra1[r],
            ra2r[r],
            ra2i[r],
            flat[r],
            alen[r],
            seg_lam[r],
            seg_alen[r],
            mark[r],
            tri,
            deg,
            g,
            blen,
            occlusion,
            seg_weight,
            lmin[r],
            lmax[r],
            tab,
            prof,
            hyper,
        )
        a = root1[r]
        b = root2[r]
        out[r] = closed_root_min(tab[a], tab[b], lmin[r, a], lmax[r, a], lmin[r, b], lmax[r, b])[0]


class BoundStack(ModelStack):
    """Lower bounds of ψ for many closed models against a target in one kernel call
    (a :class:`ModelStack`, whose ``costs`` it keeps, plus which tables are kept).

    The twin of :class:`shapetree.matching._batch.ModelStack` (same arguments, same
    checks): ``bounds(target)[i] <= ModelStack(...).costs(target)[i]`` for every model.

    Parameters
    ----------
    models : sequence of Model
        Closed, equal numbers of points and shape-trees, one ``length_power``.
    m : int
        Points of the targets.
    params : MatchParams, optional
    dtype : {numpy.float64, numpy.float32}
    keep_from, keep_top : int
        Which nodes are computed exactly (:func:`keep_mask`; the default drops the two
        roots); the rest are dropped.
    """

    def __init__(
        self,
        models: Sequence[Model],
        m: int,
        params: MatchParams | None = None,
        dtype: type = np.float64,
        *,
        keep_from: int | None = 1,
        keep_top: int = 0,
    ) -> None:
        super().__init__(models, m, params, dtype)
        tds = [td for mod in self.models for td in mod.trees]
        marks = np.stack([table_marks(td, keep_from, keep_top) for td in tds])
        self._marks = np.ascontiguousarray(marks)

    def bounds(self, target: Target) -> np.ndarray:
        """A lower bound of ψ(model_i, target) for every model (its trees combined as in
        :meth:`costs`),
        lowered by :data:`BOUND_SLACK`; shape (n_models,), float64."""
        tab = self._table_workspace(target)
        out = np.empty(self.n_models * self.n_trees, dtype=self.dtype)
        closed_bounds(
            *self._arrays,
            self._marks,
            target.tri,
            target.deg,
            target.base_table(self.params.dif),
            target.blen,
            self.params.kernel_occlusion,
            self.params.segment_weight,
            tab,
            out,
            self.params.hyper,
        )
        # per tree, bound <= cost; so also for their minimum or mean
        best = self.params.combine_trees(finite_or_inf(out.reshape(self.n_models, self.n_trees)))
        return np.maximum(best * (1.0 - BOUND_SLACK), 0.0)
