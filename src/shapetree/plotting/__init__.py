"""Pictures with matplotlib (Agg, no display): every picture shapetree draws is drawn here.

Matches, shape-trees and deformations (paper Fig. 3 and 4), retrieval results, detections
(Fig. 5). Figures are plain :class:`matplotlib.figure.Figure` objects not registered with
pyplot, so nothing ever opens a window; every ``plot_*`` function that makes a figure takes
``path=`` to save it, and :func:`save_figure` writes atomically (temporary file, then
``os.replace``), so no half-written picture is ever left behind.
"""

from shapetree.plotting._detection import plot_contours, plot_detections
from shapetree.plotting._draw import (
    plot_curve,
    plot_deformations,
    plot_match,
    plot_ranking,
    plot_tree,
)
from shapetree.plotting._retrieval import plot_bullseye_per_class, plot_retrieval_grid
from shapetree.plotting._save import save_figure

__all__ = [
    "plot_bullseye_per_class",
    "plot_contours",
    "plot_curve",
    "plot_deformations",
    "plot_detections",
    "plot_match",
    "plot_ranking",
    "plot_retrieval_grid",
    "plot_tree",
    "save_figure",
]
