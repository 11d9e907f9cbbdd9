"""The second dynamic programme of §4: stitching contour matches into object matches.

Notation (paper §4).  The model is a closed curve sampled at ``m`` points
``M[0..m-1]`` (indices cyclic).  A model interval ``(a, L)`` is the subcurve
from ``a`` forward ``L`` segments; ``frac(a, L)`` is its share of the model's
arclength.  Image contours are used in both directions; a *piece* ``d`` is one
contour in one direction, going from endpoint ``p_d`` to endpoint ``q_d``.
``Match(a, b, p, q)`` is a matching of the model interval ``a -> b`` to some
contours with ``a -> p``, ``b -> q``.

All costs are in units of "fraction of the model" so that they are comparable
across images and scales:

* **piece**: ``Match(a, a+L, p_d, q_d)`` from one contour costs
  ``frac(a, L) * T_d[a, L] + piece_cost`` where ``T_d`` is the contour-vs-model
  table of §3 (λ of the contour's root = 1);
* **composition** (paper's rule): ``Match(a, b, p, q) + Match(b, c, r, s)``
  with ``|q - r| <= tau`` costs the sum plus
  ``lam * frac(a, c) * dif((M_a, M_b, M_c), (p, (q + r) / 2, s))``, with ``dif``
  the squared full Procrustes distance ``1 - |<z, w>|^2`` of the centred,
  unit-size complex triangles, computed by the project's one compiled ``dif``
  (:mod:`shapetree.geometry._dif`; 1 for a triangle of zero size);
* **gap**: a gap match leaves model interval ``b -> b'`` unmatched at cost
  ``gap_cost * sum of gap weights of its segments`` (the weights are the
  segments' arclength shares; 0 on an open model's artificial closing chord).
  A gap joins the end ``q`` of a left match to the start ``r`` of a right
  match whatever their distance, i.e. ``Match(a, b, p, q) + Gap(b, b', q, r) +
  Match(b', c, r, s)``, with the two triangle terms of the paper's binary rule
  for the better of the two bracketings;
* **complete match**: an interval match of length ``m`` (the whole loop) whose
  ends are within ``tau`` (the paper's ``Match(a,b,p,q) + Match(b,a,q',p')``;
  that last composition has no triangle, the model triangle being degenerate),
  or an interval match of length ``L < m`` closed by one gap over the rest.

Pruning (the exact DP is ``O(m^3 k^3)``):

* the model is sampled coarsely for stitching (``m`` points, default 30);
* per model interval only the ``beam`` cheapest matches are kept, and among
  them at most ``per_end`` with the same image start endpoint and at most
  ``per_end`` with the same image end endpoint;
* direct compositions only between endpoints within ``tau``;
* gaps at most ``max_gap`` model segments long inside an interval, and a
  composition across a gap only combines the ``gap_beam`` cheapest matches
  on each side;
* a contour may be used only once per match (a 128-bit hash of contour ids
  per match; rare hash collisions forbid a valid combination).

Exact shortcuts (the kept matches are those of listing every candidate with all its
terms, the literal oracle :func:`._stitch_reference.reference_stitch`): beams are sorted,
so a loop over a beam stops at the first candidate whose cost before triangle terms
already reaches the full heap's worst; across a gap, the triangle terms are computed
one at a time and a bracketing stops being evaluated once one of its terms alone
reaches that worst cost.
"""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

from shapetree.geometry._dif import helmert_dif, helmert_dif_kind, unit_helmert

INF = 1e30


@nb.njit(cache=True)
def _shape(z1: complex, z2: complex, z3: complex) -> tuple[float, float, float]:
    """Unit Helmert coordinates of the triangle ``(z1, z2, z3)`` (zero for a point)."""
    return unit_helmert(z1.real, z1.imag, z2.real, z2.imag, z3.real, z3.imag)


@nb.njit(cache=True)
def _dif(z1: complex, z2: complex, z3: complex, w1: complex, w2: complex, w3: complex) -> float:
    """Squared full Procrustes distance between triangles (z1,z2,z3) and (w1,w2,w3)."""
    a1, a2r, a2i = _shape(z1, z2, z3)
    b1, b2r, b2i = _shape(w1, w2, w3)
    return helmert_dif(a1, a2r, a2i, b1, b2r, b2i)


@nb.njit(cache=True)
def _difn(
    a: tuple[float, float, float], w1: complex, w2: complex, w3: complex, hyper: bool = False
) -> float:
    """``_dif`` with the first triangle already given by its shape ``a = _shape(...)``
    (``hyper``: the pseudo-hyperbolic ``dif`` of :mod:`shapetree.geometry._dif`)."""
    b1, b2r, b2i = _shape(w1, w2, w3)
    return helmert_dif_kind(a[0], a[1], a[2], b1, b2r, b2i, hyper)


