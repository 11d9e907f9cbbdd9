"""Resampling of curves uniformly in arc length."""

from __future__ import annotations

import numbers

import numpy as np
from numpy.typing import ArrayLike

from shapetree._errors import CurveError
from shapetree.curves._validate import as_curve

__all__ = ["resample"]


def resample(points: ArrayLike, n: int, *, closed: bool) -> np.ndarray:
    """Resample a polygonal curve to ``n`` points equally spaced in arc length.

    Parameters
    ----------
    points : array_like, shape (m, 2)
        The ``(x, y)`` points; validated with :func:`as_curve` first.
    n : int
        Number of output points, at least 3.
    closed : bool
        Open curve: the first and last points are kept and the ``n - 1`` gaps along the curve are
        equal (``length / (n - 1)``). Closed curve: the output starts at the first point and the
        ``n`` points split the whole perimeter, including the closing segment, into ``n`` equal
        arcs (``length / n``); the first point is not repeated at the end.

    Returns
    -------
    numpy.ndarray, shape (n, 2), float64
        The resampled points, on the original polygon.

    Raises
    ------
    CurveError
        If ``n`` is not an integer >= 3, or the curve is invalid (see :func:`as_curve`).
    """
    if isinstance(n, bool) or not isinstance(n, numbers.Integral) or n < 3:
        raise CurveError(f"resample: n must be an integer >= 3, got {n!r}")
    n = int(n)
    arr = as_curve(points, closed=closed)
    if closed:
        arr = np.vstack([arr, arr[:1]])
    seg = np.hypot(*np.diff(arr, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    total = s[-1]
    t = np.arange(n) * (total / n) if closed else np.linspace(0.0, total, n)
    # Segment index of each target: the last vertex with s <= t (clipped to a real segment).
    idx = np.clip(np.searchsorted(s, t, side="right") - 1, 0, len(seg) - 1)
    frac = (t - s[idx]) / seg[idx]
    out = arr[idx] + frac[:, None] * (arr[idx + 1] - arr[idx])
    out[0] = arr[0]
    if not closed:
        out[-1] = arr[-1]
    return out


def point_at(points: ArrayLike, pos: ArrayLike, *, closed: bool) -> np.ndarray:
    """Points at fractional sample indices along a polyline.

    ``pos = j + t`` (``0 <= t < 1``) is the point ``(1 - t) p_j + t p_{j+1}``; this is how
    matching results give positions along a curve (``MatchResult.a_to_b``).

    Parameters
    ----------
    points : array_like, shape (n, 2)
    pos : array_like, shape (k,)
        Fractional indices (taken modulo ``n`` for closed curves, clipped for open ones).
    closed : bool

    Returns
    -------
    ndarray, shape (k, 2)
    """
    pts = np.asarray(points, dtype=float)
    q = np.asarray(pos, dtype=float)
    n = pts.shape[0]
    i0 = np.floor(q).astype(int)
    t = (q - i0)[:, None]
    if closed:
        i0 %= n
        i1 = (i0 + 1) % n
    else:
        i0 = np.clip(i0, 0, n - 1)
        i1 = np.minimum(i0 + 1, n - 1)
    return (1 - t) * pts[i0] + t * pts[i1]
