"""Matching a deformable model to cluttered images (paper §4).

Stages: a soft edge map (:func:`edge_map`, or a stored Pb map via
:func:`load_edges`), contour tracing (:func:`trace_contours`), contour-vs-model
tables of §3 (:func:`contour_tables`), and the stitching DP with gaps
(:func:`detect`).
"""

from shapetree.detection._contours import trace_contours
from shapetree.detection._detect import (
    Detection,
    DetectionRun,
    DetectParams,
    detect,
    detect_detailed,
    outline_dif,
)
from shapetree.detection._edges import edge_map, load_edges, load_image
from shapetree.detection._ethz_eval import (
    ETHZ_CLASSES,
    dr_at_fppi,
    dr_fppi_curve,
    evaluate_ethz,
    recall_any,
)
from shapetree.detection._files import detect_to_files
from shapetree.detection._model import (
    DetectionModel,
    chain_strokes,
    load_model,
    make_model,
    outline_from_image,
    outline_strokes,
)
from shapetree.detection._tables import contour_tables

__all__ = [
    "DetectParams",
    "Detection",
    "DetectionModel",
    "DetectionRun",
    "ETHZ_CLASSES",
    "chain_strokes",
    "detect_to_files",
    "dr_at_fppi",
    "dr_fppi_curve",
    "evaluate_ethz",
    "recall_any",
    "contour_tables",
    "detect",
    "detect_detailed",
    "edge_map",
    "load_edges",
    "load_image",
    "load_model",
    "make_model",
    "outline_dif",
    "outline_from_image",
    "outline_strokes",
    "trace_contours",
]
