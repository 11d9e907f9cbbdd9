"""Dynamic programs over pairs of subcurves: the symmetric matcher and arbitrary replacement.

The shape-tree matcher (:mod:`._kernels`) deforms the fixed shape-tree of ``A``: its
states are (node of A's tree, subcurve of B). The two options here need states for
*every* pair of subcurves ``(A', B')``, ``A' = A[sa .. sa + la]``, ``B' = B[sb .. sb +
lb]`` (indices modulo the number of points of a closed curve), with the half rule giving
every subcurve its midpoint ``sa + la // 2`` (the ``split="half"`` shape-tree is exactly
this rule applied from the root down, so its nodes are some of these states).

Recursion
---------
Write ``λ_A(A') = weight (|A'| / |A|) ** length_power``, ``ρ_A(A') = |A'| / |A|`` (and the
same for B), ``dif`` the configured triangle dissimilarity (Procrustes or hyperbolic) and
``tri_A(sa, la, i)`` the triangle ``(a_sa, a_{sa+i}, a_{sa+la})``. For ``la, lb >= 2``

    D_A(A', B') = min_{0 < k < lb}  S(A'[.. la//2], B'[.. k]) + S(A'[la//2 ..], B'[k ..])
                                   + λ_A(A') dif(tri_A(sa, la, la//2), tri_B(sb, lb, k))

(A' split at its midpoint, B' anywhere: the shape-tree recursion, eq. (1)), and, for the
symmetric matcher, the mirror term with the roles of the curves exchanged,

    D_B(A', B') = min_{0 < i < la}  S(A'[.. i], B'[.. lb//2]) + S(A'[i ..], B'[lb//2 ..])
                                   + λ_B(B') dif(tri_A(sa, la, i), tri_B(sb, lb, lb//2)).

Base cases: two segments cost 0; a subcurve against a single segment of the other curve
costs ``F(subcurve)``, the cost of deforming it over its own half-rule tree onto the
straight, evenly subdivided segment (the matcher's ``flat``); in the directed form a
segment of A against a longer ``B'`` costs ``segment_weight λ_A(segment) G(B')`` (the
matcher's ``g``), in the symmetric form ``F(B')``. The replacement (occlusion ``κ``) is

    R(A', B') = κ λ (ρ_A(A') + ρ_B(B')),  λ = λ_A(A') (directed), (λ_A(A') + λ_B(B')) / 2
                                                                  (symmetric).

Then ``S = min(D_A, [D_B], R)`` for the plain options. **Arbitrary replacement**
(``replace_any``) adds cuts of ``(A', B')`` at any pair of points ``(i, k)``, each
anchored by the state's triangle term ``C(i, k) = λ dif(tri_A(sa, la, i), tri_B(sb, lb,
k))`` (the cut is a shape-tree node split at ``i`` instead of the midpoint, so the pieces
stay placed relative to each other) with one side starting with a replaced piece: with

    H(A', B') = min( R(A', B'),
                     min_{i, k} R(A'[.. i], B'[.. k]) + S(A'[i ..], B'[k ..]) + C(i, k) )

(a replaced piece first, then anything), ``S`` also takes ``H(A', B')`` and
``min_{i, k} S(A'[.. i], B'[.. k]) + H(A'[i ..], B'[k ..]) + C(i, k)``: any sequence of
deformed and replaced pieces, so any part of A together with any part of B can be
replaced, not only a subtree of A's tree; the directed matcher's matchings (half-rule
tree) are among them, so its cost is never higher.

The top: open curves ``S(A, B)``; closed curves cut A at ``a_o`` and ``a_{o + n//2}``
for the tree offsets ``o`` of ``n_trees`` (:func:`._prepare.tree_variants`) and B
anywhere, ``min_{sb, lb} S(A[o .. o + n//2], B[sb .. sb + lb]) + S(A[o + n//2 .. o + n],
B[sb + lb .. sb + m])`` (the shape-tree matcher's top); the symmetric matcher also takes
the same with the roles exchanged (B cut at its offsets, A anywhere).

Symmetry
--------
Every term of the symmetric recursion maps onto a term of the recursion with ``A`` and
``B`` exchanged (``D_A <-> D_B``, the base cases, ``R``, the two tops), so ``S_{A,B}(A',
B') = S_{B,A}(B', A')`` by induction and ψ(A, B) = ψ(B, A) **exactly**: the kernel is
compiled without fast-math and evaluates both mirror terms with the same operations in the
same order (:func:`shapetree.geometry._dif.exact_dif_kind` is bitwise symmetric), so the
floats agree bit for bit (tested).

Complexity
----------
States: ``n^2 m^2`` (all pairs of subcurves; a ``band`` keeps the pairs whose relative
lengths differ by at most that factor). Directed recursion: ``O(m)`` per state, the
symmetric one ``O(n + m)``: ``O(n^2 m^2 (n + m))`` time, against ``O(n m^3)`` for the
shape-tree matcher (the paper's footnote 1: "a less efficient algorithm"). Arbitrary
replacement: ``O(n m)`` per state, ``O(n^3 m^3)`` time (the end of §3). Memory: one
(two with ``replace_any``) float64 tables of ``n^2 m^2`` entries (50 MB each at n = m =
50). Single-pair options: seconds per pair at n = m = 50 (``benchmarks/bench_match.py``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from shapetree._errors import ShapeTreeError
from shapetree.geometry._dif import exact_dif_kind, unit_helmert
from shapetree.matching._kernels import SENTINEL
from shapetree.matching._prepare import prepare_target

__all__ = [
    "MAX_TABLE_BYTES",
    "PairCurve",
    "admissible_lengths",
    "pair_curve",
    "pair_tables",
    "pair_top",
    "pair_traceback",
]

#: Largest DP table this module allocates (a ``ShapeTreeError`` names the sizes beyond).
MAX_TABLE_BYTES = 2 * 1024**3

# no fast-math: the symmetric recursion must give bitwise equal floats both ways round
_jit = njit(cache=True, nogil=True)


@dataclass(frozen=True, eq=False)
class PairCurve:
    """Per-curve tables of the pair DPs (either curve, either role).

    Attributes
    ----------
    points : ndarray, shape (N, 2)
    closed : bool
    tri : ndarray, shape (N, N, 3, N)
        ``[L, k, :, s]``: unit Helmert coordinates of ``(x_s, x_{s+k}, x_{s+L})``.
    lam, rel, flat, g : ndarray, shape (N, N)
        ``[L, s]``: λ, relative arclength, the flat base cost ``F`` and the per-unit-λ
        base cost ``G`` of the subcurve ``(s, L)`` (module docstring).
    """

    points: np.ndarray
    closed: bool
    tri: np.ndarray
    lam: np.ndarray
    rel: np.ndarray
    flat: np.ndarray
    g: np.ndarray

    @property
    def n_points(self) -> int:
        return int(self.points.shape[0])

    @property
    def n_segments(self) -> int:
        n = self.n_points
        return n if self.closed else n - 1


@_jit
def _flat_table(tri: np.ndarray, lam: np.ndarray, cyclic: bool, hyper: bool, out: np.ndarray):
    """``out[L, s] = F``: the subcurve over its half-rule tree against a straight segment."""
    n = lam.shape[0]
    for length in range(2, n):
        kk = length // 2
        w = kk / length - 0.5
        e1, e2, _ = unit_helmert(-0.5, 0.0, w, 0.0, 0.5, 0.0)
        ns = n if cyclic else n - length
        for s in range(ns):
            d = exact_dif_kind(
                tri[length, kk, 0, s],
                tri[length, kk, 1, s],
                tri[length, kk, 2, s],
                e1,
                e2,
                0.0,
                hyper,
            )
            right = (s + kk) % n
            out[length, s] = lam[length, s] * d + out[kk, s] + out[length - kk, right]


def pair_curve(
    points: np.ndarray,
    *,
    closed: bool,
    weight: float,
    length_power: float,
    dif: str,
) -> PairCurve:
    """The tables of one curve for :func:`pair_tables` (same tables whatever its role).

    Parameters
    ----------
    points : ndarray, shape (N, 2)
    closed : bool
    weight, length_power : float
        λ of a subcurve is ``weight * (relative length) ** length_power``.
    dif : {"procrustes", "hyperbolic"}

    Returns
    -------
    PairCurve
    """
    t = prepare_target(points, closed=closed, length_power=length_power, dtype=np.float64)
    n = t.n_points
    rel = np.ascontiguousarray(t.blen, dtype=np.float64)
    lam = weight * rel**length_power
    flat = np.zeros((n, n))
    tri = np.ascontiguousarray(t.tri)
    _flat_table(tri, lam, closed, dif == "hyperbolic", flat)
    return PairCurve(
        points=t.points,
        closed=closed,
        tri=tri,
        lam=np.ascontiguousarray(lam),
        rel=rel,
        flat=flat,
        g=np.ascontiguousarray(t.base_table(dif), dtype=np.float64),
    )


def admissible_lengths(na: int, nb: int, nseg_a: int, nseg_b: int, band: float | None):
    """``ok[la, lb]``: the pairs of lengths the DP fills (all with ``band=None``).

    With a band ``r``: ``lb <= r la ρ + 1`` and ``la <= r lb / ρ + 1``, ``ρ = nseg_b /
    nseg_a`` (symmetric under exchanging the curves).
    """
    la = np.arange(na)[:, None].astype(float)
    lb = np.arange(nb)[None, :].astype(float)
    ok = (la >= 1) & (lb >= 1)
    if band is not None:
        ok &= lb * nseg_a <= band * la * nseg_b + nseg_a
        ok &= la * nseg_b <= band * lb * nseg_a + nseg_b
    return np.ascontiguousarray(ok.astype(np.uint8))


@_jit
def _fill(
    tri_a, lam_a, rel_a, flat_a, g_a, cyc_a,
    tri_b, lam_b, rel_b, flat_b, g_b, cyc_b,
    ok, sym, gaps, hyper, occlusion, seg_weight, S, H,
):  # fmt: skip
    na = lam_a.shape[0]
    nb = lam_b.shape[0]
    occl = occlusion > 0.0
    for la in range(1, na):
        nsa = na if cyc_a else na - la
        for lb in range(1, nb):
            nsb = nb if cyc_b else nb - lb
            if not ok[la, lb]:
                for sa in range(nsa):
                    for sb in range(nsb):
                        S[la, lb, sa, sb] = SENTINEL
                        if gaps:
                            H[la, lb, sa, sb] = SENTINEL
                continue
            ka = la // 2
            kb = lb // 2
            for sa in range(nsa):
                lam1 = lam_a[la, sa]
                ra = rel_a[la, sa]
                for sb in range(nsb):
                    lam2 = lam_b[lb, sb]
                    if sym:
                        rlam = 0.5 * (lam1 + lam2)
                    else:
                        rlam = lam1
                    rep = occlusion * rlam * (ra + rel_b[lb, sb]) if occl else SENTINEL
                    if la == 1 and lb == 1:
                        c = 0.0
                    elif la == 1:
                        if sym:
                            c = flat_b[lb, sb]
                        else:
                            c = seg_weight * lam1 * g_b[lb, sb]
                    elif lb == 1:
                        c = flat_a[la, sa]
                    else:
                        c = SENTINEL
                        sa2 = (sa + ka) % na
                        a1 = tri_a[la, ka, 0, sa]
                        a2r = tri_a[la, ka, 1, sa]
                        a2i = tri_a[la, ka, 2, sa]
                        for k in range(1, lb):
                            if not (ok[ka, k] and ok[la - ka, lb - k]):
                                continue
                            d = exact_dif_kind(
                                a1,
                                a2r,
                                a2i,
                                tri_b[lb, k, 0, sb],
                                tri_b[lb, k, 1, sb],
                                tri_b[lb, k, 2, sb],
                                hyper,
                            )
                            v = S[ka, k, sa, sb] + S[la - ka, lb - k, sa2, (sb + k) % nb] + lam1 * d
                            if v < c:
                                c = v
                        if sym:
                            sb2 = (sb + kb) % nb
                            b1 = tri_b[lb, kb, 0, sb]
                            b2r = tri_b[lb, kb, 1, sb]
                            b2i = tri_b[lb, kb, 2, sb]
                            for i in range(1, la):
                                if not (ok[i, kb] and ok[la - i, lb - kb]):
                                    continue
                                d = exact_dif_kind(
                                    tri_a[la, i, 0, sa],
                                    tri_a[la, i, 1, sa],
                                    tri_a[la, i, 2, sa],
                                    b1,
                                    b2r,
                                    b2i,
                                    hyper,
                                )
                                v = (
                                    S[i, kb, sa, sb]
                                    + S[la - i, lb - kb, (sa + i) % na, sb2]
                                    + lam2 * d
                                )
                                if v < c:
                                    c = v
                    if rep < c:
                        c = rep
                    if gaps:
                        # a cut of (A', B') at (i, k), anchored by the triangle term of
                        # the state (as a shape-tree node split at i): H takes a replaced
                        # piece first and anything after it, S anything first and then a
                        # part that starts with a replaced piece
                        h = rep
                        g = SENTINEL
                        for i in range(1, la):
                            sai = (sa + i) % na
                            ri = rel_a[i, sa]
                            li = lam_a[i, sa]
                            t1 = tri_a[la, i, 0, sa]
                            t2r = tri_a[la, i, 1, sa]
                            t2i = tri_a[la, i, 2, sa]
                            for k in range(1, lb):
                                if not (ok[i, k] and ok[la - i, lb - k]):
                                    continue
                                sbk = (sb + k) % nb
                                d = rlam * exact_dif_kind(
                                    t1,
                                    t2r,
                                    t2i,
                                    tri_b[lb, k, 0, sb],
                                    tri_b[lb, k, 1, sb],
                                    tri_b[lb, k, 2, sb],
                                    hyper,
                                )
                                if sym:
                                    rl = 0.5 * (li + lam_b[k, sb])
                                else:
                                    rl = li
                                v = (
                                    occlusion * rl * (ri + rel_b[k, sb])
                                    + S[la - i, lb - k, sai, sbk]
                                )
                                v = v + d
                                if v < h:
                                    h = v
                                w = S[i, k, sa, sb] + H[la - i, lb - k, sai, sbk] + d
                                if w < g:
                                    g = w
                        H[la, lb, sa, sb] = h
                        if h < c:
                            c = h
                        if g < c:
                            c = g
                    S[la, lb, sa, sb] = c


def pair_tables(
    ca: PairCurve,
    cb: PairCurve,
    *,
    symmetric: bool,
    replace_any: bool,
    dif: str,
    occlusion: float | None,
    segment_weight: float = 1.0,
    band: float | None = None,
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """Fill the tables ``S`` (and ``H``) of the pair DP (module docstring).

    Parameters
    ----------
    ca, cb : PairCurve
        From :func:`pair_curve`; both closed or both open.
    symmetric : bool
        Add the mirror term ``D_B`` and the symmetric base cases and replacement.
    replace_any : bool
        Arbitrary replacement (needs ``occlusion``).
    dif : {"procrustes", "hyperbolic"}
    occlusion : float or None
    segment_weight : float
        Directed base case factor (the symmetric form needs 1).
    band : float or None

    Returns
    -------
    S : ndarray, shape (N_A, N_B, N_A, N_B)
        ``S[la, lb, sa, sb]``; :data:`._kernels.SENTINEL` where not admissible.
    H : ndarray or None
    ok : ndarray of uint8, shape (N_A, N_B)
    """
    if ca.closed != cb.closed:
        raise ShapeTreeError("both curves must be closed or both open")
    if replace_any and occlusion is None:
        raise ShapeTreeError("replace_any needs an occlusion factor")
    if symmetric and segment_weight != 1.0:
        raise ShapeTreeError("the symmetric matcher needs segment_weight=1")
    na, nb = ca.n_points, cb.n_points
    nbytes = na * na * nb * nb * 8 * (2 if replace_any else 1)
    if nbytes > MAX_TABLE_BYTES:
        raise ShapeTreeError(
            f"the pair DP of {na} x {nb} points needs {nbytes / 2**30:.1f} GiB of tables "
            f"(limit {MAX_TABLE_BYTES / 2**30:.0f} GiB): use fewer points (n_points)"
        )
    ok = admissible_lengths(na, nb, ca.n_segments, cb.n_segments, band)
    S = np.full((na, nb, na, nb), SENTINEL)
    H = np.full((na, nb, na, nb), SENTINEL) if replace_any else np.zeros((1, 1, 1, 1))
    _fill(
        ca.tri, ca.lam, ca.rel, ca.flat, ca.g, ca.closed,
        cb.tri, cb.lam, cb.rel, cb.flat, cb.g, cb.closed,
        ok, bool(symmetric), bool(replace_any), dif == "hyperbolic",
        -1.0 if occlusion is None else float(occlusion), float(segment_weight), S, H,
    )  # fmt: skip
    return S, (H if replace_any else None), ok


def _offsets(n: int, n_trees: int) -> list[int]:
    return sorted({(t * n) // (2 * n_trees) for t in range(n_trees)})


def pair_top(
    S: np.ndarray, ca: PairCurve, cb: PairCurve, *, symmetric: bool, n_trees: int = 1
) -> tuple[float, tuple]:
    """ψ from the filled table ``S`` and the top that gave it.

    Returns
    -------
    cost : float
        ``inf`` when nothing is admissible.
    top : tuple
        ``("open",)``, or ``(side, offset_index, cut, sa, la, sb, lb)`` with ``side`` 0
        (A cut at its offset, B anywhere) or 1 (B cut, A anywhere): the two halves are
        ``(la, lb, sa, sb)`` and their complements.
    """
    na, nb = ca.n_points, cb.n_points
    if not ca.closed:
        c = float(S[na - 1, nb - 1, 0, 0])
        return (np.inf if c >= 0.5 * SENTINEL else c), ("open",)
    best, top = np.inf, None
    ka = na // 2
    for t, o in enumerate(_offsets(na, n_trees)):
        o2 = (o + ka) % na
        for lb in range(1, nb):
            first = S[ka, lb, o, :]
            second = S[na - ka, nb - lb, o2, (np.arange(nb) + lb) % nb]
            tot = first + second
            j = int(np.argmin(tot))
            if tot[j] < best:
                best, top = float(tot[j]), (0, t, o, o, ka, j, lb)
    if symmetric:
        kb = nb // 2
        for t, o in enumerate(_offsets(nb, n_trees)):
            o2 = (o + kb) % nb
            for la in range(1, na):
                first = S[la, kb, :, o]
                second = S[na - la, nb - kb, (np.arange(na) + la) % na, o2]
                tot = first + second
                j = int(np.argmin(tot))
                if tot[j] < best:
                    best, top = float(tot[j]), (1, t, o, j, la, o, kb)
    if best >= 0.5 * SENTINEL:
        return np.inf, top or (0, 0, 0, 0, ka, 0, 1)
    return best, top


def pair_traceback(
    S: np.ndarray,
    H: np.ndarray | None,
    ok: np.ndarray,
    ca: PairCurve,
    cb: PairCurve,
    top: tuple,
    *,
    symmetric: bool,
    dif: str,
    occlusion: float | None,
    segment_weight: float = 1.0,
) -> tuple[np.ndarray, np.ndarray, list[tuple[int, int, int, int]]]:
    """The correspondence of an optimal pair matching, re-deriving each choice.

    Returns
    -------
    a_to_b : ndarray, shape (N_A,)
        Fractional position along B of every point of A (NaN inside replaced parts).
    b_to_a : ndarray, shape (N_B,)
    replaced : list of (a_start, a_end, b_start, b_end)
        Replaced pieces, indices modulo the curves' sizes when closed.
    """
    na, nb = ca.n_points, cb.n_points
    hyper = dif == "hyperbolic"
    occl = occlusion is not None
    pos_a = np.full(na, np.nan)
    pos_b = np.full(nb, np.nan)
    replaced: list[tuple[int, int, int, int]] = []

    def rep(la: int, lb: int, sa: int, sb: int) -> float:
        if not occl:
            return np.inf
        lam = 0.5 * (ca.lam[la, sa] + cb.lam[lb, sb]) if symmetric else ca.lam[la, sa]
        return occlusion * lam * (ca.rel[la, sa] + cb.rel[lb, sb])

    def put(ia: int, jb: float, ib: int | None = None, fa: float | None = None) -> None:
        pos_a[ia % na] = jb % nb
        if ib is not None:
            pos_b[ib % nb] = (fa if fa is not None else ia) % na

    def replace(la: int, lb: int, sa: int, sb: int) -> None:
        replaced.append((sa % na, (sa + la) % na, sb % nb, (sb + lb) % nb))
        for i in range(1, la):
            pos_a[(sa + i) % na] = np.nan
        for k in range(1, lb):
            pos_b[(sb + k) % nb] = np.nan

    def cut(la: int, lb: int, xa: int, xb: int, i: int, k: int) -> float:
        lam = 0.5 * (ca.lam[la, xa] + cb.lam[lb, xb]) if symmetric else ca.lam[la, xa]
        return lam * exact_dif_kind(*ca.tri[la, i, :, xa], *cb.tri[lb, k, :, xb], hyper)

    def close(x: float, y: float) -> bool:
        return abs(x - y) <= 1e-12 * max(1.0, abs(y))

    def visit_h(la: int, lb: int, sa: int, sb: int) -> None:
        target = H[la, lb, sa % na, sb % nb]
        if close(rep(la, lb, sa % na, sb % nb), target):
            replace(la, lb, sa, sb)
            return
        for i in range(1, la):
            for k in range(1, lb):
                if not (ok[i, k] and ok[la - i, lb - k]):
                    continue
                v = rep(i, k, sa % na, sb % nb) + S[la - i, lb - k, (sa + i) % na, (sb + k) % nb]
                v = v + cut(la, lb, sa % na, sb % nb, i, k)
                if close(v, target):
                    replace(i, k, sa, sb)
                    put(sa + i, sb + k, sb + k)
                    visit(la - i, lb - k, sa + i, sb + k)
                    return
        raise AssertionError("traceback found no choice (H)")  # pragma: no cover

    def visit(la: int, lb: int, sa: int, sb: int) -> None:
        xa, xb = sa % na, sb % nb
        target = S[la, lb, xa, xb]
        if la == 1 and lb == 1:
            return
        if la == 1 or lb == 1:
            base = (
                (cb.flat[lb, xb] if symmetric else segment_weight * ca.lam[1, xa] * cb.g[lb, xb])
                if la == 1
                else ca.flat[la, xa]
            )
            if close(base, target) or not close(rep(la, lb, xa, xb), target):
                if la == 1:
                    for k in range(1, lb):
                        pos_b[(sb + k) % nb] = (sa + k / lb) % na
                else:
                    for i in range(1, la):
                        pos_a[(sa + i) % na] = (sb + i / la) % nb
                return
            replace(la, lb, sa, sb)
            return
        ka, kb = la // 2, lb // 2
        for k in range(1, lb):
            if not (ok[ka, k] and ok[la - ka, lb - k]):
                continue
            d = exact_dif_kind(*ca.tri[la, ka, :, xa], *cb.tri[lb, k, :, xb], hyper)
            v = S[ka, k, xa, xb] + S[la - ka, lb - k, (xa + ka) % na, (xb + k) % nb]
            v += ca.lam[la, xa] * d
            if close(v, target):
                put(sa + ka, sb + k, sb + k)
                visit(ka, k, sa, sb)
                visit(la - ka, lb - k, sa + ka, sb + k)
                return
        if symmetric:
            for i in range(1, la):
                if not (ok[i, kb] and ok[la - i, lb - kb]):
                    continue
                d = exact_dif_kind(*ca.tri[la, i, :, xa], *cb.tri[lb, kb, :, xb], hyper)
                v = S[i, kb, xa, xb] + S[la - i, lb - kb, (xa + i) % na, (xb + kb) % nb]
                v += cb.lam[lb, xb] * d
                if close(v, target):
                    put(sa + i, sb + kb, sb + kb)
                    visit(i, kb, sa, sb)
                    visit(la - i, lb - kb, sa + i, sb + kb)
                    return
        if close(rep(la, lb, xa, xb), target):
            replace(la, lb, sa, sb)
            return
        if H is not None:
            if close(H[la, lb, xa, xb], target):
                visit_h(la, lb, sa, sb)
                return
            for i in range(1, la):
                for k in range(1, lb):
                    if not (ok[i, k] and ok[la - i, lb - k]):
                        continue
                    v = S[i, k, xa, xb] + H[la - i, lb - k, (xa + i) % na, (xb + k) % nb]
                    v = v + cut(la, lb, xa, xb, i, k)
                    if close(v, target):
                        put(sa + i, sb + k, sb + k)
                        visit(i, k, sa, sb)
                        visit_h(la - i, lb - k, sa + i, sb + k)
                        return
        raise AssertionError("traceback found no choice (S)")  # pragma: no cover

    if top[0] == "open":
        put(0, 0, 0)
        put(na - 1, nb - 1, nb - 1)
        visit(na - 1, nb - 1, 0, 0)
    else:
        _side, _t, _o, sa, la, sb, lb = top
        put(sa, sb, sb)
        put(sa + la, sb + lb, sb + lb)
        visit(la, lb, sa, sb)
        visit(na - la, nb - lb, sa + la, sb + lb)
    return pos_a, pos_b, sorted(replaced)
