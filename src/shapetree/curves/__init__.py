"""Curves: validation, resampling, smoothing, orientation, point files and silhouettes from images.

A curve is an ``(n, 2)`` float64 array of ``(x, y)`` points. Closed curves are stored without
repeating the first point. Curves traced from images are in pixel coordinates with ``x`` the
column and ``y`` the row (y points down), so ``"ccw"`` (positive :func:`signed_area`) looks
clockwise on screen.

The functions here, matching, retrieval and shape-trees read their curves with :func:`as_curve`,
so they also accept OpenCV contours (the ``(n, 1, 2)`` integer arrays of ``cv2.findContours``)
and shapely geometries (a ``Polygon``'s exterior, a ``LinearRing``, a ``LineString``; anything
with a ``__geo_interface__``).
"""

from shapetree.curves._image import curve_from_image
from shapetree.curves._io import load_curve, load_points
from shapetree.curves._resample import point_at, resample, smooth
from shapetree.curves._validate import as_curve, curve_length, orient, signed_area

__all__ = [
    "as_curve",
    "curve_from_image",
    "curve_length",
    "load_curve",
    "load_points",
    "orient",
    "point_at",
    "resample",
    "signed_area",
    "smooth",
]
