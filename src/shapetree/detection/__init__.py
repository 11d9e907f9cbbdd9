"""Matching a deformable model to cluttered images (paper §4).

Stages: a soft edge map (:func:`edge_map`, or a stored Pb map via
:func:`load_edges`), contour tracing (:func:`trace_contours`), contour-vs-model
tables of §3 (:func:`contour_tables`), and the stitching DP with gaps
(:func:`detect`).
"""

from shapetree.detection._contours import resample_polyline, trace_contours
from shapetree.detection._edges import edge_map, load_edges, load_image

__all__ = [
    "edge_map",
    "load_edges",
    "load_image",
    "resample_polyline",
    "trace_contours",
]
