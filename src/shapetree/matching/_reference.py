"""Slow, readable reference of the matching recursion (eq. 1), used as the test oracle.

This module follows the paper's definitions literally and shares no code with the
compiled kernel except the shape-tree itself: every ``dif`` is computed from the raw
triangles by its own literal pure-Python :func:`_dif` (centre, scale to unit size,
``1 - |<z, w>|^2``; the only ``dif`` of the project outside
:mod:`shapetree.geometry._dif`), and both base cases are evaluated by *actually
subdividing* the line segment and scoring the identity correspondence, as §3 describes.
The one convention it takes from :mod:`shapetree.geometry` is the rule for triangles of
zero size (:data:`~shapetree.geometry.DEGENERATE_DIF`). It is exponential without its
memo table and O(n m^3) Python steps with it: use it only for small curves (n, m <= ~16).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import cache, lru_cache

import numpy as np

from shapetree.geometry import DEGENERATE_DIF
from shapetree.geometry._dif import HYPERBOLIC_EPS
from shapetree.tree import ShapeTree


def _dif(tri_a: np.ndarray, tri_b: np.ndarray) -> float:
    """Squared full Procrustes distance of two labelled triangles, literally (§3).

    Both triangles (``(3, 2)`` arrays) are centred and scaled to unit size as complex
    vectors ``z``, ``w``; ``dif = 1 - |<z, w>|^2``. A triangle whose three points coincide
    has zero size and no shape: :data:`~shapetree.geometry.DEGENERATE_DIF`.
    """
    out = []
    for t in (np.asarray(tri_a, dtype=float), np.asarray(tri_b, dtype=float)):
        if all(p[0] == t[0][0] and p[1] == t[0][1] for p in t):
            return DEGENERATE_DIF
        z = [complex(x, y) for x, y in t]
        c = sum(z) / len(z)
        z = [v - c for v in z]
        size = math.sqrt(sum(abs(v) ** 2 for v in z))
        out.append([v / size for v in z])
    z, w = out
    ip = sum(a.conjugate() * b for a, b in zip(z, w, strict=True))
    return min(max(1.0 - abs(ip) ** 2, 0.0), 1.0)


def _hdif(tri_a: np.ndarray, tri_b: np.ndarray) -> float:
    """Regularised pseudo-hyperbolic ``dif`` of two labelled triangles, literally.

    With ``u``, ``v`` the Bookstein coordinates of the middle points (the base ``first ->
    last`` mapped to ``-1/2 -> 1/2``): ``min(1, |u - v|^2 / (|u - conj v|^2 + eps))``
    (:mod:`shapetree.geometry._dif`, ``eps`` = ``HYPERBOLIC_EPS``). A triangle of zero
    size: :data:`~shapetree.geometry.DEGENERATE_DIF`; a "needle" (``first == last``, ``u``
    at infinity): 0 against a needle, 1 against anything else.
    """
    us = []
    for t in (np.asarray(tri_a, dtype=float), np.asarray(tri_b, dtype=float)):
        if all(p[0] == t[0][0] and p[1] == t[0][1] for p in t):
            return DEGENERATE_DIF
        z1, z2, z3 = (complex(x, y) for x, y in t)
        us.append(None if z3 == z1 else (z2 - 0.5 * (z1 + z3)) / (z3 - z1))
    u, v = us
    if u is None or v is None:
        return 0.0 if u is None and v is None else 1.0
    r = abs(u - v) ** 2 / (abs(u - v.conjugate()) ** 2 + HYPERBOLIC_EPS)
    return min(r, 1.0)


#: The literal ``dif`` of each ``dif`` option.
DIF_FUNCTIONS = {"procrustes": _dif, "hyperbolic": _hdif}


def _arclen(p: np.ndarray) -> float:
    return float(np.sum(np.hypot(*np.diff(p, axis=0).T)))


def _identity_cost(
    p: np.ndarray,
    q: np.ndarray,
    weight: float,
    scale: float,
    mids: dict[tuple[int, int], int],
    power: float = 1.0,
    dif_fn=_dif,
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
        total += lam * dif_fn(p[[s, i, e]], q[[s, i, e]])
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
    dif : {"procrustes", "hyperbolic"}
        Which literal ``dif`` (:data:`DIF_FUNCTIONS`).
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
        dif: str = "procrustes",
    ) -> None:
        self.tree = tree
        self.dif = DIF_FUNCTIONS[dif]
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

    def base_cost(self, sa: int, ea: int, s: int, length: int) -> float:
        """The base cases of eq. (1): a segment of ``A`` (``ea - sa == 1``) or a target
        segment (``length == 1``), by actual subdivision (no replacement)."""
        a = self.u[sa : ea + 1]
        bsub = self.b_sub(s, length)
        if ea - sa == 1:
            if length == 1:
                return 0.0  # segment vs segment
            # subdivide A's segment to as many points as B' and match point for point
            t = np.linspace(0.0, 1.0, length + 1)[:, None]
            seg = a[0] + t * (a[1] - a[0])
            return self.segment_weight * _identity_cost(
                seg, bsub, self.weight, self.la, _half_mids(length + 1), self.power, self.dif
            )
        # subdivide B's segment to as many points as A' and match point for point
        k = ea - sa + 1
        t = np.linspace(0.0, 1.0, k)[:, None]
        seg = bsub[0] + t * (bsub[1] - bsub[0])
        mids = {
            (s0 - sa, e0 - sa): i - sa for (s0, e0), i in self.mids.items() if sa <= s0 and e0 <= ea
        }
        return _identity_cost(a, seg, self.weight, self.la, mids, self.power, self.dif)

    def split_cost(self, sa: int, ea: int, s: int, length: int, j: int) -> float:
        """λ dif of the node ``(sa, mid, ea)`` against the target triangle ``(b_s, b_{s+j},
        b_{s+length})`` (the term eq. (1) adds for split ``j``)."""
        i = self.mids[(sa, ea)]
        lam = self.weight * (_arclen(self.u[sa : ea + 1]) / self.la) ** self.power
        return lam * self.dif(self.u[[sa, i, ea]], self.b_sub(s, length)[[0, j, length]])

    def _psi(self, sa: int, ea: int, s: int, length: int) -> float:
        """ψ(U[sa..ea], B[s..s+length])."""
        if ea - sa == 1 or length == 1:
            cost = self.base_cost(sa, ea, s, length)
        else:
            i = self.mids[(sa, ea)]
            cost = math.inf
            for j in range(1, length):
                c = (
                    self.psi(sa, i, s, j)
                    + self.psi(i, ea, (s + j) % self.m if self.cyclic else s + j, length - j)
                    + self.split_cost(sa, ea, s, length, j)
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
    dif: str = "procrustes",
) -> float:
    """ψ(A, B) by the literal recursion: open A vs open B, or closed A vs closed B.

    Parameters
    ----------
    tree : ShapeTree
        Shape-tree of ``A``; ``tree.closed`` decides the mode (``B`` is taken to be of the
        same kind).
    b : ndarray, shape (m, 2)
    dif : {"procrustes", "hyperbolic"}

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
        dif=dif,
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
                + lam * _dif(rm.u[[sa, i, ea]], bsub[[0, j, length]])
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


