"""Validation and basic geometry of curves.

Public here: ``as_curve``, ``curve_length``, ``signed_area``, ``orient``.

A curve is an ``(n, 2)`` float64 array of ``(x, y)`` points. Closed curves are stored without
repeating the first point at the end.

Every function that takes a curve reads it through :func:`_as_xy`, which also accepts the
forms other libraries hand curves over in: 1-D complex arrays ``x + iy``, OpenCV contours
(``cv2.findContours`` gives ``(n, 1, 2)`` integer arrays) and geometries with a
``__geo_interface__`` (shapely's ``Polygon``, ``LinearRing`` and ``LineString``, or the
GeoJSON dicts they describe).
"""

from __future__ import annotations

import numbers
from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike

from shapetree._errors import CurveError

__all__ = ["as_curve", "curve_length", "signed_area", "orient"]

_ORIENTATIONS = ("ccw", "cw", "keep")

ACCEPTED_FORMS = (
    "an (n, 2) array of (x, y) points, a 1-D complex array of points x + iy, an OpenCV "
    "contour of shape (n, 1, 2), or a LineString, LinearRing or Polygon (an object with "
    "__geo_interface__, e.g. shapely)"
)
_RINGS = ("LinearRing", "Polygon")
_MULTI = ("MultiPoint", "MultiLineString", "MultiPolygon", "GeometryCollection")


def _geo_coords(geo: object, name: str, depth: int = 0) -> tuple[object, bool]:
    """The coordinates of one geo-interface geometry and whether they form a ring.

    A Polygon gives its exterior ring (holes are ignored); a Feature its geometry.
    """
    if not isinstance(geo, Mapping) or "type" not in geo:
        raise CurveError(
            f"{name}: __geo_interface__ is not a GeoJSON-like mapping with a 'type' "
            f"(got {type(geo).__name__}); expected {ACCEPTED_FORMS}"
        )
    kind = geo["type"]
    if kind == "Feature" and depth == 0:
        return _geo_coords(geo.get("geometry"), name, depth + 1)
    if kind in _MULTI or kind == "FeatureCollection":
        hint = (
            " (e.g. the largest polygon: max(shape.geoms, key=lambda g: g.area))"
            if kind == "MultiPolygon"
            else ""
        )
        raise CurveError(
            f"{name}: a {kind} holds several geometries, not one curve; pass one of its "
            f"parts{hint}; expected {ACCEPTED_FORMS}"
        )
    if kind not in ("LineString", *_RINGS):
        raise CurveError(f"{name}: a {kind} geometry is not a curve; expected {ACCEPTED_FORMS}")
    coords = geo.get("coordinates")
    if kind == "Polygon":
        coords = coords[0] if coords is not None and len(coords) else None  # the exterior
    if coords is None or not len(coords):
        raise CurveError(f"{name}: the {kind} is empty (it has no coordinates)")
    return coords, kind in _RINGS


def _coerce(points: object, name: str) -> tuple[np.ndarray, bool]:
    """``points`` as an ``(n, 2)``-or-other float64 array (a copy), and whether it was a ring.

    Geo-interface geometries become their ``(x, y)`` coordinates (a ``z`` is dropped, a
    ring's repeated closing point too); OpenCV's ``(n, 1, 2)`` contours become ``(n, 2)``.
    Any other shape is returned as it is, for :func:`_as_xy` to refuse.
    """
    ring = False
    geo = getattr(points, "__geo_interface__", None)
    if geo is None and isinstance(points, Mapping) and "type" in points:
        geo = points  # a GeoJSON geometry dict itself
    if geo is not None:
        points, ring = _geo_coords(geo, name)
    arr = _float_array(points, name)
    if geo is not None:
        if arr.ndim == 2 and arr.shape[1] == 3:
            arr = arr[:, :2]  # GeoJSON positions may carry a z; the curve is its (x, y)
        if ring and arr.ndim == 2 and arr.shape[0] > 1 and np.array_equal(arr[-1], arr[0]):
            arr = arr[:-1]  # GeoJSON rings repeat their first point at the end
    elif arr.ndim == 3 and arr.shape[1:] == (1, 2):
        arr = arr.reshape(-1, 2)  # an OpenCV contour
    return arr, ring


