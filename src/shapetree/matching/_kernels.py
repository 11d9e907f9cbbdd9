"""Compiled dynamic-programming kernels of eq. (1) (numba ``nopython``, cached on disk).

Layout
------
A target subcurve is named by its *length* ``L`` (number of target segments,
``1 <= L <= m - 1``) and its *start* ``s``; it ends at ``s + L`` (mod ``m`` when the
target is closed, i.e. its subcurves wrap around). Every table of costs is stored once,
by start, and *doubled*: ``T[t, L, x]`` for ``x`` in ``[0, 2m)`` holds the cost of table
``t`` against the subcurve that starts at ``x mod m``. The right child of ``(s, L)`` split
at ``k`` starts at ``s + k``, so it is read as the contiguous row ``T[right, L - k, k:]``
without any modulo.

Each table ``t`` (a node of the shape-tree, or one of the model's segments) may only use
target lengths in its band ``[lmin[t], lmax[t]]`` (the pruned mode; ``1`` and ``m - 1``
for exact matching). Entries outside a table's band are **never written**: every reader
(the kernel itself, :func:`closed_root_min`, the traceback) restricts itself to the band.

The loops run ``L chunk -> node -> L -> k -> s`` with ``s`` innermost: the minimum over
the split ``k`` becomes an element-wise minimum over ``s`` that LLVM vectorises
(:func:`node_row`, :func:`fill_tables` for the order and why it gives the same numbers).

``dif``
-------
``dif`` is the squared full Procrustes distance between the model triangle
``(a_start, a_mid, a_end)`` and the target triangle ``(b_s, b_{s+k}, b_{s+L})``, computed
by the project's one compiled implementation (:mod:`shapetree.geometry._dif`). Each
triangle is kept as its unit-size Helmert coordinates ``z = (z1, z2)``
(:func:`~shapetree.geometry._dif.unit_helmert`), rotated so that ``z1`` is real and
``>= 0``. By Lagrange's identity for unit vectors of ``C^2``,

    dif = 1 - |<z_a, z_b>|^2 = |a1 z2 - a2 z1|^2,

a sum of two squares with no cancellation, so the tables keep their relative precision
in float32 too. The model's coordinates are scaled by ``sqrt(λ)`` once per node, so the
inner loop adds :func:`~shapetree.geometry._dif.lagrange_form` of the scaled model
coordinates and the target's: four multiply-adds and two squares per entry.

A target triangle of zero size (its three points coincide) has no shape: its ``dif`` is
:data:`~shapetree.geometry.DEGENERATE_DIF` (1) against every model triangle, as in the
oracle. :func:`target_tables` stores it as ``z = (0, 0, 0)`` and flags its ``(L, k)``
plane in ``deg``; the kernel scores flagged planes with
:func:`~shapetree.geometry._dif.weighted_dif` (``λ`` for a zero-size triangle), the others
with the branch-free linear form. A target without such triangles (nearly all) passes
``deg=None``, and numba compiles a specialisation without that branch.

Hyperbolic ``dif``
-----------------
With ``hyper`` true the kernels use the pseudo-hyperbolic ``dif``
(:mod:`shapetree.geometry._dif`): ``λ dif = λ num / den`` with ``num`` the Lagrange form
above and ``den`` the same form against the mirrored target triangle (``z2`` conjugated)
plus the regularisation (:func:`~shapetree.geometry._dif.hyperbolic_den`), clipped by
:func:`~shapetree.geometry._dif.hyperbolic_ratio`; the base cases read the
target's hyperbolic table ``g`` and the model's hyperbolic ``flat`` constants. The target
triangles ``tri`` are the same for both.

Sentinel and fast-math
----------------------
The kernels are compiled with :data:`~shapetree.geometry._dif.FASTMATH` (fast-math without
``nnan`` / ``ninf``) and never store ``inf``: an entry with no admissible split (possible
only in the pruned mode, when the children's bands cannot add up to ``L``) holds
:data:`SENTINEL` (``1e30``, representable in float32; sums of two sentinels stay finite).
Every reader at the Python boundary maps values ``>= SENTINEL / 2`` to ``inf``
(:func:`finite_or_inf`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shapetree.geometry._dif import (
    FASTMATH,
    helmert_dif,
    helmert_dif_kind,
    hyperbolic_den,
    hyperbolic_ratio,
    is_zero_shape,
    lagrange_form,
    unit_helmert,
    weighted_dif_kind,
)

#: Placeholder cost of a table entry that nothing can reach (no admissible split inside a
#: band; "not yet improved" in a minimum). Finite, so that the kernels may be compiled
#: without ``nnan`` / ``ninf``; float32-safe (max 3.4e38), and a sum of a few stays finite.
SENTINEL = 1e30

_jit = njit(cache=True, nogil=True, fastmath=set(FASTMATH))


def finite_or_inf(x: float | np.ndarray) -> float | np.ndarray:
    """``x`` with entries ``>= SENTINEL / 2`` (unreachable) replaced by ``inf``.

    Scalars give a Python float, arrays a new array of the same dtype.
    """
    if np.ndim(x) == 0:
        v = float(x)
        return np.inf if v >= 0.5 * SENTINEL else v
    return np.where(np.asarray(x) >= 0.5 * SENTINEL, np.inf, x).astype(np.asarray(x).dtype)


@_jit
def degenerate_split(best, lrow, rrow, lam_v, q1, qr, qi, z1, zr, zi, ns, hyper):
    """One split ``k`` of a node on a plane with a zero-size target triangle (its ``dif``
    is :data:`~shapetree.geometry.DEGENERATE_DIF`); computed in float64, apart from the
    fast loops, which must stay in the tables' precision."""
    for s in range(ns):
        cd = lrow[s] + rrow[s] + weighted_dif_kind(lam_v, q1, qr, qi, z1[s], zr[s], zi[s], hyper)
        if cd < best[s]:
            best[s] = cd


