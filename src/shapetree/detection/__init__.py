"""Matching a deformable model to cluttered images (paper §4).

Stages: a soft edge map (:func:`edge_map`, or a stored Pb map via
:func:`load_edges`), contour tracing (:func:`trace_contours`), contour-vs-model
tables of §3 (:func:`contour_tables`), and the stitching DP with gaps
(:func:`detect`).
"""

from shapetree.detection._contours import resample_polyline, trace_contours
from shapetree.detection._detect import (
    Detection,
    DetectionRun,
    DetectParams,
    detect,
    detect_detailed,
)
from shapetree.detection._edges import edge_map, load_edges, load_image
from shapetree.detection._model import DetectionModel, load_model, make_model, outline_from_image
from shapetree.detection._tables import contour_tables

__all__ = [
    "DetectParams",
    "Detection",
    "DetectionModel",
    "DetectionRun",
    "contour_tables",
    "detect",
    "detect_detailed",
    "edge_map",
    "load_edges",
    "load_image",
    "load_model",
    "make_model",
    "outline_from_image",
    "resample_polyline",
    "trace_contours",
]