def _float_array(points: object, name: str) -> np.ndarray:
    """``points`` as a float64 array (a copy). A 1-D complex array is the curve ``x + iy``
    (an ``(n, 2)`` array of its real and imaginary parts); any other complex array must
    have no imaginary part, which is never dropped silently."""
    try:
        raw = np.asarray(points)
        if raw.dtype.kind != "c":
            return np.array(raw, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        hint = ""
        first = points[0] if isinstance(points, list | tuple) and points else None
        if isinstance(first, np.ndarray) and first.ndim == 3 and first.shape[1:] == (1, 2):
            hint = (
                "; this looks like a list of OpenCV contours: pass one of them "
                "(e.g. max(contours, key=cv2.contourArea))"
            )
        raise CurveError(
            f"{name}: points are not a numeric (n, 2) array of (x, y) coordinates ({exc}); "
            f"expected {ACCEPTED_FORMS}{hint}"
        ) from None
    if raw.ndim == 1:
        return np.column_stack([raw.real, raw.imag]).astype(np.float64)
    if np.any(raw.imag != 0):
        raise CurveError(
            f"{name}: complex coordinates in an array of shape {raw.shape}; a complex curve "
            "is a 1-D array of points x + iy, and an (n, 2) array must hold real numbers"
        )
    return np.array(raw.real, dtype=np.float64)


def _as_xy(points: ArrayLike, name: str = "curve", *, closed: bool | None = None) -> np.ndarray:
    """Return ``points`` as a finite ``(n, 2)`` float64 array (a copy), or raise ``CurveError``.

    Accepts the forms of :data:`ACCEPTED_FORMS` (see :func:`as_curve`). Only the array itself
    is checked (shape, numbers, finiteness); duplicate points are kept. ``closed=False``
    refuses rings (a Polygon or LinearRing is a closed curve); ``None`` does not check.
    """
    arr, ring = _coerce(points, name)
    if ring and closed is False:
        raise CurveError(
            f"{name}: a Polygon or LinearRing is a closed curve, but an open one was asked "
            "for; use closed=True, or pass a LineString (or an array) for an open curve"
        )
    if arr.ndim != 2 or arr.shape[1] != 2:
        kind = f"{arr.ndim}-D array" if arr.ndim != 2 else "array"
        hint = ""
        if arr.ndim == 4 and arr.shape[2:] == (1, 2):
            hint = (
                "; this looks like a list of OpenCV contours: pass one of them "
                "(e.g. max(contours, key=cv2.contourArea))"
            )
        elif arr.ndim == 2 and arr.shape[0] == 2:
            hint = "; this looks like a row of x and a row of y: pass its transpose (points.T)"
        raise CurveError(
            f"{name}: expected {ACCEPTED_FORMS}; got a {kind} of shape {arr.shape}{hint}"
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


def as_curve(
    points: ArrayLike, *, closed: bool, name: str = "curve", min_points: int = 3
) -> np.ndarray:
    """Validate a curve and return it as a clean ``(n, 2)`` float64 copy.

    Every public function that takes a curve reads it with this function, so all of them
    accept the same inputs:

    * an ``(n, 2)`` array-like of ``(x, y)`` points (any real numeric dtype);
    * a 1-D complex array of points ``x + iy`` (an ``(n, 2)`` complex array is refused
      unless its imaginary parts are all zero, never silently dropped);
    * an OpenCV contour, the ``(n, 1, 2)`` integer arrays that ``cv2.findContours`` returns
      (one contour, not the list of them);
    * an object with a ``__geo_interface__`` (shapely geometries), or such a GeoJSON geometry
      dict: a ``Polygon`` gives its exterior ring (holes are ignored), a ``LinearRing`` its
      ring, a ``LineString`` its points; a ring's repeated closing point is dropped and a
      ``z`` coordinate is ignored. Rings are closed curves (``closed=False`` refuses them);
      multi-part geometries (``MultiPolygon``, ...) are refused.

    Consecutive duplicate points are dropped. For a closed curve a last point equal to the
    first one (an explicitly repeated endpoint) is dropped too, because closed curves are stored
    without repeating the first point.

    Parameters
    ----------
    points : array_like, shape (n, 2); OpenCV contour (n, 1, 2); or geometry
        The ``(x, y)`` points of the curve, in any length unit (pixels for image curves).
    closed : bool
        Whether the curve is closed (the last point connects back to the first one).
    name : str, optional
        What to call the curve in error messages (e.g. a file name).
    min_points : int, optional
        The fewest distinct points accepted, 3 by default (what matching and shape-trees
        need); open curves may ask for 2 (a straight segment, as contour tracing produces).

    Returns
    -------
    numpy.ndarray, shape (m, 2), float64
        The validated points, ``m <= n``; a new array, never a view of ``points``.

    Raises
    ------
    CurveError
        If the input is none of the forms above (1-D, 3 columns, empty, not numeric, a
        multi-part geometry), contains NaN or inf (the message names the row), has zero
        length, has fewer than ``min_points`` distinct points, or is closed with every
        point on one straight line (it encloses no area).
    """
    if (
        isinstance(min_points, bool)
        or not isinstance(min_points, numbers.Integral)
        or min_points < (3 if closed else 2)
    ):
        raise CurveError(
            f"{name}: min_points must be an integer >= {3 if closed else 2} for "
            f"{'a closed' if closed else 'an open'} curve, got {min_points!r}"
        )
    arr = _as_xy(points, name, closed=closed)
    if arr.shape[0] > 1:
        keep = np.ones(arr.shape[0], dtype=bool)
        keep[1:] = np.any(arr[1:] != arr[:-1], axis=1)
        arr = arr[keep]
    if closed:
        while arr.shape[0] > 1 and np.array_equal(arr[-1], arr[0]):
            arr = arr[:-1]
    # the distinct points, counted as complex numbers x + iy (5x faster than unique rows)
    n_distinct = np.unique(np.ascontiguousarray(arr).view(np.complex128)).size
    if n_distinct == 1:
        raise CurveError(f"{name}: the curve has zero length (all its points are identical)")
    if n_distinct < min_points:
        raise CurveError(
            f"{name}: the curve has fewer than {min_points} distinct points ({n_distinct}); "
            f"a curve needs at least {min_points}"
        )
    if closed:
        sv = np.linalg.svd(arr - arr.mean(axis=0), compute_uv=False)
        if sv[1] <= 1e-12 * sv[0]:
            raise CurveError(
                f"{name}: all the points of this closed curve lie on one straight line, so it "
                "encloses no area; pass it as an open curve (closed=False) if it is a line"
            )
    return arr


def curve_length(points: ArrayLike, *, closed: bool) -> float:
    """Total length of a polygonal curve.

    Parameters
    ----------
    points : array_like, shape (n, 2)
        The ``(x, y)`` points, or any other form :func:`as_curve` accepts.
    closed : bool
        If true, the closing segment from the last point back to the first one is included.

    Returns
    -------
    float
        The sum of the segment lengths, in the units of the coordinates.
    """
    arr = _as_xy(points, closed=closed)
    if closed:
        arr = np.vstack([arr, arr[:1]])
    return float(np.sum(np.hypot(*np.diff(arr, axis=0).T)))


def signed_area(points: ArrayLike) -> float:
    """Signed area enclosed by a closed polygon (shoelace formula, coordinates as given).

    Parameters
    ----------
    points : array_like, shape (n, 2)
        The ``(x, y)`` vertices (or any other form :func:`as_curve` accepts); the polygon is
        closed implicitly (last point to first).

    Returns
    -------
    float
        Positive if the vertices run counter-clockwise in a y-up frame, negative if clockwise, in
        squared coordinate units. For image curves (``x`` = column, ``y`` = row, y pointing down) a
        positive area means the curve looks *clockwise* on screen.
    """
    arr = _as_xy(points, closed=True)
    x, y = arr[:, 0], arr[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def orient(points: ArrayLike, orientation: str | None = "ccw") -> np.ndarray:
    """Return a closed curve with the requested orientation.

    Parameters
    ----------
    points : array_like, shape (n, 2)
        The ``(x, y)`` points of a closed curve (without a repeated endpoint), or any other
        form :func:`as_curve` accepts.
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
    arr = _as_xy(points, closed=True)
    if orientation is None or orientation == "keep":
        return arr
    area = signed_area(arr)
    if (orientation == "ccw" and area < 0) or (orientation == "cw" and area > 0):
        arr = np.concatenate([arr[:1], arr[:0:-1]])
    return arr
