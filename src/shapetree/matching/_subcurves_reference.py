"""Slow, literal oracle of the pair-of-subcurves DPs (:mod:`._subcurves`): tests only.

A memoised recursion over pairs of subcurves written from the definitions in the
docstring of :mod:`._subcurves`, sharing no code with the kernel: every ``dif`` is the
literal pure-Python one of :mod:`._reference` (Procrustes or hyperbolic), both base cases
are evaluated by actually subdividing the segment and scoring the identity correspondence
(:func:`._reference._identity_cost`), arclengths are summed point by point. Exponential
without its memo, polynomial but slow with it: curves of up to about 10 points.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np

from shapetree.matching._reference import DIF_FUNCTIONS, _arclen, _half_mids, _identity_cost

__all__ = ["reference_pair_cost"]


class _Curve:
    def __init__(self, pts: np.ndarray, closed: bool) -> None:
        self.p = np.asarray(pts, dtype=float)
        self.n = len(self.p)
        self.closed = closed
        ring = np.vstack([self.p, self.p[:1]]) if closed else self.p
        self.total = _arclen(ring)

    def sub(self, s: int, length: int) -> np.ndarray:
        return self.p[[(s + t) % self.n for t in range(length + 1)]]


def reference_pair_cost(
    a: np.ndarray,
    b: np.ndarray,
    *,
    closed: bool,
    symmetric: bool,
    replace_any: bool,
    dif: str = "procrustes",
    occlusion: float | None = None,
    weight: float = 1.0,
    power: float = 1.0,
    segment_weight: float = 1.0,
    n_trees: int = 1,
) -> float:
    """ψ of the pair DP by the literal recursion (no band).

    Parameters
    ----------
    a, b : ndarray, shapes (n, 2), (m, 2)
    closed : bool
    symmetric, replace_any : bool
        The options of :func:`._subcurves.pair_tables`.
    dif, occlusion, weight, power, segment_weight, n_trees
        As in :class:`shapetree.matching.MatchConfig`.

    Returns
    -------
    float
    """
    A, B = _Curve(a, closed), _Curve(b, closed)
    d = DIF_FUNCTIONS[dif]

    def lam(c: _Curve, s: int, length: int) -> float:
        return weight * (_arclen(c.sub(s, length)) / c.total) ** power

    def rel(c: _Curve, s: int, length: int) -> float:
        return _arclen(c.sub(s, length)) / c.total

    def flat(c: _Curve, s: int, length: int) -> float:
        p = c.sub(s, length)
        t = np.linspace(0.0, 1.0, length + 1)[:, None]
        seg = p[0] + t * (p[-1] - p[0])
        return _identity_cost(p, seg, weight, c.total, _half_mids(length + 1), power, d)

    def seg_vs(sa: int, sb: int, lb: int) -> float:
        """Directed base: A's segment subdivided onto B'."""
        seg2 = A.sub(sa, 1)
        t = np.linspace(0.0, 1.0, lb + 1)[:, None]
        seg = seg2[0] + t * (seg2[1] - seg2[0])
        cost = _identity_cost(seg, B.sub(sb, lb), weight, A.total, _half_mids(lb + 1), power, d)
        return segment_weight * cost

    def rep(sa: int, la: int, sb: int, lb: int) -> float:
        if occlusion is None:
            return math.inf
        lm = 0.5 * (lam(A, sa, la) + lam(B, sb, lb)) if symmetric else lam(A, sa, la)
        return occlusion * lm * (rel(A, sa, la) + rel(B, sb, lb))

    def cut(sa: int, la: int, sb: int, lb: int, i: int, k: int) -> float:
        """The triangle term anchoring a cut of (A', B') at (i, k)."""
        lm = 0.5 * (lam(A, sa, la) + lam(B, sb, lb)) if symmetric else lam(A, sa, la)
        return lm * d(A.sub(sa, la)[[0, i, la]], B.sub(sb, lb)[[0, k, lb]])

    @cache
    def h(sa: int, la: int, sb: int, lb: int) -> float:
        best = rep(sa, la, sb, lb)
        for i in range(1, la):
            for k in range(1, lb):
                v = rep(sa, i, sb, k) + psi((sa + i) % A.n, la - i, (sb + k) % B.n, lb - k)
                best = min(best, v + cut(sa, la, sb, lb, i, k))
        return best

    @cache
    def psi(sa: int, la: int, sb: int, lb: int) -> float:
        pa, pb = A.sub(sa, la), B.sub(sb, lb)
        if la == 1 and lb == 1:
            best = 0.0
        elif la == 1:
            best = flat(B, sb, lb) if symmetric else seg_vs(sa, sb, lb)
        elif lb == 1:
            best = flat(A, sa, la)
        else:
            best = math.inf
            i = la // 2
            for k in range(1, lb):
                v = (
                    psi(sa, i, sb, k)
                    + psi((sa + i) % A.n, la - i, (sb + k) % B.n, lb - k)
                    + lam(A, sa, la) * d(pa[[0, i, la]], pb[[0, k, lb]])
                )
                best = min(best, v)
            if symmetric:
                k = lb // 2
                for i in range(1, la):
                    v = (
                        psi(sa, i, sb, k)
                        + psi((sa + i) % A.n, la - i, (sb + k) % B.n, lb - k)
                        + lam(B, sb, lb) * d(pa[[0, i, la]], pb[[0, k, lb]])
                    )
                    best = min(best, v)
        best = min(best, rep(sa, la, sb, lb))
        if replace_any:
            best = min(best, h(sa, la, sb, lb))
            for i in range(1, la):
                for k in range(1, lb):
                    v = psi(sa, i, sb, k) + h((sa + i) % A.n, la - i, (sb + k) % B.n, lb - k)
                    best = min(best, v + cut(sa, la, sb, lb, i, k))
        return best

    if not closed:
        return psi(0, A.n - 1, 0, B.n - 1)
    best = math.inf
    sides = [(A, B, False)] + ([(B, A, True)] if symmetric else [])
    for x, y, swapped in sides:
        k = x.n // 2
        for o in sorted({(t * x.n) // (2 * n_trees) for t in range(n_trees)}):
            for s in range(y.n):
                for length in range(1, y.n):
                    if swapped:
                        v = psi(s, length, o, k) + psi(
                            (s + length) % A.n, A.n - length, (o + k) % B.n, B.n - k
                        )
                    else:
                        v = psi(o, k, s, length) + psi(
                            (o + k) % A.n, A.n - k, (s + length) % B.n, B.n - length
                        )
                    best = min(best, v)
    return best
