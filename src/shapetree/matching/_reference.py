"""Slow, readable reference of the matching recursion (eq. 1), used as the test oracle.

This module follows the paper's definitions literally and shares no code with the
compiled kernel except the shape-tree itself: every ``dif`` is computed from the raw
triangles, and both base cases are evaluated by *actually subdividing* the line segment
and scoring the identity correspondence, as §3 describes. It is exponential without its
memo table and O(n m^3) Python steps with it: use it only for small curves (n, m <= ~16).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from shapetree.geometry import triangle_dif
from shapetree.tree import ShapeTree


def _arclen(p: np.ndarray) -> float:
    return float(np.sum(np.hypot(*np.diff(p, axis=0).T)))


def _identity_cost(
    p: np.ndarray,
    q: np.ndarray,
    weight: float,
    scale: float,
    mids: dict[tuple[int, int], int],
    power: float = 1.0,
) -> float:
    """Cost of deforming ``p`` onto ``q`` point for point (same length), over a tree of ``p``.

    ``mids`` gives the midpoint of each subcurve (s, e) of the tree used; λ of a node is
    ``weight * arclength(p[s..e]) / scale``.
    """
    total = 0.0
    stack = [(0, len(p) - 1)]
    while stack:
        s, e = stack.pop()
        if e - s < 2:
            continue
        i = mids[(s, e)]
        lam = weight * (_arclen(p[s : e + 1]) / scale) ** power
        total += lam * float(triangle_dif(p[[s, i, e]], q[[s, i, e]]))
        stack += [(s, i), (i, e)]
    return total


def _half_mids(k: int) -> dict[tuple[int, int], int]:
    out: dict[tuple[int, int], int] = {}
    stack = [(0, k - 1)]
    while stack:
        s, e = stack.pop()
        if e - s < 2:
            continue
        i = s + (e - s) // 2
        out[(s, e)] = i
        stack += [(s, i), (i, e)]
    return out


class ReferenceMatcher:
    """Memoised recursion ψ(A', B') of eq. (1) for one model tree and one target curve.

    Parameters
    ----------
    tree : ShapeTree
        Shape-tree of the curve ``A`` that is deformed.
    b : ndarray, shape (m, 2)
        Target curve ``B``.
    cyclic : bool
        Whether subcurves of ``B`` may wrap around (``B`` closed).
    weight : float
        λ of a node is ``weight * arclength(A') / length_scale``.
    occlusion : float or None
        Replacement cost factor κ: ψ(A', B') is bounded by ``κ λ_{A'} (|A'| + |B'|)``
        with lengths relative to the total lengths of ``A`` and ``B``.
    length_scale : float or None
        Default: the length of ``A`` (perimeter for closed curves).
    """

    def __init__(
        self,
        tree: ShapeTree,
        b: np.ndarray,
        *,
        cyclic: bool,
        weight: float = 1.0,
        occlusion: float | None = None,
        length_scale: float | None = None,
        power: float = 1.0,
        segment_weight: float = 1.0,
    ) -> None:
        self.tree = tree
        self.segment_weight = segment_weight
        self.u = tree.unrolled
        self.b = np.asarray(b, dtype=float)
        self.m = len(self.b)
        self.cyclic = cyclic
        self.weight = weight
        self.power = power
        self.occlusion = occlusion
        self.la = length_scale if length_scale is not None else _arclen(self.u)
        bb = np.vstack([self.b, self.b[:1]]) if cyclic else self.b
        self.lb = _arclen(bb)
        self.node_of = {
            (int(s), int(e)): v for v, (s, e) in enumerate(zip(tree.start, tree.end, strict=True))
        }
        self.mids = {
            (int(s), int(e)): int(i) for s, i, e in zip(tree.start, tree.mid, tree.end, strict=True)
        }
        self.psi = lru_cache(maxsize=None)(self._psi)

    def b_sub(self, s: int, length: int) -> np.ndarray:
        idx = [(s + t) % self.m if self.cyclic else s + t for t in range(length + 1)]
        return self.b[idx]

    def _replace(self, sa: int, ea: int, s: int, length: int) -> float:
        a_len = _arclen(self.u[sa : ea + 1]) / self.la
        b_len = _arclen(self.b_sub(s, length)) / self.lb
        return self.occlusion * self.weight * a_len**self.power * (a_len + b_len)

    def _psi(self, sa: int, ea: int, s: int, length: int) -> float:
        """ψ(U[sa..ea], B[s..s+length])."""
        a = self.u[sa : ea + 1]
        bsub = self.b_sub(s, length)
        if ea - sa == 1:
            if length == 1:
                cost = 0.0  # segment vs segment
            else:
                # subdivide A's segment to as many points as B' and match point for point
                t = np.linspace(0.0, 1.0, length + 1)[:, None]
                seg = a[0] + t * (a[1] - a[0])
                cost = self.segment_weight * _identity_cost(
                    seg, bsub, self.weight, self.la, _half_mids(length + 1), self.power
                )
        elif length == 1:
            # subdivide B's segment to as many points as A' and match point for point
            k = ea - sa + 1
            t = np.linspace(0.0, 1.0, k)[:, None]
            seg = bsub[0] + t * (bsub[1] - bsub[0])
            mids = {
                (s0 - sa, e0 - sa): i - sa
                for (s0, e0), i in self.mids.items()
                if sa <= s0 and e0 <= ea
            }
            cost = _identity_cost(a, seg, self.weight, self.la, mids, self.power)
        else:
            i = self.mids[(sa, ea)]
            lam = self.weight * (_arclen(a) / self.la) ** self.power
            cost = math.inf
            for j in range(1, length):
                tri_b = bsub[[0, j, length]]
                c = (
                    self.psi(sa, i, s, j)
                    + self.psi(i, ea, (s + j) % self.m if self.cyclic else s + j, length - j)
                    + lam * float(triangle_dif(self.u[[sa, i, ea]], tri_b))
                )
                cost = min(cost, c)
        if self.occlusion is not None:
            cost = min(cost, self._replace(sa, ea, s, length))
        return cost

    def root_cost(self, root_range: tuple[int, int], s: int, length: int) -> float:
        return self.psi(root_range[0], root_range[1], s, length)


def reference_match_cost(
    tree: ShapeTree,
    b: np.ndarray,
    *,
    weight: float = 1.0,
    occlusion: float | None = None,
    power: float = 1.0,
    segment_weight: float = 1.0,
) -> float:
    """ψ(A, B) by the literal recursion: open A vs open B, or closed A vs closed B.

    Parameters
    ----------
    tree : ShapeTree
        Shape-tree of ``A``; ``tree.closed`` decides the mode (``B`` is taken to be of the
        same kind).
    b : ndarray, shape (m, 2)

    Returns
    -------
    float
    """
    rm = ReferenceMatcher(
        tree,
        b,
        cyclic=tree.closed,
        weight=weight,
        occlusion=occlusion,
        power=power,
        segment_weight=segment_weight,
    )
    m = rm.m
    if not tree.closed:
        return rm.psi(0, tree.n_points - 1, 0, m - 1)
    k, n = tree.split_index, tree.n_points
    best = math.inf
    for s in range(m):
        for length in range(1, m):
            c = rm.psi(0, k, s, length) + rm.psi(k, n, (s + length) % m, m - length)
            best = min(best, c)
    return best


def reference_subcurve_table(
    tree: ShapeTree,
    b: np.ndarray,
    *,
    weight: float = 1.0,
    occlusion: float | None = None,
    length_scale: float | None = None,
) -> np.ndarray:
    """Cost of deforming the open curve of ``tree`` to every cyclic subcurve of closed ``b``.

    Returns
    -------
    ndarray, shape (m, m)
        Entry ``[s, L]``: target subcurve from index ``s`` going forward ``L`` segments;
        column 0 is ``inf``.
    """
    rm = ReferenceMatcher(
        tree, b, cyclic=True, weight=weight, occlusion=occlusion, length_scale=length_scale
    )
    m = rm.m
    out = np.full((m, m), np.inf)
    for s in range(m):
        for length in range(1, m):
            out[s, length] = rm.psi(0, tree.n_points - 1, s, length)
    return out


def reference_correspondence(
    tree: ShapeTree,
    b: np.ndarray,
    *,
    weight: float = 1.0,
    tol: float = 1e-9,
) -> tuple[float, dict[int, int], bool]:
    """Optimal cost and the target index of every *node* point of ``A`` (no occlusion).

    Returns
    -------
    cost : float
    mapping : dict
        Unrolled index of each endpoint/midpoint of ``A`` -> unrolled index on ``B``.
    unique : bool
        False when some choice along the way was tied within ``tol`` (then another
        optimal correspondence exists).
    """
    rm = ReferenceMatcher(tree, b, cyclic=tree.closed, weight=weight)
    m = rm.m
    unique = True
    mapping: dict[int, int] = {}

    def pick(cands: list[tuple[float, object]]) -> object:
        nonlocal unique
        cands.sort(key=lambda c: c[0])
        if len(cands) > 1 and cands[1][0] - cands[0][0] <= tol * (1 + abs(cands[0][0])):
            unique = False
        return cands[0][1]

    def visit(sa: int, ea: int, s: int, length: int) -> None:
        if ea - sa < 2 or length < 2:
            return
        i = rm.mids[(sa, ea)]
        lam = weight * _arclen(rm.u[sa : ea + 1]) / rm.la
        bsub = rm.b_sub(s, length)
        cands = []
        for j in range(1, length):
            c = (
                rm.psi(sa, i, s, j)
                + rm.psi(i, ea, (s + j) % m if rm.cyclic else s + j, length - j)
                + lam * float(triangle_dif(rm.u[[sa, i, ea]], bsub[[0, j, length]]))
            )
            cands.append((c, j))
        j = int(pick(cands))
        mapping[i] = s + j
        visit(sa, i, s, j)
        visit(i, ea, s + j, length - j)

    if not tree.closed:
        n = tree.n_points
        mapping[0], mapping[n - 1] = 0, m - 1
        cost = rm.psi(0, n - 1, 0, m - 1)
        visit(0, n - 1, 0, m - 1)
        return cost, mapping, unique
    k, n = tree.split_index, tree.n_points
    cands = []
    for s in range(m):
        for length in range(1, m):
            c = rm.psi(0, k, s, length) + rm.psi(k, n, (s + length) % m, m - length)
            cands.append((c, (s, length)))
    s, length = pick(cands)  # type: ignore[misc]
    cost = cands[0][0]
    mapping[0], mapping[k], mapping[n] = s, s + length, s + m
    visit(0, k, s, length)
    visit(k, n, s + length, m - length)
    return cost, mapping, unique