#: Target lengths are processed in chunks whose triangle planes ``tri[L]`` take about this
#: many bytes together (:func:`length_chunk`), so that every node reads them from cache.
CHUNK_BYTES = 1 << 19


@_jit
def length_chunk(m: int, itemsize: int) -> int:
    """Number of target lengths per chunk of :func:`fill_tables` (at least 1)."""
    return max(1, CHUNK_BYTES // (3 * m * m * itemsize))


@_jit
def replace_row(best, lv, la, brow, ns, occlusion):
    """Bound a row by the replacement cost ``κ λ (|A'| + |B'|)`` (occlusion)."""
    for s in range(ns):
        best[s] = np.minimum(best[s], occlusion * lv * (la + brow[s]))


@_jit
def node_row(
    tab, v, length, ns, left_tab, right_tab, ra1, ra2r, ra2i, flat, lam, tri, deg, lmin, lmax, hyper
):
    """Row ``length`` of node ``v``'s table, before replacement: ``flat[v]`` at length 1,
    else ``min_k tab[lt, k, s] + tab[rt, length - k, s + k] + λ dif`` over the admissible
    splits ``k`` (:data:`SENTINEL` when there is none), for ``s < ns``.

    Shared by :func:`fill_tables` and the bound's kept nodes
    (:func:`shapetree.matching._bound.fill_bound_tables`).

    Speed (``benchmarks/bench_match.py``): two splits are taken per pass over ``s`` (half
    the loads and stores of the running minimum), their rows indexed directly, and the
    minimum is ``np.minimum``, which LLVM turns into a blend and a plain store; the
    equivalent ``c if c < b else b`` became a masked store (``vmaskmovps``), which on the
    AMD EPYC here ran the loop 3.4x slower (a scratch microbenchmark of the loop alone).
    The minimum of the same values in another order is the same number, so the tables are
    bit for bit those of a one-split loop (no NaN can reach them: curves are validated and
    nothing here divides by zero).
    """
    best = tab[v, length]
    if length == 1:
        fl = flat[v]
        for s in range(ns):
            best[s] = fl
        return
    # coefficients read from arrays of the tables' precision, so that a float32 run stays
    # in float32 in the inner loop
    q1 = ra1[v]
    qr = ra2r[v]
    qi = ra2i[v]
    lt = left_tab[v]
    rt = right_tab[v]
    for s in range(ns):
        best[s] = SENTINEL
    # splits k whose halves both fall inside their children's bands
    k0 = max(1, lmin[lt], length - lmax[rt])
    k1 = min(length - 1, lmax[lt], length - lmin[rt])
    # the dif is chosen outside the split loop: a branch on `hyper` inside it stops LLVM
    # from vectorising the Procrustes loop (2.8x slower, measured)
    if hyper:
        lvh = lam[v]
        for k in range(k0, k1 + 1):
            lrow = tab[lt, k]
            rrow = tab[rt, length - k, k : k + ns]
            z1 = tri[length, k, 0]
            zr = tri[length, k, 1]
            zi = tri[length, k, 2]
            if deg is not None:
                if deg[length, k]:
                    degenerate_split(best, lrow, rrow, lvh, q1, qr, qi, z1, zr, zi, ns, True)
                    continue
            for s in range(ns):
                num = lagrange_form(q1, qr, qi, z1[s], zr[s], zi[s])
                den = hyperbolic_den(q1, qr, qi, z1[s], zr[s], zi[s])
                c = lrow[s] + rrow[s] + lvh * hyperbolic_ratio(num, den)
                best[s] = np.minimum(best[s], c)
    else:
        k = k0
        while k + 1 <= k1:
            if deg is not None:
                if deg[length, k] or deg[length, k + 1]:
                    one_split(best, k, length, ns, v, lt, rt, lam, q1, qr, qi, tri, deg, tab)
                    one_split(best, k + 1, length, ns, v, lt, rt, lam, q1, qr, qi, tri, deg, tab)
                    k += 2
                    continue
            rl = length - k
            for s in range(ns):
                c0 = (
                    tab[lt, k, s]
                    + tab[rt, rl, k + s]
                    + lagrange_form(
                        q1, qr, qi, tri[length, k, 0, s], tri[length, k, 1, s], tri[length, k, 2, s]
                    )
                )
                c1 = (
                    tab[lt, k + 1, s]
                    + tab[rt, rl - 1, k + 1 + s]
                    + lagrange_form(
                        q1,
                        qr,
                        qi,
                        tri[length, k + 1, 0, s],
                        tri[length, k + 1, 1, s],
                        tri[length, k + 1, 2, s],
                    )
                )
                tab[v, length, s] = np.minimum(tab[v, length, s], np.minimum(c0, c1))
            k += 2
        if k <= k1:
            one_split(best, k, length, ns, v, lt, rt, lam, q1, qr, qi, tri, deg, tab)


@_jit
def one_split(best, k, length, ns, v, lt, rt, lam, q1, qr, qi, tri, deg, tab):
    """One split ``k`` of :func:`node_row` (Procrustes ``dif``) into its row ``best``."""
    lrow = tab[lt, k]
    rrow = tab[rt, length - k, k : k + ns]
    z1 = tri[length, k, 0]
    zr = tri[length, k, 1]
    zi = tri[length, k, 2]
    # a plane with a zero-size target triangle (dif = 1 there); numba prunes this branch
    # when deg is None (the specialisation of nearly every target)
    if deg is not None:
        if deg[length, k]:
            degenerate_split(best, lrow, rrow, lam[v], q1, qr, qi, z1, zr, zi, ns, False)
            return
    for s in range(ns):
        c = lrow[s] + rrow[s] + lagrange_form(q1, qr, qi, z1[s], zr[s], zi[s])
        best[s] = np.minimum(best[s], c)


@_jit
def fill_tables(
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
    tri: np.ndarray,
    deg: np.ndarray | None,
    g: np.ndarray,
    blen: np.ndarray,
    cyclic: bool,
    occlusion: float,
    seg_weight: float,
    lmin: np.ndarray,
    lmax: np.ndarray,
    tab: np.ndarray,
    hyper: bool = False,
    chunk: int = 0,
) -> None:
    """Fill the cost tables of every segment and node of one shape-tree, leaves up.

    Parameters
    ----------
    left_tab, right_tab : int64 (K,)
        Table index of each node's children (the model's segments have indices ``K ..``).
    lam, ra1, ra2r, ra2i, flat, alen : float (K,)
        Per node: λ (weight included); ``sqrt(λ)`` times its triangle's Helmert
        coordinates ``a1`` (real), ``a2`` (real and imaginary part; module docstring); its
        cost against a straight target segment (base case); its relative arclength (for
        the replacement cost).
    seg_lam, seg_alen : float64 (S,)
        Per model segment: λ and relative arclength.
    tri : float (m, m, 3, m)
        Target triangles ``[L, k, (z1, z2.real, z2.imag), s]``.
    deg : uint8 (m, m) or None
        ``deg[L, k]``: some target triangle of plane ``(L, k)`` has zero size; ``None``
        when no target triangle has (``Target.deg``).
    g : float64 (m, m)
        ``g[L, s]``: base-case cost per unit λ of a straight segment vs subcurve (s, L).
    blen : float64 (m, m)
        ``blen[L, s]``: relative arclength of the target subcurve (s, L).
    cyclic : bool
        Target subcurves wrap around.
    occlusion : float
        Replacement cost factor κ (``<= 0`` disables replacement).
    seg_weight : float
        Factor on the base case "model segment vs a target subcurve" (paper: 1).
    lmin, lmax : int64 (K + S,)
        Band of target lengths each table may use.
    tab : float64 (K + S, m, 2 m)
        Output, doubled by start (module docstring); only in-band rows are written
        (:data:`SENTINEL` where no admissible split exists and nothing replaces it).
    hyper : bool
        Pseudo-hyperbolic ``dif`` (module docstring); ``g`` and ``flat`` must be the
        hyperbolic ones then.
    chunk : int
        Target lengths per chunk (below); ``0`` (the default) takes
        :func:`length_chunk`. Any value gives the same tables.

    Notes
    -----
    The segments' tables come first. The nodes' rows are then filled by chunks of target
    lengths (:func:`length_chunk`): for each chunk, every node in order (children before
    parents) fills the rows of its band that fall in the chunk. A row of length ``L``
    reads its children's rows of lengths ``< L`` only, which earlier chunks, or earlier
    nodes of this chunk, have filled, so every entry is the same number as in a
    node-by-node fill; the chunks keep the triangle planes ``tri[L]`` of the chunk in
    cache for all the nodes that use them (1.35x at ``n = 100``, ``m = 200``, where
    ``tri`` takes 96 MB in float32: ``chunk x`` of ``benchmarks/bench_match.py``).
    """
    m = g.shape[1]
    n_nodes = lam.shape[0]
    n_seg = seg_lam.shape[0]
    occl = occlusion > 0.0
    for t in range(n_seg):
        out = n_nodes + t
        lv = seg_lam[t]
        lg = lv * seg_weight
        for length in range(lmin[out], lmax[out] + 1):
            ns = m if cyclic else m - length
            if ns <= 0:
                break
            best = tab[out, length]
            grow = g[length]
            for s in range(ns):
                best[s] = lg * grow[s]
            if occl:
                replace_row(best, lv, seg_alen[t], blen[length], ns, occlusion)
            if cyclic:
                for s in range(m):
                    best[m + s] = best[s]
    if chunk <= 0:
        chunk = length_chunk(m, tri.itemsize)
    for c0 in range(1, m, chunk):
        c1 = min(c0 + chunk - 1, m - 1)
        for v in range(n_nodes):
            for length in range(max(lmin[v], c0), min(lmax[v], c1) + 1):
                ns = m if cyclic else m - length
                if ns <= 0:
                    break
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
                best = tab[v, length]
                if occl:
                    replace_row(best, lam[v], alen[v], blen[length], ns, occlusion)
                if cyclic:
                    for s in range(m):
                        best[m + s] = best[s]


@_jit
def closed_root_min(
    t1: np.ndarray, t2: np.ndarray, lo1: int, hi1: int, lo2: int, hi2: int
) -> tuple[float, int, int]:
    """Best cyclic alignment of a closed model, ``min_{s, L} T1[L, s] + T2[m - L, s + L]``.

    ``t1``, ``t2`` are the two halves' doubled tables (the second half starts at ``s + L``
    and ends at ``s``); ``[lo, hi]`` are their bands.

    Returns
    -------
    cost, s, L
        ``cost >= SENTINEL / 2`` when no alignment is admissible.
    """
    m = t1.shape[0]
    best = SENTINEL
    bs = 0
    bl = 1
    for length in range(max(1, lo1, m - hi2), min(m - 1, hi1, m - lo2) + 1):
        row1 = t1[length]
        row2 = t2[m - length]
        for s in range(m):
            c = row1[s] + row2[s + length]
            if c < best:
                best = c
                bs = s
                bl = length
    return best, bs, bl


@_jit
def closed_costs(
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
    """ψ of many closed shape-trees against one closed target, in one call.

    The per-tree arguments of :func:`fill_tables` are stacked along a first axis of
    length ``R`` (one row per shape-tree; all trees have the same numbers of nodes and
    segments), ``root1``/``root2`` (``R``,) are the table indices of each tree's two
    roots, ``tab`` is one tree's workspace and ``out`` (``R``,) receives the costs
    (``>= SENTINEL / 2`` where no matching is admissible).
    """
    for r in range(lam.shape[0]):
        fill_tables(
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
            tri,
            deg,
            g,
            blen,
            True,
            occlusion,
            seg_weight,
            lmin[r],
            lmax[r],
            tab,
            hyper,
        )
        a = root1[r]
        b = root2[r]
        out[r] = closed_root_min(tab[a], tab[b], lmin[r, a], lmax[r, a], lmin[r, b], lmax[r, b])[0]


@_jit
def target_tables(
    bx: np.ndarray,
    by: np.ndarray,
    cyclic: bool,
    power: float,
    tri: np.ndarray,
    deg: np.ndarray,
    g: np.ndarray,
    blen: np.ndarray,
    g_hyp: np.ndarray,
) -> None:
    """Per-target precomputation: triangle shapes, base-case costs and subcurve lengths.

    Computed in float64 and stored in the outputs' precision (float64 or float32).

    Parameters
    ----------
    bx, by : float64 (m,)
        Target points.
    cyclic : bool
    power : float
        λ exponent (a piece of ``l`` of the ``L`` segments weighs ``(l / L) ** power``).
    tri : (m, m, 3, m)
        Output ``[L, k, (z1, z2.real, z2.imag), s]``: unit Helmert coordinates of the
        triangle ``(b_s, b_{s+k}, b_{s+L})`` (:func:`~shapetree.geometry._dif.unit_helmert`;
        ``(0, 0, 0)`` for a triangle of zero size).
    deg : uint8 (m, m)
        Output ``[L, k]``: 1 where plane ``(L, k)`` holds a zero-size triangle, zeroed by
        the caller.
    g : (m, m)
        Output ``[L, s]``, zeroed by the caller.
    blen : (m, m)
        Output ``[L, s]``, zeroed by the caller.
    g_hyp : (m, m)
        Output: ``g`` with the pseudo-hyperbolic ``dif``, zeroed by the caller.
    """
    m = bx.shape[0]
    h = np.zeros((m, m))
    hh = np.zeros((m, m))
    nseg = m if cyclic else m - 1
    seg = np.empty(nseg)
    for i in range(nseg):
        j = i + 1 if i + 1 < m else 0
        seg[i] = np.hypot(bx[j] - bx[i], by[j] - by[i])
    total = seg.sum()
    for s in range(m):
        acc = 0.0
        for length in range(1, m):
            if not cyclic and s + length > m - 1:
                break
            acc += seg[(s + length - 1) % m]
            blen[length, s] = acc / total
    # doubled coordinates: index s + k < 2m needs no modulo
    x2 = np.concatenate((bx, bx))
    y2 = np.concatenate((by, by))
    for length in range(2, m):
        ns = m if cyclic else m - length
        for k in range(1, length):
            tp = tri[length, k, 0]
            tr = tri[length, k, 1]
            ti = tri[length, k, 2]
            for s in range(ns):
                z1, z2r, z2i = unit_helmert(
                    x2[s], y2[s], x2[s + k], y2[s + k], x2[s + length], y2[s + length]
                )
                tp[s] = z1
                tr[s] = z2r
                ti[s] = z2i
                if is_zero_shape(z1, z2r, z2i):
                    deg[length, k] = 1
    # base case: a straight segment subdivided to L + 1 points matched point for point
    # to B[s..s+L] over the half-split tree; h = sum of (node length in segments) * dif
    for length in range(2, m):
        kk = length // 2
        w = kk / length - 0.5  # Bookstein coordinate of the subdivided segment's midpoint
        a1, a2, _ = unit_helmert(-0.5, 0.0, w, 0.0, 0.5, 0.0)  # real: the segment is straight
        for s in range(m):
            if not cyclic and s + length > m - 1:
                break
            dif = helmert_dif(
                a1,
                a2,
                0.0,
                float(tri[length, kk, 0, s]),
                float(tri[length, kk, 1, s]),
                float(tri[length, kk, 2, s]),
            )
            hdif = helmert_dif_kind(
                a1,
                a2,
                0.0,
                float(tri[length, kk, 0, s]),
                float(tri[length, kk, 1, s]),
                float(tri[length, kk, 2, s]),
                True,
            )
            right = (s + kk) % m
            h[length, s] = h[kk, s] + h[length - kk, right] + length**power * dif
            g[length, s] = h[length, s] / length**power
            hh[length, s] = hh[kk, s] + hh[length - kk, right] + length**power * hdif
            g_hyp[length, s] = hh[length, s] / length**power
