"""Compiled dynamic-programming kernels of eq. (1) (numba ``nopython``, cached on disk).

Layout
------
A target subcurve is named by its *length* ``L`` (number of target segments,
``1 <= L <= m - 1``) and its *start* ``s``; it ends at ``e = s + L`` (mod ``m`` when the
target is closed, i.e. its subcurves wrap around). Every cost table is stored twice:

* ``tl[t, L, s]``: by start (a *left* child is read as ``tl[left, k, :]``);
* ``er[t, L, e2]`` with ``e2`` in ``[0, 2m)``: by end, duplicated at ``e`` and ``e + m`` for
  closed targets, so the *right* child of ``(s, L)`` split at ``k`` is ``er[right, L-k, s+L]``
  without any modulo.

The loops run ``node -> L -> k -> s`` with ``s`` innermost: the minimum over the split
``k`` becomes an element-wise minimum over ``s`` that LLVM vectorises (a min-*reduction*
over ``k`` would not be vectorised from numba).

``dif`` is the squared full Procrustes distance between the model triangle
``(a_start, a_mid, a_end)`` and the target triangle ``(b_s, b_{s+k}, b_{s+L})``, both as
unit-size Helmert coordinates rotated so the first coordinate is real::

    dif = 1 - (a1 z1 + a2r z2r + a2i z2i)^2 - (a2r z2i - a2i z2r)^2

The target's ``z`` (indexed ``[L, k, s]``) are precomputed once per target and shared by
every model matched against it.
"""

from __future__ import annotations

import numpy as np
from numba import njit

_SQRT2 = np.sqrt(2.0)
_SQRT6 = np.sqrt(6.0)


@njit(cache=True, fastmath=True, nogil=True)
def fill_tables(
    left_tab: np.ndarray,
    right_tab: np.ndarray,
    lam: np.ndarray,
    a1: np.ndarray,
    a2r: np.ndarray,
    a2i: np.ndarray,
    flat: np.ndarray,
    alen: np.ndarray,
    seg_lam: np.ndarray,
    seg_alen: np.ndarray,
    z1: np.ndarray,
    z2r: np.ndarray,
    z2i: np.ndarray,
    g: np.ndarray,
    blen: np.ndarray,
    cyclic: bool,
    occlusion: float,
    lmin: np.ndarray,
    lmax: np.ndarray,
    tl: np.ndarray,
    er: np.ndarray,
) -> None:
    """Fill the cost tables of every segment and node of one shape-tree, leaves up.

    Parameters
    ----------
    left_tab, right_tab : int64 (K,)
        Table index of each node's children (the model's segments have indices ``K ..``).
    lam, a1, a2r, a2i, flat, alen : float64 (K,)
        Per node: λ (weight included), Helmert shape of its triangle, cost against a
        straight segment (base case), relative arclength (for the replacement cost).
    seg_lam, seg_alen : float64 (S,)
        Per model segment: λ and relative arclength.
    z1, z2r, z2i : float64 (m, m, m)
        Target triangle shapes ``[L, k, s]``.
    g : float64 (m, m)
        ``g[L, s]``: base-case cost per unit λ of a straight segment vs subcurve (s, L).
    blen : float64 (m, m)
        ``blen[L, s]``: relative arclength of the target subcurve (s, L).
    cyclic : bool
        Target subcurves wrap around.
    occlusion : float
        Replacement cost factor κ (``<= 0`` disables replacement).
    lmin, lmax : int64 (K + S,)
        Band of target lengths each table may use (pruned mode); ``1`` and ``m - 1``
        for exact matching. Entries outside the band are ``+inf``.
    tl : float64 (K + S, m, m)
        Output, by start.
    er : float64 (K + S, m, 2 m)
        Output, by end.
    """
    m = g.shape[1]
    n_nodes = lam.shape[0]
    n_seg = seg_lam.shape[0]
    occl = occlusion > 0.0
    best = np.empty(m)
    for t in range(n_seg + n_nodes):
        is_seg = t < n_seg
        v = t - n_seg  # node index when not a segment
        tab = n_nodes + t if is_seg else v
        if is_seg:
            lv = seg_lam[t]
            la = seg_alen[t]
        else:
            lv = lam[v]
            la = alen[v]
        lo = lmin[tab]
        hi = lmax[tab]
        for length in range(1, m):
            ns = m if cyclic else m - length
            if ns <= 0:
                break
            if length < lo or length > hi:
                for s in range(ns):
                    best[s] = np.inf
            elif is_seg:
                grow = g[length]
                for s in range(ns):
                    best[s] = lv * grow[s]
            elif length == 1:
                fl = flat[v]
                for s in range(ns):
                    best[s] = fl
            else:
                c1 = a1[v]
                c2r = a2r[v]
                c2i = a2i[v]
                lt = left_tab[v]
                rt = right_tab[v]
                for s in range(ns):
                    best[s] = np.inf
                # splits k whose halves both fall inside their children's bands
                k0 = max(1, lmin[lt], length - lmax[rt])
                k1 = min(length - 1, lmax[lt], length - lmin[rt])
                for k in range(k0, k1 + 1):
                    lrow = tl[lt, k]
                    rrow = er[rt, length - k, length:]
                    zz1 = z1[length, k]
                    zzr = z2r[length, k]
                    zzi = z2i[length, k]
                    for s in range(ns):
                        ip_re = c1 * zz1[s] + c2r * zzr[s] + c2i * zzi[s]
                        ip_im = c2r * zzi[s] - c2i * zzr[s]
                        c = lrow[s] + rrow[s] + lv * (1.0 - ip_re * ip_re - ip_im * ip_im)
                        b = best[s]
                        best[s] = c if c < b else b
            if occl and lo <= length <= hi:
                brow = blen[length]
                for s in range(ns):
                    r = occlusion * lv * (la + brow[s])
                    if r < best[s]:
                        best[s] = r
            for s in range(ns):
                tl[tab, length, s] = best[s]
            if cyclic:
                for s in range(ns):
                    e = s + length
                    if e >= m:
                        e -= m
                    er[tab, length, e] = best[s]
                    er[tab, length, e + m] = best[s]
            else:
                for s in range(ns):
                    er[tab, length, s + length] = best[s]


