"""Pictures of retrieval results: nearest shapes per query, bull's-eye per class, a search.

The public functions return a :class:`matplotlib.figure.Figure` (saved atomically when
``path`` is given), like the rest of :mod:`shapetree.plotting`. The ``save_*`` functions
are the file-writing forms used by :func:`shapetree.retrieval.evaluate` and ``shapetree
search``: same pictures, the output path is required and returned.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from numpy.typing import ArrayLike

from shapetree.curves._validate import _as_xy
from shapetree.plotting._save import check_figure_path, new_figure, save_figure

__all__ = [
    "plot_bullseye_per_class",
    "plot_retrieval_grid",
    "save_bullseye_per_class",
    "save_retrieval_grid",
    "save_search",
]

PathArg = str | os.PathLike[str]


def _draw(ax: Axes, curve: np.ndarray, colour: str, invert_y: bool = True) -> None:
    """One closed curve (already read with ``_as_xy``), filled."""
    c = np.vstack([curve, curve[:1]])
    ax.fill(c[:, 0], c[:, 1], color=colour, alpha=0.25, lw=0)
    ax.plot(c[:, 0], c[:, 1], color=colour, lw=1.2)
    ax.set_aspect("equal")
    if invert_y:
        ax.invert_yaxis()  # image coordinates: y points down
    ax.set_xticks([])
    ax.set_yticks([])


def _finish(fig: Figure, path: PathArg | None, dpi: float) -> Figure:
    if path is not None:
        save_figure(fig, path, dpi=dpi)
    return fig


def plot_retrieval_grid(
    D: ArrayLike,
    labels: ArrayLike,
    curves: Sequence[ArrayLike],
    *,
    path: PathArg | None = None,
    queries: Sequence[int] | None = None,
    n_top: int = 10,
    title: str = "",
    invert_y: bool = True,
    dpi: float = 90,
) -> Figure:
    """Queries (first column) with their nearest shapes; wrong-class matches in red.

    Parameters
    ----------
    D : array_like, shape (n, n)
        Distance matrix (row = query), e.g. from :func:`shapetree.retrieval.distance_matrix`.
    labels : array_like, shape (n,)
        Class of each shape.
    curves : sequence of array_like, each shape (k, 2)
        The shapes (closed curves), in the order of ``D``; each may also be any other form
        :func:`shapetree.curves.as_curve` accepts (an OpenCV contour ``(k, 1, 2)``, a
        shapely ``Polygon``: its exterior, ...).
    path : path-like, optional
        Save the figure there (atomically, see :func:`save_figure`).
    queries : sequence of int, optional
        Rows to show; default one query per class (the one with most wrong matches), at
        most 12.
    n_top : int, default 10
        Matches shown per query (the query itself excluded).
    title : str
    invert_y : bool, default True
        ``y`` points down (curves traced from images, as :func:`shapetree.datasets.load`
        gives them).
    dpi : float, default 90

    Returns
    -------
    matplotlib.figure.Figure
        ``len(queries) * (n_top + 1)`` axes, row-major.

    Raises
    ------
    CurveError
        If a shape drawn is none of the accepted forms (the message names ``curves[i]``).
    """
    from shapetree.retrieval._protocols import ranked_neighbours

    if path is not None:
        check_figure_path(path)
    lab = np.asarray(labels)
    order = ranked_neighbours(D, exclude_self=True)[:, :n_top]
    n_top = order.shape[1]
    wrong = (lab[order] != lab[:, None]).sum(axis=1)
    if queries is None:
        queries = []
        for c in sorted(set(lab.tolist())):
            idx = np.flatnonzero(lab == c)
            queries.append(int(idx[np.argmax(wrong[idx])]))
        queries = queries[:12]
    nq = len(queries)
    fig = new_figure(1.1 * (n_top + 1), 1.15 * nq + (0.3 if title else 0.0))
    axes = fig.subplots(nq, n_top + 1, squeeze=False)
    read: dict[int, np.ndarray] = {}

    def curve(i: int) -> np.ndarray:
        if i not in read:
            read[i] = _as_xy(curves[i], f"plot_retrieval_grid curves[{i}]", closed=True)
        return read[i]

    for r, q in enumerate(queries):
        _draw(axes[r, 0], curve(q), "black", invert_y)
        axes[r, 0].set_ylabel(str(lab[q])[:12], fontsize=7)
        for k in range(n_top):
            j = order[q, k]
            ok = lab[j] == lab[q]
            ax = axes[r, k + 1]
            _draw(ax, curve(int(j)), "tab:blue" if ok else "red", invert_y)
            if not ok:
                for s in ax.spines.values():
                    s.set_color("red")
                    s.set_linewidth(2)
            if r == 0:
                ax.set_title(str(k + 1), fontsize=8)
    axes[0, 0].set_title("query", fontsize=8)
    if title:
        fig.suptitle(title, fontsize=10)
    return _finish(fig, path, dpi)


def plot_bullseye_per_class(
    per_class: dict[str, float],
    *,
    path: PathArg | None = None,
    overall: float | None = None,
    title: str = "Bull's-eye per class",
    second: dict[str, float] | None = None,
    labels: tuple[str, str] = ("pairwise", "re-ranked"),
    second_overall: float | None = None,
    dpi: float = 100,
) -> Figure:
    """Horizontal bar chart of per-class bull's-eye scores (sorted, worst at the bottom).

    Parameters
    ----------
    per_class : dict
        ``{class: percentage}`` from :func:`shapetree.retrieval.bullseye_per_class`.
    path : path-like, optional
        Save the figure there (atomically).
    overall : float, optional
        Drawn as a vertical line.
    title : str
    second : dict, optional
        A second score per class (e.g. after re-ranking), drawn as dots on the bars.
    labels : (str, str)
        Legend names of ``per_class`` and ``second``.
    second_overall : float, optional
        Overall value of ``second``, drawn as a dotted line.
    dpi : float, default 100

    Returns
    -------
    matplotlib.figure.Figure
        One axes.
    """
    if path is not None:
        check_figure_path(path)
    items = sorted(per_class.items(), key=lambda kv: kv[1])
    names = [k for k, _ in items]
    vals = np.array([v for _, v in items])
    fig = new_figure(7, max(3.0, 0.16 * len(items) + 1))
    ax = fig.add_subplot()
    colours = ["red" if v < 70 else "tab:orange" if v < 90 else "tab:blue" for v in vals]
    ax.barh(np.arange(len(vals)), vals, color=colours, label=labels[0] if second else None)
    if second:
        ax.plot([second[k] for k in names], np.arange(len(vals)), "k.", ms=4, label=labels[1])
    ax.set_yticks(np.arange(len(vals)), names, fontsize=6)
    ax.set_xlim(0, 100)
    ax.set_xlabel("bull's-eye (%)")
    if overall is not None:
        ax.axvline(overall, color="black", ls="--", lw=1, label=f"all: {overall:.2f}%")
    if second_overall is not None:
        ax.axvline(
            second_overall,
            color="black",
            ls=":",
            lw=1,
            label=f"all, {labels[1]}: {second_overall:.2f}%",
        )
    if overall is not None or second:
        ax.legend(loc="lower right", fontsize=8)
    ax.set_title(title, fontsize=10)
    return _finish(fig, path, dpi)


def _search_figure(
    query: ArrayLike,
    matches: Sequence[ArrayLike],
    captions: Sequence[str],
    *,
    title: str = "",
    per_row: int = 6,
) -> Figure:
    """A query outline and its nearest shapes in rank order, with captions (y down)."""
    q = _as_xy(query, "search query", closed=True)
    shapes = [_as_xy(c, f"search match #{i}", closed=True) for i, c in enumerate(matches, 1)]
    n = len(matches) + 1
    cols = min(per_row, n)
    rows = -(-n // cols)
    fig = new_figure(1.7 * cols, 1.9 * rows + (0.3 if title else 0.0))
    axes = fig.subplots(rows, cols, squeeze=False)
    for ax in axes.ravel():
        ax.axis("off")
    _draw(axes[0, 0], q, "black")
    axes[0, 0].axis("on")
    axes[0, 0].set_title("query", fontsize=8)
    for i, (curve, cap) in enumerate(zip(shapes, captions), start=1):
        ax = axes[i // cols, i % cols]
        _draw(ax, curve, "tab:blue")
        ax.axis("on")
        ax.set_title(f"{i}. {cap}", fontsize=7)
    if title:
        fig.suptitle(title, fontsize=10)
    return fig


# ---------------------------------------------------------------- file-writing forms


def save_retrieval_grid(
    D: ArrayLike, labels: ArrayLike, curves: Sequence[ArrayLike], path: PathArg, **kwargs: Any
) -> Path:
    """:func:`plot_retrieval_grid` written to ``path``; returns ``path``."""
    plot_retrieval_grid(D, labels, curves, path=path, **kwargs)
    return Path(path)


def save_bullseye_per_class(per_class: dict[str, float], path: PathArg, **kwargs: Any) -> Path:
    """:func:`plot_bullseye_per_class` written to ``path``; returns ``path``."""
    plot_bullseye_per_class(per_class, path=path, **kwargs)
    return Path(path)


def save_search(
    query: ArrayLike,
    matches: Sequence[ArrayLike],
    captions: Sequence[str],
    path: PathArg,
    *,
    title: str = "",
    per_row: int = 6,
    dpi: float = 100,
) -> Path:
    """The ``shapetree search --plot`` picture: the query, then its nearest shapes.

    Parameters
    ----------
    query : array_like, shape (n, 2)
        Closed curve in image coordinates (y down), or any other form
        :func:`shapetree.curves.as_curve` accepts (OpenCV contour, shapely ``Polygon``, ...).
    matches : sequence of array_like, each shape (k, 2)
        The nearest shapes, best first (same forms as ``query``).
    captions : sequence of str
        One per match (e.g. name and distance).
    path : path-like
        Output picture (written atomically).
    title : str
    per_row : int
        Panels per row (the query takes the first panel).
    dpi : float, default 100

    Returns
    -------
    pathlib.Path
    """
    check_figure_path(path)
    fig = _search_figure(query, matches, captions, title=title, per_row=per_row)
    return save_figure(fig, path, dpi=dpi)
