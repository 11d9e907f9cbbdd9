"""Slow, literal oracle of the stitching DP (:func:`._stitch._stitch_kernel`): tests only.

Written from the rules in the docstring of :mod:`._stitch`, sharing no code with the
kernel: every ``dif`` is the literal pure-Python one of
:mod:`shapetree.matching._reference`, the contours a match uses are a Python set (the
kernel's 128-bit hash is exact for fewer than 128 contours, the hash multiplier being
odd), and no candidate is ever skipped early: for each model interval ``(a, L)``, in the
kernel's order (``L`` outer, ``a`` inner), it lists **every** candidate

* a single piece ``d`` (``L < m``): ``base[d, a, L]``;
* a direct composition of kept matches ``i`` of ``(a, l)`` and ``j`` of ``(a + l, L -
  l)`` with ``q_i`` near ``p_j`` and no shared contour: ``cost_i + cost_j + λ frac(a, L)
  dif((M_a, M_b, M_c), (p_i, (q_i + p_j) / 2, q_j))``, or, for ``L = m``, no triangle and
  ``q_j`` near ``p_i``;
* a composition across a gap ``(a + l1, g)`` of the ``gap_beam`` cheapest kept matches
  on each side: ``cost_i + gap + cost_j`` plus the cheaper bracketing's two triangle
  terms (one each for ``L = m``, where ``q_j`` must be near ``p_i``);

keeps the ``4 beam`` cheapest, and from them, cheapest first, up to ``beam`` with at
most ``per_end`` sharing an image start and at most ``per_end`` sharing an image end.
The kernel reaches the same lists while pruning (sorted beams, a bounded heap, triangle
terms computed only while they can matter); this module is what it must agree with.
Python loops throughout: models of about a dozen points and a few dozen pieces.
"""

from __future__ import annotations

import numpy as np

from shapetree.matching._reference import DIF_FUNCTIONS

__all__ = ["reference_stitch"]


def _tri(*z: complex) -> np.ndarray:
    return np.array([[v.real, v.imag] for v in z])


def reference_stitch(
    M: np.ndarray,
    frac: np.ndarray,
    gapc: np.ndarray,
    base: np.ndarray,
    piece_p: np.ndarray,
    piece_q: np.ndarray,
    piece_contour: np.ndarray,
    piece_box: np.ndarray,
    E: np.ndarray,
    near: np.ndarray,
    lam: float,
    beam: int,
    per_end: int,
    max_gap: int,
    gap_beam: int,
    dif: str = "procrustes",
) -> list[dict]:
    """The kept interval matches, in the kernel's entry order.

    Arguments are those of :func:`._stitch._stitch_kernel` (``M``, ``E`` complex;
    ``base`` with ``inf`` where a piece is not allowed), except ``piece_contour`` (the
    contour id of each piece) in place of its hash bits.

    Returns
    -------
    list of dict
        One per kept match: ``cost``, ``a``, ``L``, ``p``, ``q``, ``kind`` (0 piece, 1
        direct, 2 across a gap), ``left`` (piece id for kind 0, else entry id),
        ``right`` (entry id or -1), ``gap`` (gap length), ``contours`` (frozenset),
        ``box`` (tuple ``x1, y1, x2, y2``).
    """
    dfn = DIF_FUNCTIONS[dif]
    m = len(M)
    entries: list[dict] = []
    kept: dict[tuple[int, int], list[int]] = {}

    def tri_dif(model3: tuple[complex, ...], image3: tuple[complex, ...]) -> float:
        return dfn(_tri(*model3), _tri(*image3))

    for L in range(1, m + 1):
        for a in range(m):
            c_end = (a + L) % m
            cands: list[tuple[float, int, int, int, int, int, int]] = []
            if L < m:
                for d in range(len(base)):
                    if np.isfinite(base[d, a, L]):
                        cands.append((float(base[d, a, L]), 0, d, -1, 0, piece_p[d], piece_q[d]))
            lamf = lam * frac[a, L]
            for l in range(1, L):
                b = (a + l) % m
                for i in kept[a, l]:
                    for j in kept[b, L - l]:
                        ei, ej = entries[i], entries[j]
                        if not near[ei["q"], ej["p"]] or ei["contours"] & ej["contours"]:
                            continue
                        c = ei["cost"] + ej["cost"]
                        if L < m:
                            mid = 0.5 * (E[ei["q"]] + E[ej["p"]])
                            image3 = (E[ei["p"]], mid, E[ej["q"]])
                            c += lamf * tri_dif((M[a], M[b], M[c_end]), image3)
                        elif not near[ej["q"], ei["p"]]:
                            continue
                        cands.append((c, 1, i, j, 0, ei["p"], ej["q"]))
            for l1 in range(1, L - 1):
                b = (a + l1) % m
                for g in range(1, min(max_gap, L - 1 - l1) + 1):
                    b2 = (a + l1 + g) % m
                    lr = L - l1 - g
                    fr1 = lam * frac[a, l1 + g]
                    fr2 = lam * frac[b, L - l1]
                    for i in kept[a, l1][:gap_beam]:
                        for j in kept[b2, lr][:gap_beam]:
                            ei, ej = entries[i], entries[j]
                            if ei["contours"] & ej["contours"]:
                                continue
                            p, q, r, s = E[ei["p"]], E[ei["q"]], E[ej["p"]], E[ej["q"]]
                            c = ei["cost"] + gapc[b, g] + ej["cost"]
                            t1 = fr1 * tri_dif((M[a], M[b], M[b2]), (p, q, r))
                            t2 = fr2 * tri_dif((M[b], M[b2], M[c_end]), (q, r, s))
                            if L < m:
                                t1 += lamf * tri_dif((M[a], M[b2], M[c_end]), (p, r, s))
                                t2 += lamf * tri_dif((M[a], M[b], M[c_end]), (p, q, s))
                            elif not near[ej["q"], ei["p"]]:
                                continue
                            cands.append((c + min(t1, t2), 2, i, j, g, ei["p"], ej["q"]))
            cands.sort(key=lambda t: t[0])
            n_p: dict[int, int] = {}
            n_q: dict[int, int] = {}
            ids: list[int] = []
            for c, kind, left, right, g, p, q in cands[: 4 * beam]:
                if n_p.get(p, 0) >= per_end or n_q.get(q, 0) >= per_end:
                    continue
                n_p[p] = n_p.get(p, 0) + 1
                n_q[q] = n_q.get(q, 0) + 1
                if kind == 0:
                    used = frozenset([int(piece_contour[left])])
                    box = tuple(float(v) for v in piece_box[left])
                else:
                    bl, br = entries[left]["box"], entries[right]["box"]
                    used = entries[left]["contours"] | entries[right]["contours"]
                    box = (*np.minimum(bl[:2], br[:2]), *np.maximum(bl[2:], br[2:]))
                ids.append(len(entries))
                entries.append(
                    {
                        "cost": c,
                        "a": a,
                        "L": L,
                        "p": int(p),
                        "q": int(q),
                        "kind": kind,
                        "left": int(left),
                        "right": int(right),
                        "gap": int(g),
                        "contours": used,
                        "box": box,
                    }
                )
                if len(ids) == beam:
                    break
            kept[a, L] = ids
    return entries