@nb.njit(cache=True)
def _bracketing(c, wc, t_whole, fr, sh, z1, z2, z3, hyper):
    """One bracketing of a composition across a gap: ``fr dif(sh, (z1, z2, z3)) +
    t_whole`` (its own triangle term plus the whole interval's, given), or ``INF`` as soon
    as either term brings ``c`` to ``wc`` (then it cannot be kept)."""
    if c + t_whole >= wc:
        return INF
    t = fr * _difn(sh, z1, z2, z3, hyper) + t_whole
    return INF if c + t >= wc else t


@nb.njit(cache=True)
def _insert(buf_cost, buf_info, n_used, worst, cost, info):
    """Insert a candidate into a bounded max-heap that keeps the cheapest entries.

    ``buf_cost[0]`` is the most expensive kept candidate once the heap is full;
    ``worst`` is always 0 and kept for the call signature.
    """
    cap = buf_cost.shape[0]
    if n_used < cap:
        # sift up
        i = n_used
        n_used += 1
        while i > 0:
            par = (i - 1) // 2
            if buf_cost[par] >= cost:
                break
            buf_cost[i] = buf_cost[par]
            buf_info[i, :] = buf_info[par, :]
            i = par
        buf_cost[i] = cost
        buf_info[i, :] = info
        return n_used, 0
    if cost >= buf_cost[0]:
        return n_used, 0
    # replace the root and sift down
    i = 0
    while True:
        lc = 2 * i + 1
        if lc >= cap:
            break
        big = lc
        if lc + 1 < cap and buf_cost[lc + 1] > buf_cost[lc]:
            big = lc + 1
        if buf_cost[big] <= cost:
            break
        buf_cost[i] = buf_cost[big]
        buf_info[i, :] = buf_info[big, :]
        i = big
    buf_cost[i] = cost
    buf_info[i, :] = info
    return n_used, 0


