"""Resampling of curves uniformly in arc length."""

from __future__ import annotations

import numbers

import numpy as np
from numpy.typing import ArrayLike

from shapetree._errors import CurveError
from shapetree.curves._validate import as_curve

__all__ = ["point_at", "resample", "smooth"]


def resample(points: ArrayLike, n: int, *, closed: bool, phase: float = 0.0) -> np.ndarray:
    """Resample a polygonal curve to ``n`` points equally spaced in arc length.

    Parameters
    ----------
    points : array_like, shape (m, 2)
        The ``(x, y)`` points (or any other form :func:`as_curve` accepts); validated with
        :func:`as_curve` first. An open curve needs 2 distinct points (a straight segment is
        a valid open polyline), a closed one 3.
    n : int
        Number of output points: at least 3 for a closed curve, at least 2 for an open one
        (its two ends).
    closed : bool
        Open curve: the first and last points are kept and the ``n - 1`` gaps along the curve are
        equal (``length / (n - 1)``). Closed curve: the output starts at the first point and the
        ``n`` points split the whole perimeter, including the closing segment, into ``n`` equal
        arcs (``length / n``); the first point is not repeated at the end.
    phase : float, optional
        Closed curves only: start ``phase`` sample spacings (``phase * length / n``) after
        the first point instead of at it, ``0 <= phase < 1``. Resampling with phases
        ``p / P`` gives ``P`` interleaved samplings of the same curve (the retrieval
        engine's ``phases`` option).

    Returns
    -------
    numpy.ndarray, shape (n, 2), float64
        The resampled points, on the original polygon.

    Raises
    ------
    CurveError
        If ``n`` is not an integer >= 3 (closed) or >= 2 (open), or the curve is invalid (see
        :func:`as_curve`).
    """
    n_min = 3 if closed else 2
    if isinstance(n, bool) or not isinstance(n, numbers.Integral) or n < n_min:
        what = "a closed" if closed else "an open"
        raise CurveError(f"resample: n must be an integer >= {n_min} for {what} curve, got {n!r}")
    n = int(n)
    if isinstance(phase, bool) or not isinstance(phase, numbers.Real):
        raise CurveError(f"resample: phase must be a number, got {phase!r}")
    phase = float(phase)
    if not 0.0 <= phase < 1.0:
        raise CurveError(f"resample: phase must be in [0, 1), got {phase}")
    if phase and not closed:
        raise CurveError(
            "resample: phase applies to closed curves only (open ones keep their ends)"
        )
    arr = as_curve(points, closed=closed, min_points=3 if closed else 2)
    if closed:
        arr = np.vstack([arr, arr[:1]])
    seg = np.hypot(*np.diff(arr, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    total = s[-1]
    t = (np.arange(n) + phase) * (total / n) if closed else np.linspace(0.0, total, n)
    # Segment index of each target: the last vertex with s <= t (clipped to a real segment).
    idx = np.clip(np.searchsorted(s, t, side="right") - 1, 0, len(seg) - 1)
    frac = (t - s[idx]) / seg[idx]
    out = arr[idx] + frac[:, None] * (arr[idx + 1] - arr[idx])
    if not phase:
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


def smooth(points: ArrayLike, sigma: float, *, closed: bool) -> np.ndarray:
    """Gaussian smoothing along the curve, with a width relative to its length.

    The curve is first resampled densely and uniformly in arc length (so the smoothing
    does not depend on how unevenly the input was sampled, e.g. a pixel boundary), then
    each coordinate is convolved with a Gaussian of standard deviation ``sigma`` times the
    curve's length (wrapping around for a closed curve; an open curve keeps its end points).
    Smoothing removes pixel staircases and detail finer than about ``sigma``; it also
    shrinks a curve slightly where it bends (a circle of radius ``r`` by about
    ``r * (1 - exp(-(2 pi sigma)^2 / 2))``).

    Parameters
    ----------
    points : array_like, shape (m, 2)
    sigma : float
        Width of the Gaussian as a fraction of the curve length, ``0 <= sigma < 0.5``
        (``0`` returns the curve unchanged).
    closed : bool

    Returns
    -------
    numpy.ndarray, shape (k, 2), float64
        The smoothed curve, ``k = max(m, 512, ceil(10 / sigma))`` points (at most 20000)
        evenly spaced along the input; resample it to the size you need.

    Raises
    ------
    CurveError
        If ``sigma`` is not a finite number in ``[0, 0.5)`` or the curve is invalid.
    """
    from scipy.ndimage import gaussian_filter1d

    if isinstance(sigma, bool) or not isinstance(sigma, numbers.Real):
        raise CurveError(f"smooth: sigma must be a number, got {sigma!r}")
    sigma = float(sigma)
    if not (np.isfinite(sigma) and 0.0 <= sigma < 0.5):
        raise CurveError(
            f"smooth: sigma must be in [0, 0.5) (a fraction of the length), got {sigma}"
        )
    arr = as_curve(points, closed=closed)
    if sigma == 0.0:
        return arr.copy()
    k = int(min(max(len(arr), 512, np.ceil(10.0 / sigma)), 20000))
    dense = resample(arr, k, closed=closed)
    width = sigma * (k if closed else k - 1)
    out = gaussian_filter1d(dense, width, axis=0, mode="wrap" if closed else "nearest")
    if not closed:
        out[0], out[-1] = dense[0], dense[-1]
    return out
