"""Pictures with matplotlib (Agg, no display): matches, shape-trees, deformations.

Figures are plain :class:`matplotlib.figure.Figure` objects not registered with pyplot, so
nothing ever opens a window; :func:`save_figure` writes atomically (temporary file, then
``os.replace``), so no half-written picture is ever left behind.
"""

from shapetree.plotting._draw import (
    merge_replaced,
    plot_curve,
    plot_deformations,
    plot_match,
    plot_ranking,
    plot_tree,
)
from shapetree.plotting._save import check_figure_path, new_figure, save_figure

__all__ = [
    "check_figure_path",
    "merge_replaced",
    "new_figure",
    "plot_curve",
    "plot_deformations",
    "plot_match",
    "plot_ranking",
    "plot_tree",
    "save_figure",
]
