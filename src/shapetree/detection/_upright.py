"""How far each candidate piece of a detection turns the model (``DetectParams.upright_cost``).

The stitching of §4 is invariant to rotation: each contour is matched to a model interval
by its shape alone, so a piece may place its part of the model at any angle, and a whole
match may lay the model on its side. Photographs mostly show their objects standing as
drawn. This module measures, for every contour direction ``d`` and model interval
``(a, L)`` of the piece table, the angle ``theta`` of the least-squares similarity (rotation
and scale, no reflection) that takes the interval's samples onto the contour's, both
resampled to :data:`TURN_SAMPLES` points equally spaced in arc length and centred:
``theta = arg sum_k conj(p_k) q_k`` in complex coordinates. The piece cost then adds
``upright_cost * f * (1 - cos theta)`` (``f`` the interval's share of the model), 0 for a
piece standing as drawn, ``upright_cost * f`` for one turned by a quarter.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from shapetree.curves import resample

__all__ = ["TURN_SAMPLES", "piece_turn_cos"]

#: points per piece and per model interval in the fit of the turn
TURN_SAMPLES = 8


def _interval_samples(model_points: NDArray[np.float64], k: int) -> NDArray[np.complex128]:
    """Shape ``(m, m, k)``: model interval ``(a, L)`` (samples ``a .. a + L``, cyclic)
    resampled to ``k`` points equally spaced in arc length, centred (complex)."""
    m = len(model_points)
    loop = np.vstack([model_points, model_points, model_points[:1]])
    seg = np.hypot(*np.diff(loop, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    start = cum[np.arange(m)][:, None, None]
    end = cum[np.arange(m)[:, None] + np.arange(m)[None, :]][:, :, None]
    t = start + (end - start) * np.linspace(0.0, 1.0, k)[None, None, :]
    z = np.interp(t, cum, loop[:, 0]) + 1j * np.interp(t, cum, loop[:, 1])
    return z - z.mean(axis=2, keepdims=True)


def piece_turn_cos(
    model_points: NDArray[np.float64],
    contours: Sequence[NDArray[np.float64]],
    k: int = TURN_SAMPLES,
) -> NDArray[np.float64]:
    """``cos theta`` of every piece of the stitching's table.

    Parameters
    ----------
    model_points : ndarray, shape (m, 2)
        The closed model's samples (px of the model's own frame, ``y`` down like the
        image's).
    contours : sequence of ndarray, each shape (n_i, 2)
        The open image contours (px), each of some length (the stitching's are: they
        were resampled for the tables already); one of zero length raises
        :class:`~shapetree.CurveError`.
    k : int
        Points per piece in the fit (default :data:`TURN_SAMPLES`).

    Returns
    -------
    ndarray, shape (2 * len(contours), m, m)
        Entry ``[d, a, L]``: the cosine of the turn that takes model interval ``(a, L)``
        onto contour ``d // 2`` (reversed where ``d`` is odd), in ``[-1, 1]``; 1 where
        the turn is undefined (``L = 0``, or a piece or interval whose samples do not
        determine it).
    """
    p = _interval_samples(np.asarray(model_points, dtype=np.float64), k)
    q = np.empty((2 * len(contours), k), np.complex128)
    for i, c in enumerate(contours):
        r = resample(c, k, closed=False)
        z = r[:, 0] + 1j * r[:, 1]
        q[2 * i] = z - z.mean()
        q[2 * i + 1] = q[2 * i][::-1]  # the same samples, read backwards
    inner = np.einsum("abk,dk->dab", np.conj(p), q)
    size = np.abs(inner)
    out = np.ones(inner.shape)
    ok = size > 1e-9 * (1.0 + size.max(initial=0.0))
    out[ok] = inner.real[ok] / size[ok]
    return out
