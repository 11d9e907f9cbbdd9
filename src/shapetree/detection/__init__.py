"""Matching a deformable model to cluttered images (paper §4).

Stages: a soft edge map (:func:`edge_map`, or a stored Pb map via :func:`load_edges`),
contour tracing (:func:`trace_contours`), contour-vs-model tables of §3
(:func:`contour_tables`), the stitching DP with gaps (:func:`detect`, or
:func:`detect_detailed` to keep the edge map and contours), and the verification of
each kept detection by the shape-context agreement of its placed outline
(:func:`context_agreement`). Over a collection of photos, all detections are ranked
together by the collection re-scorer (:func:`rescore_collection`, :data:`RESCORER_WEIGHTS`,
:func:`detection_terms`), whose terms include the colour agreement of each with the most
confident ones of the other photos (:func:`appearance_agreement`; or that agreement alone,
:func:`collection_scores`). Models come from outline
drawings, point files or arrays (:func:`load_model`, :func:`make_model`). The ETHZ Shape
Classes protocol is :func:`evaluate_ethz` (DR against FPPI, :func:`dr_fppi_curve`).
Pictures are drawn by :func:`shapetree.plotting.plot_detections`.
"""

from shapetree.detection._appearance import (
    appearance_agreement,
    collection_scores,
    colour_bins,
    interior_histogram,
)
from shapetree.detection._contours import trace_contours
from shapetree.detection._detect import (
    Detection,
    DetectionRun,
    DetectParams,
    detect,
    detect_detailed,
)
from shapetree.detection._edges import edge_map, load_edges, load_image
from shapetree.detection._ethz_eval import dr_at_fppi, dr_fppi_curve, evaluate_ethz
from shapetree.detection._files import detect_to_files
from shapetree.detection._model import (
    DetectionModel,
    load_model,
    make_model,
    outline_from_image,
)
from shapetree.detection._rescore import RESCORER_WEIGHTS, detection_terms, rescore_collection
from shapetree.detection._tables import contour_tables
from shapetree.detection._verify import context_agreement, shape_contexts

__all__ = [
    "DetectParams",
    "Detection",
    "DetectionModel",
    "DetectionRun",
    "RESCORER_WEIGHTS",
    "appearance_agreement",
    "collection_scores",
    "colour_bins",
    "context_agreement",
    "contour_tables",
    "detect",
    "detect_detailed",
    "detect_to_files",
    "detection_terms",
    "dr_at_fppi",
    "dr_fppi_curve",
    "edge_map",
    "evaluate_ethz",
    "interior_histogram",
    "load_edges",
    "load_image",
    "load_model",
    "make_model",
    "outline_from_image",
    "rescore_collection",
    "shape_contexts",
    "trace_contours",
]