@nb.njit(cache=True)
def _stitch_kernel(
    M,  # (m,) complex model samples
    frac,  # (m, m+1) arclength share of interval (a, L)
    gapc,  # (m, m+1) cost of a gap over interval (a, L)
    base,  # (nd, m, m) piece costs (INF where not allowed)
    piece_p,  # (nd,) start endpoint id
    piece_q,  # (nd,) end endpoint id
    piece_mask,  # (nd, 2) uint64 contour hash bits
    piece_box,  # (nd, 4) x1 y1 x2 y2
    E,  # (k,) complex endpoints
    near,  # (k, k) bool
    lam,
    beam,
    per_end,
    max_gap,
    gap_beam,
    hyper=False,  # pseudo-hyperbolic dif (geometry._dif) instead of Procrustes
):
    m = M.shape[0]
    nd = base.shape[0]
    k = E.shape[0]
    cap = m * (m + 1) * beam + 1
    # entry arrays
    e_cost = np.empty(cap)
    e_a = np.empty(cap, np.int64)
    e_L = np.empty(cap, np.int64)
    e_p = np.empty(cap, np.int64)
    e_q = np.empty(cap, np.int64)
    e_kind = np.empty(cap, np.int64)  # 0 piece, 1 direct, 2 gap
    e_left = np.empty(cap, np.int64)  # piece id for kind 0
    e_right = np.empty(cap, np.int64)
    e_gap = np.empty(cap, np.int64)  # gap length (kind 2): gap starts at end of left
    e_mask = np.empty((cap, 2), np.uint64)
    e_box = np.empty((cap, 4))
    n_e = 0
    beams = -np.ones((m, m + 1, beam), np.int64)
    nbeam = np.zeros((m, m + 1), np.int64)
    # the kept matches' cost and endpoints beside their ids, in beam order, so that the
    # composition loops read contiguous memory
    bcost = np.empty((m, m + 1, beam))
    bp = np.empty((m, m + 1, beam), np.int64)
    bq = np.empty((m, m + 1, beam), np.int64)

    bufcap = 4 * beam
    buf_cost = np.empty(bufcap)
    # info: kind, left, right, gap, p, q
    buf_info = np.empty((bufcap, 6), np.int64)
    info = np.empty(6, np.int64)
    cnt_p = np.zeros(k, np.int64)
    cnt_q = np.zeros(k, np.int64)

    for L in range(1, m + 1):
        for a in range(m):
            n_used = 0
            worst = 0
            c_end = (a + L) % m
            # single pieces
            if L < m:
                for d in range(nd):
                    c = base[d, a, L]
                    if c < INF:
                        info[0] = 0
                        info[1] = d
                        info[2] = -1
                        info[3] = 0
                        info[4] = piece_p[d]
                        info[5] = piece_q[d]
                        n_used, worst = _insert(buf_cost, buf_info, n_used, worst, c, info)
            lamf = lam * frac[a, L]
            # direct compositions
            for l in range(1, L):
                b = (a + l) % m
                wsh = _shape(M[a], M[b], M[c_end])
                nl = nbeam[a, l]
                nr = nbeam[b, L - l]
                if nl == 0 or nr == 0:
                    continue
                rcost = bcost[b, L - l]
                rp = bp[b, L - l]
                cr0 = rcost[0]
                for ii in range(nl):
                    ci = bcost[a, l, ii]
                    if n_used == bufcap and ci + cr0 >= buf_cost[worst]:
                        break  # beams are sorted by cost
                    i = beams[a, l, ii]
                    qi = bq[a, l, ii]
                    near_q = near[qi]
                    for jj in range(nr):
                        c = ci + rcost[jj]
                        if n_used == bufcap and c >= buf_cost[worst]:
                            break
                        pj = rp[jj]
                        if not near_q[pj]:
                            continue
                        j = beams[b, L - l, jj]
                        if (e_mask[i, 0] & e_mask[j, 0]) != 0 or (e_mask[i, 1] & e_mask[j, 1]) != 0:
                            continue
                        if L < m:
                            mid = 0.5 * (E[qi] + E[pj])
                            c += lamf * _difn(wsh, E[e_p[i]], mid, E[e_q[j]], hyper)
                        elif not near[e_q[j], e_p[i]]:
                            continue
                        info[0] = 1
                        info[1] = i
                        info[2] = j
                        info[3] = 0
                        info[4] = e_p[i]
                        info[5] = e_q[j]
                        n_used, worst = _insert(buf_cost, buf_info, n_used, worst, c, info)
            # gap compositions: left (a, l1) + gap (b, g) + right (b2, L - l1 - g)
            for l1 in range(1, L - 1):
                b = (a + l1) % m
                for g in range(1, min(max_gap, L - 1 - l1) + 1):
                    b2 = (a + l1 + g) % m
                    lr = L - l1 - g
                    gcost = gapc[b, g]
                    nl = min(nbeam[a, l1], gap_beam)
                    nr = min(nbeam[b2, lr], gap_beam)
                    fr1 = lam * frac[a, l1 + g]
                    fr2 = lam * frac[b, L - l1]
                    ush = _shape(M[a], M[b], M[b2])
                    vsh = _shape(M[a], M[b2], M[c_end])
                    xsh = _shape(M[b], M[b2], M[c_end])
                    ysh = _shape(M[a], M[b], M[c_end])
                    if nl == 0 or nr == 0:
                        continue
                    rcost = bcost[b2, lr]
                    rp = bp[b2, lr]
                    rq = bq[b2, lr]
                    cr0 = rcost[0]
                    for ii in range(nl):
                        ci = bcost[a, l1, ii] + gcost
                        if n_used == bufcap and ci + cr0 >= buf_cost[worst]:
                            break  # beams are sorted by cost
                        i = beams[a, l1, ii]
                        mi0 = e_mask[i, 0]
                        mi1 = e_mask[i, 1]
                        pi = E[bp[a, l1, ii]]
                        qi = E[bq[a, l1, ii]]
                        for jj in range(nr):
                            c = ci + rcost[jj]
                            if n_used == bufcap and c >= buf_cost[worst]:
                                break
                            j = beams[b2, lr, jj]
                            if (mi0 & e_mask[j, 0]) != 0 or (mi1 & e_mask[j, 1]) != 0:
                                continue
                            rj = E[rp[jj]]
                            sj = E[rq[jj]]
                            if L < m:
                                # Each bracketing costs the sum of two non-negative
                                # triangle terms.  Once the heap is full, a bracketing one
                                # of whose terms alone brings c to the heap's worst cost is
                                # out (floating addition is monotone): the other bracketing
                                # decides, and with both out _insert would refuse the
                                # candidate, so it is skipped.  The same candidates reach
                                # _insert with the same costs as with all four terms.
                                wc = buf_cost[worst] if n_used == bufcap else INF
                                tv = lamf * _difn(vsh, pi, rj, sj, hyper)
                                t1 = _bracketing(c, wc, tv, fr1, ush, pi, qi, rj, hyper)
                                ty = lamf * _difn(ysh, pi, qi, sj, hyper)
                                t2 = _bracketing(c, wc, ty, fr2, xsh, qi, rj, sj, hyper)
                                if t1 == INF and t2 == INF:
                                    continue
                            else:
                                if not near[e_q[j], e_p[i]]:
                                    continue
                                t1 = fr1 * _difn(ush, pi, qi, rj, hyper)
                                t2 = fr2 * _difn(xsh, qi, rj, sj, hyper)
                            c += t1 if t1 < t2 else t2
                            info[0] = 2
                            info[1] = i
                            info[2] = j
                            info[3] = g
                            info[4] = e_p[i]
                            info[5] = e_q[j]
                            n_used, worst = _insert(buf_cost, buf_info, n_used, worst, c, info)
            # select with per-endpoint diversity
            order = np.argsort(buf_cost[:n_used])
            kept = 0
            for t in order:
                p = buf_info[t, 4]
                q = buf_info[t, 5]
                if cnt_p[p] >= per_end or cnt_q[q] >= per_end:
                    continue
                cnt_p[p] += 1
                cnt_q[q] += 1
                kind = buf_info[t, 0]
                e = n_e
                n_e += 1
                e_cost[e] = buf_cost[t]
                e_a[e] = a
                e_L[e] = L
                e_p[e] = p
                e_q[e] = q
                e_kind[e] = kind
                e_left[e] = buf_info[t, 1]
                e_right[e] = buf_info[t, 2]
                e_gap[e] = buf_info[t, 3]
                if kind == 0:
                    d = buf_info[t, 1]
                    e_mask[e, 0] = piece_mask[d, 0]
                    e_mask[e, 1] = piece_mask[d, 1]
                    for u in range(4):
                        e_box[e, u] = piece_box[d, u]
                else:
                    i = buf_info[t, 1]
                    j = buf_info[t, 2]
                    e_mask[e, 0] = e_mask[i, 0] | e_mask[j, 0]
                    e_mask[e, 1] = e_mask[i, 1] | e_mask[j, 1]
                    e_box[e, 0] = min(e_box[i, 0], e_box[j, 0])
                    e_box[e, 1] = min(e_box[i, 1], e_box[j, 1])
                    e_box[e, 2] = max(e_box[i, 2], e_box[j, 2])
                    e_box[e, 3] = max(e_box[i, 3], e_box[j, 3])
                beams[a, L, kept] = e
                bcost[a, L, kept] = buf_cost[t]
                bp[a, L, kept] = p
                bq[a, L, kept] = q
                kept += 1
                if kept == beam:
                    break
            nbeam[a, L] = kept
            for t in order:
                cnt_p[buf_info[t, 4]] = 0
                cnt_q[buf_info[t, 5]] = 0
    return (
        n_e,
        e_cost[:n_e].copy(),
        e_a[:n_e].copy(),
        e_L[:n_e].copy(),
        e_p[:n_e].copy(),
        e_q[:n_e].copy(),
        e_kind[:n_e].copy(),
        e_left[:n_e].copy(),
        e_right[:n_e].copy(),
        e_gap[:n_e].copy(),
        e_box[:n_e].copy(),
    )