@njit(cache=True, fastmath=True, nogil=True)
def closed_root_min(t1: np.ndarray, er2: np.ndarray) -> tuple[float, int, int]:
    """Best cyclic alignment of a closed model, ``min_{s, L} T1[L, s] + T2[m - L, s + L]``.

    ``t1`` is the first half's by-start table, ``er2`` the second half's by-end table (the
    second half starts at ``s + L`` and ends at ``s``).

    Returns
    -------
    cost, s, L
    """
    m = t1.shape[1]
    best = np.inf
    bs = 0
    bl = 1
    for length in range(1, m):
        row1 = t1[length]
        row2 = er2[m - length]
        for s in range(m):
            c = row1[s] + row2[s]
            if c < best:
                best = c
                bs = s
                bl = length
    return best, bs, bl


@njit(cache=True, fastmath=False, nogil=True)
def target_tables(
    bx: np.ndarray, by: np.ndarray, cyclic: bool, power: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per-target precomputation: triangle shapes, base-case costs and subcurve lengths.

    Parameters
    ----------
    bx, by : float64 (m,)
        Target points.
    cyclic : bool
    power : float
        λ exponent (a piece of ``l`` of the ``L`` segments weighs ``(l / L) ** power``).

    Returns
    -------
    z1, z2r, z2i : (m, m, m) ``[L, k, s]``
    g : (m, m) ``[L, s]``
    blen : (m, m) ``[L, s]``
    """
    m = bx.shape[0]
    z1 = np.zeros((m, m, m))
    z2r = np.zeros((m, m, m))
    z2i = np.zeros((m, m, m))
    g = np.zeros((m, m))
    blen = np.zeros((m, m))
    h = np.zeros((m, m))
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
    for length in range(2, m):
        for s in range(m):
            if not cyclic and s + length > m - 1:
                break
            e = (s + length) % m
            h1r = (bx[e] - bx[s]) / _SQRT2
            h1i = (by[e] - by[s]) / _SQRT2
            a = np.hypot(h1r, h1i)
            if a > 0:
                rr = h1r / a
                ri = -h1i / a
            else:
                rr = 1.0
                ri = 0.0
            for k in range(1, length):
                j = (s + k) % m
                h2r = (2.0 * bx[j] - bx[s] - bx[e]) / _SQRT6
                h2i = (2.0 * by[j] - by[s] - by[e]) / _SQRT6
                # rotate by conj(h1)/|h1| so that h1 becomes real
                q2r = h2r * rr - h2i * ri
                q2i = h2r * ri + h2i * rr
                norm = np.sqrt(a * a + q2r * q2r + q2i * q2i)
                if norm > 0:
                    z1[length, k, s] = a / norm
                    z2r[length, k, s] = q2r / norm
                    z2i[length, k, s] = q2i / norm
    # base case: a straight segment subdivided to L + 1 points matched point for point
    # to B[s..s+L] over the half-split tree; h = sum of (node length in segments) * dif
    for length in range(2, m):
        kk = length // 2
        w = kk / length - 0.5
        c1 = 1.0 / _SQRT2
        c2 = 2.0 * w / _SQRT6
        nrm = np.sqrt(c1 * c1 + c2 * c2)
        c1 /= nrm
        c2 /= nrm
        for s in range(m):
            if not cyclic and s + length > m - 1:
                break
            ip_re = c1 * z1[length, kk, s] + c2 * z2r[length, kk, s]
            ip_im = c2 * z2i[length, kk, s]
            dif = max(1.0 - ip_re * ip_re - ip_im * ip_im, 0.0)
            right = (s + kk) % m
            h[length, s] = h[kk, s] + h[length - kk, right] + length**power * dif
            g[length, s] = h[length, s] / length**power
    return z1, z2r, z2i, g, blen