def reference_score(
    tree: ShapeTree,
    b: np.ndarray,
    a_to_b: np.ndarray,
    replaced: Sequence[tuple[int, int, int, int]] = (),
    *,
    weight: float = 1.0,
    occlusion: float | None = None,
    power: float = 1.0,
    segment_weight: float = 1.0,
    dif: str = "procrustes",
) -> float:
    """The cost of one given correspondence, scored literally (the oracle of a traceback).

    Walks ``tree`` from its root(s) with the images the correspondence gives the nodes'
    endpoints: a node listed in ``replaced`` costs its replacement, a segment of ``A`` or
    a node mapped to a single target segment costs its base case (by subdivision),
    any other node its ``λ dif`` against the triangle of its endpoints' and midpoint's
    images plus its children's costs. Nothing is minimised, so the result equals the
    optimum only if the correspondence is optimal.

    Parameters
    ----------
    tree : ShapeTree
        The shape-tree the correspondence was found with (``MatchResult.tree_index``).
    b : ndarray, shape (m, 2)
    a_to_b : ndarray, shape (n,)
        Target index of every point of ``A`` in ``A``'s own indices (as
        ``MatchResult.a_to_b``: modulo ``m`` for closed curves; fractional or NaN values
        only where no node endpoint needs them).
    replaced : list of (a_start, a_end, b_start, b_end)
        As ``MatchResult.replaced`` (indices modulo ``n``, ``m`` for closed curves).
    weight, occlusion, power, segment_weight, dif
        As for :func:`reference_match_cost`.

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
        dif=dif,
    )
    m, n = rm.m, tree.n_points
    pos = np.asarray(a_to_b, dtype=float)
    if tree.closed:
        off = tree.offset
        s0 = float(pos[off % n])
        # unrolled target position of every unrolled point of A (u = 0 .. n)
        unrolled = [s0 + (float(pos[(u + off) % n]) - s0) % m for u in range(n)] + [s0 + m]
        reps = set()
        for a0, a1, _b0, _b1 in replaced:
            sa, ea = (a0 - off) % n, (a1 - off) % n
            reps.add((sa, ea if ea > sa else ea + n))
    else:
        unrolled = [float(p) for p in pos]
        reps = {(a0, a1) for a0, a1, _b0, _b1 in replaced}

    def image(u: int) -> int:
        p = unrolled[u]
        if not float(p).is_integer():
            raise ValueError(f"point {u} of the shape-tree has no integer image ({p})")
        return int(p)

    def visit(sa: int, ea: int) -> float:
        s, e = image(sa), image(ea)
        length = e - s
        if (sa, ea) in reps:
            if occlusion is None:
                raise ValueError("a replaced subcurve needs an occlusion factor")
            return rm._replace(sa, ea, s, length)
        if ea - sa == 1 or length == 1:
            return rm.base_cost(sa, ea, s, length)
        i = rm.mids[(sa, ea)]
        return rm.split_cost(sa, ea, s, length, image(i) - s) + visit(sa, i) + visit(i, ea)

    if not tree.closed:
        return visit(0, n - 1)
    return visit(0, tree.split_index) + visit(tree.split_index, n)


def reference_height_distance(
    a: np.ndarray,
    b: np.ndarray,
    n_entries_group: int,
    weights: Sequence[float],
    skip: float,
    complexity: bool = False,
) -> float:
    """The height-function distance ``h(A, B)`` of two sampled closed curves, literally
    (:mod:`shapetree.matching._height`, steps 2-4), sharing no code with the kernel.

    Parameters
    ----------
    a, b : (n, 2) arrays
        The sample points, counter-clockwise (already resampled; the same ``n``).
    n_entries_group : int
        Heights averaged into one descriptor entry.
    weights : sequence of float
        Weights of the descriptor entries.
    skip : float
        Cost of an unmatched point, in units of the mean point cost.
    complexity : bool
        Divide by ``C(A) + C(B)``: each curve's mean over descriptor columns of the
        column's population standard deviation, averaged over the curve and its mirror image.

    The descriptor is built point by point (the signed distance of every other point to the
    tangent line, averaged in groups that tile the other points or, when they cannot, come
    in mirror pairs from both ends, each divided by its column's largest magnitude); the
    matching is a memoised recursion over every start of B and over B and its mirror image
    (mirrored left to right, then traced counter-clockwise again). Pure Python: small
    curves only (n <= ~16).
    """

    def descriptor(p: list[tuple[float, float]]) -> list[list[float]]:
        n = len(p)
        rows = []
        for i in range(n):
            tx = p[(i + 1) % n][0] - p[i - 1][0]
            ty = p[(i + 1) % n][1] - p[i - 1][1]
            norm = math.hypot(tx, ty) or 1e-300
            nx, ny = -ty / norm, tx / norm
            hs = [
                (p[(i + k) % n][0] - p[i][0]) * nx + (p[(i + k) % n][1] - p[i][1]) * ny
                for k in range(1, n)
            ]
            g = n_entries_group
            if (n - 1) % g == 0:  # groups tile the points 1 .. n - 1
                groups = [list(range(k, k + g)) for k in range(1, n, g)]
            else:  # pairs of groups from both ends, each the other's mirror (k -> n - k)
                near = [list(range(k, k + g)) for k in range(1, g * ((n - 1) // g // 2), g)]
                far = [sorted(n - k for k in grp) for grp in reversed(near)]
                groups = near + far
            rows.append([sum(hs[k - 1] for k in grp) / g for grp in groups])
        for e in range(len(rows[0])):
            big = max(abs(r[e]) for r in rows) or 1.0
            for r in rows:
                r[e] /= big
        return rows

    def ccw(p: list[tuple[float, float]]) -> list[tuple[float, float]]:
        area = sum(
            p[i][0] * p[(i + 1) % len(p)][1] - p[(i + 1) % len(p)][0] * p[i][1]
            for i in range(len(p))
        )
        return p if area >= 0 else p[::-1]

    def match(fa: list[list[float]], fb: list[list[float]]) -> float:
        n, m = len(fa), len(fb)
        cost = [[sum(w * abs(x - y) for w, x, y in zip(weights, ra, rb)) for rb in fb] for ra in fa]
        pen = skip * sum(map(sum, cost)) / (n * m)
        best = math.inf
        for s in range(m):

            @cache
            def f(i: int, j: int, s: int = s) -> float:
                if i == 0 or j == 0:
                    return (i + j) * pen
                return min(
                    f(i - 1, j - 1) + cost[i - 1][(j - 1 + s) % m],
                    f(i - 1, j) + pen,
                    f(i, j - 1) + pen,
                )

            best = min(best, f(n, m))
        return best

    def spread(rows: list[list[float]]) -> float:
        cols = list(zip(*rows))
        sds = []
        for col in cols:
            mean = sum(col) / len(col)
            sds.append(math.sqrt(sum((x - mean) ** 2 for x in col) / len(col)))
        return sum(sds) / len(sds)

    pa = [(float(x), float(y)) for x, y in a]
    pb = [(float(x), float(y)) for x, y in b]
    fa = descriptor(ccw(pa))
    plain = descriptor(ccw(pb))
    mirrored = descriptor(ccw([(-x, y) for x, y in pb]))
    h = min(match(fa, plain), match(fa, mirrored)) / len(pa)
    if complexity:
        fa_mirrored = descriptor(ccw([(-x, y) for x, y in pa]))
        c = (spread(fa) + spread(fa_mirrored) + spread(plain) + spread(mirrored)) / 2
        h /= max(c, 0.01)
    return h