class StitchResult:
    """All interval matches kept by the stitching DP (flat arrays, one row per match).

    Attributes
    ----------
    cost, a, L, p, q, kind, left, right, gap : ndarray, shape (n_entries,)
        Cost; model start index and length; image start/end endpoint ids;
        kind (0 single piece, 1 direct composition, 2 composition across a
        gap); children (``left`` is the piece id for kind 0); gap length.
    box : ndarray, shape (n_entries, 4)
        Union of the used contours' bounding boxes ``x1, y1, x2, y2`` (px).
    m : int
        Number of model samples used for stitching.
    """

    def __init__(self, m: int, arrays: tuple) -> None:
        (
            _n,
            self.cost,
            self.a,
            self.L,
            self.p,
            self.q,
            self.kind,
            self.left,
            self.right,
            self.gap,
            self.box,
        ) = arrays
        self.m = m

    def pieces(self, e: int) -> list[tuple[int, int, int]]:
        """Pieces of match ``e`` in model order.

        Returns
        -------
        list of (piece_id, a, L)
            Piece id, model start index, number of model segments.
        """
        out: list[tuple[int, int, int]] = []
        stack = [e]
        while stack:
            x = stack.pop()
            if self.kind[x] == 0:
                out.append((int(self.left[x]), int(self.a[x]), int(self.L[x])))
            else:
                stack.append(int(self.right[x]))
                stack.append(int(self.left[x]))
        return out


