"""Elastic matching by dynamic programming over the shape-tree (paper §3, eq. 1).

``ψ(A, B) = min_j ψ(A1, B1) + ψ(A2, B2) + λ_A dif(L(a_i | a_1, a_n), L(b_j | b_1, b_m))``

The compiled kernel lives in :mod:`shapetree.matching._kernels`; the slow, literal
reference used as the test oracle lives in :mod:`shapetree.matching._reference`.

Interpretations of the paper (where its text is terse)
------------------------------------------------------
1. **dif** is the squared *full* Procrustes distance between the labelled triangles
   ``(a_1, a_i, a_n)`` and ``(b_1, b_j, b_m)``: with both centred and scaled to unit size,
   ``dif = 1 - |<z, w>|^2`` (in ``[0, 1]``). Reflections are not factored out, so a
   shape and its mirror image differ. It is computed from Helmert coordinates, so it is
   defined even when ``b_1 == b_m``.
2. **λ_A** is ``weight * arclength(A') / arclength(A)``: proportional to the length of the
   subcurve being deformed, normalised so that costs are invariant to scaling either curve.
3. **Base cases.** Segment vs segment costs 0. A segment of ``A`` vs a target subcurve
   of ``L + 1`` points: the segment is subdivided evenly into ``L + 1`` points, matched
   point for point to the target subcurve, and scored over the half-split shape-tree of
   those points (λ of each node from its share of the segment's length). A subcurve
   ``A'`` of ``k`` points vs a target *segment*: the segment is subdivided evenly into
   ``k`` points, matched point for point, and scored over ``A'``'s own subtree.
4. **No collapse.** Every subcurve of ``A`` maps to at least one target segment: the
   midpoint's image ``b_j`` lies strictly between ``b_s`` and ``b_e``.
5. **Closed curves.** ``A`` is cut at ``a_0`` and its first midpoint ``a_k`` into two open
   halves with their own shape-trees; the cost is ``min_{s, e} T1[s, e] + T2[e, s]`` over
   all target points ``s != e`` (every cyclic alignment), with no ``dif`` term at the
   top: the pair ``(a_0, a_k)`` has no shape of its own.
6. **Occlusion.** Every table entry (node or segment) is bounded by the replacement cost
   ``κ λ_{A'} (|A'| + |B'|)`` with lengths relative to the curves' total lengths; the
   replaced ranges are reported and their interior points get no correspondence (NaN).
7. **Several shape-trees.** Closed curves: the same midpoint rule started at ``T``
   different points, offsets ``t n / (2T)`` (a tree cuts the curve at ``a_0`` and
   ``a_{n/2}``, so a tree started half-way round would repeat one). Open curves (endpoints
   fixed): the two midpoint rules, ``"half"`` and ``"best"``.
8. **Pruned mode** (not in the paper, off by default): ``MatchParams(band=r)`` restricts a
   subcurve of ``k`` segments to target subcurves of about ``k m / n`` segments, within
   a stretch factor ``r``.
"""

from shapetree.matching._api import match, mirror_curve
from shapetree.matching._config import OPTIONS, PRESETS, MatchConfig
from shapetree.matching._match import (
    MatchParams,
    MatchResult,
    match_cost,
    match_prepared,
    subcurve_table,
)
from shapetree.matching._prepare import Model, Target, prepare_model, prepare_target

__all__ = [
    "OPTIONS",
    "PRESETS",
    "MatchConfig",
    "MatchParams",
    "MatchResult",
    "Model",
    "Target",
    "match",
    "match_cost",
    "match_prepared",
    "mirror_curve",
    "prepare_model",
    "prepare_target",
    "subcurve_table",
]
