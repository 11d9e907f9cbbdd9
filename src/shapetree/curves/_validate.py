"""Validation and basic geometry of curves.

Public here: ``as_curve``, ``curve_length``, ``signed_area``, ``orient``.

A curve is an ``(n, 2)`` float64 array of ``(x, y)`` points. Closed curves are stored without
repeating the first point at the end.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from shapetree._errors import CurveError

__all__ = ["as_curve", "curve_length", "signed_area", "orient"]

_ORIENTATIONS = ("ccw", "cw", "keep")


def _as_xy(points: ArrayLike, name: str = "curve") -> np.ndarray:
    """Return ``points`` as a finite ``(n, 2)`` float64 array (a copy), or raise ``CurveError``.

    Only the array itself is checked (shape, numbers, finiteness); duplicate points are kept.
    """
    try:
        arr = np.array(points, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise CurveError(
            f"{name}: points are not a numeric (n, 2) array of (x, y) coordinates ({exc})"
        ) from None
    if arr.ndim != 2 or arr.shape[1] != 2:
        kind = f"{arr.ndim}-D array" if arr.ndim != 2 else "array"
        raise CurveError(
            f"{name}: expected an (n, 2) array of (x, y) points, got a {kind} of shape {arr.shape}"
        )
    if arr.shape[0] == 0:
        raise CurveError(f"{name}: the curve is empty (shape {arr.shape})")
    bad = ~np.isfinite(arr)
    if bad.any():
        rows = np.flatnonzero(bad.any(axis=1))
        first = int(rows[0])
        what = "NaN" if np.isnan(arr[first]).any() else "inf"
        more = f" (and {rows.size - 1} more rows)" if rows.size > 1 else ""
        raise CurveError(
            f"{name}: row {first} (0-based) contains {what}: {arr[first].tolist()}{more}; "
            "all coordinates must be finite"
        )
    return arr


def as_curve(points: ArrayLike, *, closed: bool, name: str = "curve") -> np.ndarray:
    """Validate a curve and return it as a clean ``(n, 2)`` float64 copy.

    Consecutive duplicate points are dropped. For a closed curve a last point equal to the
    first one (an explicitly repeated endpoint) is dropped too, because closed curves are stored
    without repeating the first point.

    Parameters
    ----------
    points : array_like, shape (n, 2)
        The ``(x, y)`` points of the curve, in any length unit (pixels for image curves).
    closed : bool
        Whether the curve is closed (the last point connects back to the first one).
    name : str, optional
        What to call the curve in error messages (e.g. a file name).

    Returns
    -------
    numpy.ndarray, shape (m, 2), float64
        The validated points, ``m <= n``; a new array, never a view of ``points``.

    Raises
    ------
    CurveError
        If the array is not ``(n, 2)`` (1-D, 3 columns, empty, not numeric), contains NaN or inf
        (the message names the row), has zero length, or has fewer than 3 distinct points.
    """
    arr = _as_xy(points, name)
    if arr.shape[0] > 1:
        keep = np.ones(arr.shape[0], dtype=bool)
        keep[1:] = np.any(arr[1:] != arr[:-1], axis=1)
        arr = arr[keep]
    if closed:
        while arr.shape[0] > 1 and np.array_equal(arr[-1], arr[0]):
            arr = arr[:-1]
    n_distinct = np.unique(arr, axis=0).shape[0]
    if n_distinct == 1:
        raise CurveError(f"{name}: the curve has zero length (all its points are identical)")
    if n_distinct < 3:
        raise CurveError(
            f"{name}: the curve has fewer than 3 distinct points ({n_distinct}); "
            "a curve needs at least 3"
        )
    return arr


def curve_length(points: ArrayLike, *, closed: bool) -> float:
    """Total length of a polygonal curve.

    Parameters
    ----------
    points : array_like, shape (n, 2)
        The ``(x, y)`` points.
    closed : bool
        If true, the closing segment from the last point back to the first one is included.

    Returns
    -------
    float
        The sum of the segment lengths, in the units of the coordinates.
    """
    arr = _as_xy(points)
    if closed:
        arr = np.vstack([arr, arr[:1]])
    return float(np.sum(np.hypot(*np.diff(arr, axis=0).T)))


def signed_area(points: ArrayLike) -> float:
    """Signed area enclosed by a closed polygon (shoelace formula, coordinates as given).

    Parameters
    ----------
    points : array_like, shape (n, 2)
        The ``(x, y)`` vertices; the polygon is closed implicitly (last point to first).

    Returns
    -------
    float
        Positive if the vertices run counter-clockwise in a y-up frame, negative if clockwise, in
        squared coordinate units. For image curves (``x`` = column, ``y`` = row, y pointing down) a
        positive area means the curve looks *clockwise* on screen.
    """
    arr = _as_xy(points)
    x, y = arr[:, 0], arr[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def orient(points: ArrayLike, orientation: str | None = "ccw") -> np.ndarray:
    """Return a closed curve with the requested orientation.

    Parameters
    ----------
    points : array_like, shape (n, 2)
        The ``(x, y)`` points of a closed curve (without a repeated endpoint).
    orientation : {"ccw", "cw", "keep", None}, optional
        ``"ccw"``: positive :func:`signed_area`; ``"cw"``: negative signed area; ``"keep"`` or
        ``None``: unchanged. The orientation is judged in the coordinates as given: for image
        curves (``x`` = column, ``y`` = row, y pointing down) ``"ccw"`` looks clockwise on screen.

    Returns
    -------
    numpy.ndarray, shape (n, 2), float64
        A copy; if reversed, the first point stays first (``[p0, p_{n-1}, ..., p1]``). A curve of
        zero signed area is returned unchanged.

    Raises
    ------
    CurveError
        If ``orientation`` is not one of the values above, or ``points`` is not a valid array.
    """
    if orientation is not None and orientation not in _ORIENTATIONS:
        raise CurveError(
            f"unknown orientation {orientation!r}; expected one of 'ccw', 'cw', 'keep' or None"
        )
    arr = _as_xy(points)
    if orientation is None or orientation == "keep":
        return arr
    area = signed_area(arr)
    if (orientation == "ccw" and area < 0) or (orientation == "cw" and area > 0):
        arr = np.concatenate([arr[:1], arr[:0:-1]])
    return arr