def run_stitch(
    model: NDArray[np.float64],
    gap_weight: NDArray[np.float64],
    base: NDArray[np.float64],
    piece_p: NDArray[np.int64],
    piece_q: NDArray[np.int64],
    piece_contour: NDArray[np.int64],
    piece_box: NDArray[np.float64],
    endpoints: NDArray[np.float64],
    *,
    tau: float,
    lam: float,
    gap_cost: float,
    beam: int,
    per_end: int,
    max_gap: int,
    gap_beam: int = 8,
    dif: str = "procrustes",
) -> StitchResult:
    """Run the stitching DP.

    Parameters
    ----------
    model : ndarray, shape (m, 2)
        Closed model samples used for stitching.
    gap_weight : ndarray, shape (m,)
        Per-segment gap weight (segment ``i`` joins ``i`` and ``i+1``); sums
        to at most 1.
    base : ndarray, shape (nd, m, m)
        Cost of piece ``d`` matched to model interval ``(a, L)``; ``inf``
        where not allowed (column 0 must be ``inf``).
    piece_p, piece_q : ndarray, shape (nd,)
        Start and end endpoint id of each piece.
    piece_contour : ndarray, shape (nd,)
        Contour id of each piece (a contour is used at most once per match).
    piece_box : ndarray, shape (nd, 4)
        Bounding box of each piece's contour, ``x1, y1, x2, y2`` in px.
    endpoints : ndarray, shape (k, 2)
        Image endpoints ``(x, y)`` in px.
    tau : float
        Max distance in px between endpoints that may be joined directly.
    lam, gap_cost : float
        Weight of the triangle term and of a gap over the whole model.
    beam, per_end, max_gap, gap_beam : int
        Pruning limits (see module docstring).
    dif : {"procrustes", "hyperbolic"}
        The triangle ``dif`` of the stitching terms (``MatchConfig.dif``; the detector's
        default is the Procrustes ``dif``).

    Returns
    -------
    StitchResult
    """
    m = len(model)
    mz = model[:, 0] + 1j * model[:, 1]
    seg = np.abs(np.roll(mz, -1) - mz)
    total = seg.sum()
    cum = np.concatenate([[0.0], np.cumsum(np.concatenate([seg, seg]))])
    gcum = np.concatenate([[0.0], np.cumsum(np.concatenate([gap_weight, gap_weight]))])
    idx = np.arange(m)[:, None] + np.arange(m + 1)[None, :]
    frac = (cum[idx] - cum[np.arange(m)][:, None]) / total
    gapc = gap_cost * (gcum[idx] - gcum[np.arange(m)][:, None])
    ez = endpoints[:, 0] + 1j * endpoints[:, 1]
    near = np.abs(ez[:, None] - ez[None, :]) <= tau
    bits = (piece_contour.astype(np.uint64) * np.uint64(2654435761)) % np.uint64(128)
    mask = np.zeros((len(piece_contour), 2), np.uint64)
    lo = bits < 64
    mask[lo, 0] = np.left_shift(np.uint64(1), bits[lo])
    mask[~lo, 1] = np.left_shift(np.uint64(1), bits[~lo] - np.uint64(64))
    base_c = np.ascontiguousarray(np.where(np.isfinite(base), base, INF))
    arrays = _stitch_kernel(
        mz,
        frac,
        gapc,
        base_c,
        piece_p.astype(np.int64),
        piece_q.astype(np.int64),
        mask,
        piece_box.astype(np.float64),
        ez,
        near,
        float(lam),
        int(beam),
        int(per_end),
        int(max_gap),
        int(gap_beam),
        dif == "hyperbolic",
    )
    res = StitchResult(m, arrays)
    res.gapc = gapc  # type: ignore[attr-defined]
    res.frac = frac  # type: ignore[attr-defined]
    res.near = near  # type: ignore[attr-defined]
    return res


def complete_matches(res: StitchResult) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Complete (closed) matches from the kept interval matches.

    Returns
    -------
    entries : ndarray, shape (c,), int64
        Entry ids of complete matches (length-``m`` entries whose two ends are
        within ``tau``, or shorter entries closed with one gap).
    costs : ndarray, shape (c,), float64
        Total cost (entry cost + closing gap), sorted ascending.
    """
    m = res.m
    full = res.L == m
    ok_full = full & res.near[res.p, res.q]
    part = ~full
    close = res.gapc[(res.a + res.L) % m, m - res.L]
    cost = np.where(ok_full, res.cost, np.where(part, res.cost + close, np.inf))
    ids = np.flatnonzero(np.isfinite(cost))
    order = np.argsort(cost[ids], kind="stable")
    return ids[order], cost[ids][order]
