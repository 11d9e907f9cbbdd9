"""Pictures of matches, shape-trees and deformations (paper Fig. 3 and 4)."""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from numpy.typing import ArrayLike

from shapetree._errors import ShapeTreeError
from shapetree.curves import point_at
from shapetree.curves._validate import _as_xy
from shapetree.plotting._save import check_figure_path, new_figure, save_figure

__all__ = [
    "merge_replaced",
    "plot_curve",
    "plot_deformations",
    "plot_match",
    "plot_ranking",
    "plot_tree",
]

CURVE_COLOR = "#222222"
FAINT_COLOR = "#c8c8c8"
COARSE_COLOR = "#1f5fa8"
MID_COLOR = "#d62728"
REPLACED_COLOR = "#e8590c"
DEFORM_COLOR = "#1f77b4"

PathArg = str | os.PathLike[str]


def _normalise(points: np.ndarray, invert_y: bool) -> np.ndarray:
    """Centre the bounding box at 0, larger side 1; flip ``y`` for image coordinates."""
    p = np.array(points, dtype=float)
    if invert_y:
        p[:, 1] = -p[:, 1]
    lo, hi = p.min(axis=0), p.max(axis=0)
    size = float(np.max(hi - lo)) or 1.0
    return (p - 0.5 * (lo + hi)) / size


def _closed_path(points: np.ndarray, closed: bool) -> np.ndarray:
    return np.vstack([points, points[:1]]) if closed else points


def _resolve_target(
    ax: Axes | PathArg | None, path: PathArg | None
) -> tuple[Axes | None, PathArg | None]:
    if isinstance(ax, str | os.PathLike):
        if path is not None:
            raise ShapeTreeError("give the output path once (either ax=path or path=...)")
        return None, ax
    return ax, path


def _finish(fig: Figure, path: PathArg | None, dpi: float) -> Figure:
    if path is not None:
        save_figure(fig, path, dpi=dpi)
    return fig


def _clean(ax: Axes) -> None:
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    for spine in ax.spines.values():
        spine.set_visible(False)


def plot_curve(
    points: ArrayLike,
    *,
    closed: bool = True,
    ax: Axes | None = None,
    invert_y: bool = False,
    color: str = CURVE_COLOR,
    **kwargs: object,
) -> Axes:
    """Draw one curve (normalised to a unit bounding box).

    Parameters
    ----------
    points : array_like, shape (n, 2)
        The ``(x, y)`` points, or any other form :func:`shapetree.curves.as_curve` accepts
        (an OpenCV contour ``(n, 1, 2)``, a shapely ``Polygon``/``LinearRing``: its
        exterior, ``LineString``); drawn as given (duplicate points are kept).
    closed : bool, default True
        ``False`` refuses rings (a ``Polygon`` or ``LinearRing`` is closed).
    ax : matplotlib Axes, optional
        Where to draw; default a new figure.
    invert_y : bool, default False
        Flip ``y`` (for image coordinates, where ``y`` points down).
    color : str
    **kwargs
        Passed to :meth:`matplotlib.axes.Axes.plot`.

    Returns
    -------
    matplotlib.axes.Axes

    Raises
    ------
    CurveError
        If ``points`` is none of the accepted forms (the message lists them), or holds NaN/inf.
    """
    pts = _as_xy(points, "plot_curve points", closed=closed)
    if ax is None:
        ax = new_figure(3, 3).add_subplot()
    p = _closed_path(_normalise(pts, invert_y), closed)
    ax.plot(p[:, 0], p[:, 1], color=color, **kwargs)
    _clean(ax)
    return ax


def _cyclic_range(i0: int, i1: int, n: int, closed: bool) -> np.ndarray:
    """Indices ``i0..i1`` inclusive, going forward (wrapping modulo ``n`` when closed)."""
    if not closed:
        return np.arange(min(i0, i1), max(i0, i1) + 1)
    length = (i1 - i0) % n or n
    return (i0 + np.arange(length + 1)) % n


def plot_match(
    result: object,
    ax: Axes | PathArg | None = None,
    *,
    path: PathArg | None = None,
    invert_y: bool | tuple[bool, bool] = False,
    max_lines: int = 40,
    labels: tuple[str, str] = ("A", "B"),
    title: str | None = None,
    cmap: str = "plasma",
    gap: float = 0.45,
    dpi: float = 150,
) -> Figure:
    """Draw a match: both shapes side by side, matched points joined by thin lines.

    ``A`` is drawn on the left and ``B`` on the right, each scaled to a unit bounding box.
    Lines join evenly spaced points of ``A`` (at most ``max_lines``) to their positions on
    ``B``, coloured by position along ``A``; the same colours mark the matched points on
    both curves. Parts replaced rather than deformed (occlusion, ``result.replaced``) are
    drawn thick in a distinct colour and labelled. The title gives the cost ψ(A, B).

    Parameters
    ----------
    result : MatchResult
        From :func:`shapetree.matching.match`.
    ax : matplotlib Axes or path-like, optional
        Axes to draw into; a path means "new figure saved there" (same as ``path=``).
    path : path-like, optional
        Save the figure there (atomically, see :func:`save_figure`).
    invert_y : bool or (bool, bool), default False
        Flip ``y`` (curves traced from images have ``y`` pointing down); a pair applies
        to ``A`` and ``B`` separately.
    max_lines : int, default 40
        Most correspondence lines drawn (a uniform subsample of the matched points).
    labels : (str, str), default ("A", "B")
        Names shown under the two shapes.
    title : str, optional
        Default: ``"ψ(A, B) = <cost>"`` plus the tree index and replaced parts.
    cmap : str, default "plasma"
        Colour map for the correspondences.
    gap : float, default 0.45
        Horizontal space between the shapes, in units of a shape's size.
    dpi : float, default 150

    Returns
    -------
    matplotlib.figure.Figure
    """
    ax, path = _resolve_target(ax, path)
    if path is not None:
        check_figure_path(path)
    if ax is None:
        fig = new_figure(8.0, 4.2)
        ax = fig.add_subplot()
    fig = ax.get_figure()
    closed = bool(result.closed)
    flip_a, flip_b = (invert_y, invert_y) if isinstance(invert_y, bool) else invert_y
    a = _normalise(result.a, bool(flip_a))
    b = _normalise(result.b, bool(flip_b))
    shift = np.array([1.0 + gap, 0.0])
    b = b + shift
    n, m = a.shape[0], b.shape[0]

    # faint full curves underneath, then the deformed parts on top
    for pts in (a, b):
        cp = _closed_path(pts, closed)
        ax.plot(cp[:, 0], cp[:, 1], color=CURVE_COLOR, lw=1.6, zorder=2, solid_joinstyle="round")

    colours = _colormap(cmap)
    # correspondence lines
    a_to_b = np.asarray(result.a_to_b, dtype=float)
    ok = np.flatnonzero(np.isfinite(a_to_b))
    if ok.size:
        k = min(int(max_lines), ok.size)
        pick = ok[np.unique(np.round(np.linspace(0, ok.size - 1, k)).astype(int))] if k else ok[:0]
        pb = point_at(b, a_to_b[pick], closed=closed)
        pa = a[pick]
        col = colours(pick / max(n - 1, 1))
        segs = np.stack([pa, pb], axis=1)
        ax.add_collection(LineCollection(segs, colors=col, linewidths=0.7, alpha=0.75, zorder=1))
        ax.scatter(pa[:, 0], pa[:, 1], s=14, c=col, zorder=4, edgecolors="none")
        ax.scatter(pb[:, 0], pb[:, 1], s=14, c=col, zorder=4, edgecolors="none")

    # replaced parts (adjacent ones merged for the picture)
    parts = merge_replaced(result.replaced, n, m, closed)
    for r, (a0, a1, b0, b1) in enumerate(parts, start=1):
        ia = _cyclic_range(int(a0), int(a1), n, closed)
        ib = _cyclic_range(int(b0), int(b1), m, closed)
        lab = "replaced (occlusion)" if r == 1 else None
        ax.plot(a[ia, 0], a[ia, 1], color=REPLACED_COLOR, lw=4, alpha=0.85, zorder=3, label=lab)
        ax.plot(b[ib, 0], b[ib, 1], color=REPLACED_COLOR, lw=4, alpha=0.85, zorder=3)
        for pts, idx in ((a, ia), (b, ib)):
            c = pts[idx[len(idx) // 2]]
            ax.annotate(
                f"R{r}",
                c,
                xytext=(4, 4),
                textcoords="offset points",
                color=REPLACED_COLOR,
                fontsize=9,
                fontweight="bold",
                zorder=5,
            )
    if parts:
        ax.legend(loc="lower center", frameon=False, fontsize=9, bbox_to_anchor=(0.5, -0.08))

    for centre, lab in ((0.0, labels[0]), (float(shift[0]), labels[1])):
        ax.text(centre, -0.62, lab, ha="center", va="top", fontsize=11, color="#444444")
    if title is None:
        title = f"ψ({labels[0]}, {labels[1]}) = {result.cost:.4g}"
        costs = np.asarray(getattr(result, "costs", np.zeros(0)))
        if costs.size > 1:
            title += f"   (drawn with shape-tree #{result.tree_index} of {costs.size})"
        if parts:
            title += f"   ({len(parts)} part{'s' if len(parts) > 1 else ''} replaced)"
    ax.set_title(title, fontsize=12)
    ax.set_xlim(-0.6, 0.6 + float(shift[0]))
    ax.set_ylim(-0.72, 0.58)
    _clean(ax)
    return _finish(fig, path, dpi)


def merge_replaced(
    replaced: Sequence[tuple[int, int, int, int]], n: int, m: int, closed: bool
) -> list[tuple[int, int, int, int]]:
    """Join replaced parts that follow each other on both curves.

    Parameters
    ----------
    replaced : sequence of (a_start, a_end, b_start, b_end)
        ``MatchResult.replaced``.
    n, m : int
        Numbers of points of ``A`` and ``B``.
    closed : bool

    Returns
    -------
    list of (a_start, a_end, b_start, b_end)
        Maximal runs of consecutive parts (``a_end == next a_start`` and
        ``b_end == next b_start``, modulo ``n``/``m`` when closed), in order along ``A``.
    """
    parts = sorted((int(a0), int(a1), int(b0), int(b1)) for a0, a1, b0, b1 in replaced)
    out: list[list[int]] = []
    for a0, a1, b0, b1 in parts:
        if out and out[-1][1] == a0 and out[-1][3] == b0:
            out[-1][1], out[-1][3] = a1, b1
        else:
            out.append([a0, a1, b0, b1])
    if closed and len(out) > 1 and out[-1][1] % n == out[0][0] and out[-1][3] % m == out[0][2]:
        last = out.pop()
        out[0][0], out[0][2] = last[0], last[2]
    return [tuple(p) for p in out]  # type: ignore[misc]


def _colormap(name: str):
    import matplotlib

    try:
        cm = matplotlib.colormaps[name]
    except KeyError:
        raise ShapeTreeError(f"unknown colour map {name!r}") from None
    # keep away from the palest end so lines stay visible on white
    return lambda t: cm(0.05 + 0.8 * np.asarray(t, dtype=float))


def _check_tree(tree: object, func: str) -> None:
    """Refuse anything but a ShapeTree, pointing raw curves to ``build_shape_tree``."""
    from shapetree.tree import ShapeTree

    if not isinstance(tree, ShapeTree):
        raise ShapeTreeError(
            f"{func} draws shape-trees, got {type(tree).__name__}; build one from the curve "
            "(an (n, 2) array, an OpenCV contour, a shapely Polygon, ...) with "
            "shapetree.tree.build_shape_tree(points, closed=...)"
        )


def _grid(k: int, ncols: int | None) -> tuple[int, int]:
    cols = ncols or (k if k <= 4 else (3 if k <= 6 else 4))
    cols = max(1, min(cols, k))
    return (k + cols - 1) // cols, cols


def plot_tree(
    tree: object,
    *,
    path: PathArg | None = None,
    max_levels: int | None = None,
    ncols: int | None = None,
    invert_y: bool = False,
    panel_size: float = 2.6,
    title: str | None = None,
    dpi: float = 150,
) -> Figure:
    """Draw a shape-tree level by level (paper Fig. 3).

    One panel per depth ``d``: the faint curve, the coarse polygon through the points known
    at that level (the anchors and the midpoints of all shallower nodes: filled circles),
    and the midpoints of the depth-``d`` nodes (open circles), each joined by dashed lines
    to the two endpoints of its subcurve.

    Parameters
    ----------
    tree : ShapeTree
        From :func:`shapetree.tree.build_shape_tree` (which reads the curve in any form
        :func:`shapetree.curves.as_curve` accepts: OpenCV contours, shapely polygons, ...).
    path : path-like, optional
        Save the figure there (atomically).
    max_levels : int, optional
        Draw only the first ``max_levels`` depths (default: all).
    ncols : int, optional
        Panels per row (default: up to 4 for 4 panels or fewer, else 3 or 4).
    invert_y : bool, default False
        Flip ``y`` (image coordinates).
    panel_size : float, default 2.6
        Size of one panel in inches.
    title : str, optional
        Figure title (default: number of points and nodes).
    dpi : float, default 150

    Returns
    -------
    matplotlib.figure.Figure
        With one axes per drawn depth (``fig.axes``; unused grid cells are removed).

    Raises
    ------
    ShapeTreeError
        If ``tree`` is not a ShapeTree (e.g. raw points: build the tree first), or
        ``max_levels < 1``.
    """
    _check_tree(tree, "plot_tree")
    if path is not None:
        check_figure_path(path)
    levels = tree.levels() if tree.n_nodes else []
    if max_levels is not None:
        if max_levels < 1:
            raise ShapeTreeError(f"max_levels must be >= 1, got {max_levels}")
        levels = levels[:max_levels]
    if not levels:
        raise ShapeTreeError("the shape-tree has no nodes to draw (fewer than 3 points)")
    u = _normalise(tree.unrolled, invert_y)
    rows, cols = _grid(len(levels), ncols)
    fig = new_figure(panel_size * cols, panel_size * rows + 0.5)
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    known = {0, int(tree.split_index)}
    if tree.closed:
        known.add(tree.n_points)  # the repeated first point closes the polygon
    else:
        known.add(tree.n_points - 1)
    curve = _closed_path(u[: tree.n_points], tree.closed)
    for d, nodes in enumerate(levels):
        ax = axes[d]
        ax.plot(curve[:, 0], curve[:, 1], color=FAINT_COLOR, lw=1.0, zorder=1)
        idx = np.array(sorted(known))
        ax.plot(u[idx, 0], u[idx, 1], color=COARSE_COLOR, lw=1.5, zorder=2)
        for v in nodes:
            s, i, e = int(tree.start[v]), int(tree.mid[v]), int(tree.end[v])
            ax.plot(u[[s, i, e], 0], u[[s, i, e], 1], color=MID_COLOR, lw=0.8, ls="--", zorder=2)
        ax.scatter(u[idx, 0], u[idx, 1], s=16, color=COARSE_COLOR, zorder=3)
        mids = tree.mid[nodes]
        ax.scatter(
            u[mids, 0],
            u[mids, 1],
            s=22,
            facecolors="white",
            edgecolors=MID_COLOR,
            lw=1.1,
            zorder=4,
        )
        ax.set_title(
            f"depth {d}: {len(nodes)} midpoint{'s' if len(nodes) != 1 else ''}", fontsize=10
        )
        _clean(ax)
        known.update(int(i) for i in mids)
    for ax in axes[len(levels) :]:
        ax.remove()
    if title is None:
        kind = "closed" if tree.closed else "open"
        title = (
            f"shape-tree of a {kind} curve: {tree.n_points} points, {tree.n_nodes} nodes, "
            f"split={tree.split!r}"
        )
    if title:
        fig.suptitle(title, fontsize=11)
    return _finish(fig, path, dpi)


def plot_deformations(
    tree: object | Sequence[object],
    scales: float | ArrayLike | Sequence[float | ArrayLike] = (0.05, 0.1, 0.2),
    n: int = 5,
    rng: np.random.Generator | int | None = None,
    *,
    path: PathArg | None = None,
    names: Sequence[str] | None = None,
    invert_y: bool | Sequence[bool] = False,
    panel_size: float = 1.5,
    title: str | None = None,
    dpi: float = 150,
) -> Figure:
    """A gallery of random deformations (paper Fig. 4).

    One row per shape-tree and scale: the original curve, then ``n`` curves reconstructed
    after adding independent Gaussian noise to every node's Bookstein coordinate
    (:func:`shapetree.tree.deform`).

    Parameters
    ----------
    tree : ShapeTree or sequence of ShapeTree
        From :func:`shapetree.tree.build_shape_tree` (which reads the curve in any form
        :func:`shapetree.curves.as_curve` accepts: OpenCV contours, shapely polygons, ...).
    scales : float, array_like, or sequence of them, default (0.05, 0.1, 0.2)
        Noise standard deviation(s) in Bookstein units. A float or a 1-D per-depth array is
        one scale; a list gives one row per scale (per tree).
    n : int, default 5
        Deformations per row.
    rng : numpy Generator or int seed, optional
    path : path-like, optional
        Save the figure there (atomically).
    names : sequence of str, optional
        One name per tree, shown in the row labels.
    invert_y : bool or sequence of bool, default False
        Flip ``y`` (image coordinates); a sequence gives one flag per tree.
    panel_size : float, default 1.5
        Size of one panel in inches.
    title : str, optional
    dpi : float, default 150

    Returns
    -------
    matplotlib.figure.Figure
        ``rows * (n + 1)`` axes, row-major.

    Raises
    ------
    ShapeTreeError
        If ``tree`` is not a ShapeTree or a sequence of them (e.g. raw points: build the
        trees first), or for bad ``n``, ``names`` or ``invert_y``.
    """
    from shapetree.tree import ShapeTree, deform

    if path is not None:
        check_figure_path(path)
    if isinstance(tree, ShapeTree | np.ndarray | str) or hasattr(tree, "__geo_interface__"):
        trees = [tree]  # raw points are refused just below, with a pointer to build_shape_tree
    else:
        try:
            trees = list(tree)
        except TypeError:
            trees = [tree]
    if not trees:
        raise ShapeTreeError("plot_deformations needs at least one shape-tree")
    for t in trees:
        _check_tree(t, "plot_deformations")
    if np.ndim(scales) == 0 or (
        isinstance(scales, np.ndarray) and scales.ndim == 1 and scales.dtype != object
    ):
        scale_list = [scales]
    else:
        scale_list = list(scales)
    if n < 1:
        raise ShapeTreeError(f"number of deformations must be >= 1, got {n}")
    flips = [invert_y] * len(trees) if isinstance(invert_y, bool) else list(invert_y)
    labels = list(names) if names is not None else [""] * len(trees)
    if len(flips) != len(trees) or len(labels) != len(trees):
        raise ShapeTreeError("names and invert_y need one entry per shape-tree")
    gen = np.random.default_rng(rng)
    rows = [(i, t, s) for i, t in enumerate(trees) for s in scale_list]
    fig = new_figure(panel_size * (n + 1) + 0.6, panel_size * len(rows) + 0.5)
    axes = fig.subplots(len(rows), n + 1, squeeze=False)
    for r, (i, t, s) in enumerate(rows):
        curves = [t.points] + [deform(t, s, rng=gen) for _ in range(n)]
        for c, pts in enumerate(curves):
            ax = axes[r, c]
            p = _closed_path(_normalise(pts, bool(flips[i])), t.closed)
            colour = CURVE_COLOR if c == 0 else DEFORM_COLOR
            ax.fill(p[:, 0], p[:, 1], color=colour, alpha=0.08 if c else 0.12, lw=0)
            ax.plot(p[:, 0], p[:, 1], color=colour, lw=1.3)
            ax.set_xlim(-0.62, 0.62)
            ax.set_ylim(-0.62, 0.62)
            _clean(ax)
        label = "σ = " + (
            f"{float(s):g}" if np.ndim(s) == 0 else ", ".join(f"{v:g}" for v in np.ravel(s))
        )
        if labels[i]:
            label = f"{labels[i]}\n{label}"
        axes[r, 0].set_ylabel(label, fontsize=9)
        if r == 0:
            axes[r, 0].set_title("original", fontsize=9)
            for c in range(1, n + 1):
                axes[r, c].set_title(f"deformed #{c}", fontsize=9)
    if title is None:
        title = "random deformations: Gaussian noise on every node's Bookstein coordinates"
    if title:
        fig.suptitle(title, fontsize=10)
    return _finish(fig, path, dpi)


def plot_ranking(
    query: ArrayLike,
    candidates: Sequence[tuple],
    *,
    path: PathArg | None = None,
    query_label: str = "query",
    ncols: int = 6,
    closed: bool = True,
    invert_y: bool = False,
    panel_size: float = 1.6,
    title: str | None = None,
    dpi: float = 150,
) -> Figure:
    """A retrieval gallery: the query, then the candidates in ranked order with their costs.

    Parameters
    ----------
    query : array_like, shape (n, 2)
        The query curve, or any other form :func:`shapetree.curves.as_curve` accepts (an
        OpenCV contour ``(n, 1, 2)``, a shapely ``Polygon``: its exterior, ...).
    candidates : sequence of (label, points, cost) or (label, points, cost, highlight)
        In rank order (best first); ``points`` in any form ``query`` may take. Highlighted
        candidates (e.g. the true matches) are drawn in green, the others in grey-blue.
    path : path-like, optional
        Save the figure there (atomically).
    query_label : str, default "query"
    ncols : int, default 6
        Panels per row.
    closed : bool, default True
    invert_y : bool, default False
    panel_size : float, default 1.6
    title : str, optional
    dpi : float, default 150

    Returns
    -------
    matplotlib.figure.Figure
        ``1 + len(candidates)`` axes.

    Raises
    ------
    CurveError
        If the query or a candidate's points are none of the accepted forms (the message
        names the curve and lists the forms).
    ShapeTreeError
        If a candidate is not a ``(label, points, cost[, highlight])`` tuple.
    """
    if path is not None:
        check_figure_path(path)
    entries = [(query_label, _as_xy(query, "plot_ranking query", closed=closed), None, None)]
    for r, c in enumerate(candidates, start=1):
        if not isinstance(c, Sequence) or isinstance(c, str) or len(c) not in (3, 4):
            raise ShapeTreeError(
                f"plot_ranking: candidate #{r} must be a (label, points, cost) or "
                f"(label, points, cost, highlight) tuple, got {type(c).__name__}"
            )
        pts = _as_xy(c[1], f"plot_ranking candidate #{r} ({c[0]})", closed=closed)
        entries.append((c[0], pts, c[2], c[3] if len(c) > 3 else False))
    k = len(entries)
    rows, cols = _grid(k, ncols)
    fig = new_figure(panel_size * cols, panel_size * rows + 0.45)
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    for r, (label, pts, cost, hi) in enumerate(entries):
        ax = axes[r]
        p = _closed_path(_normalise(pts, invert_y), closed)
        if cost is None:
            colour, head = CURVE_COLOR, label
        else:
            colour = "#2b8a3e" if hi else "#5c6f82"
            head = f"#{r} {label}\n{cost:.3g}"
        ax.fill(p[:, 0], p[:, 1], color=colour, alpha=0.12, lw=0)
        ax.plot(p[:, 0], p[:, 1], color=colour, lw=1.4 if cost is None or hi else 1.0)
        ax.set_title(head, fontsize=9, color=colour, fontweight="bold" if hi else "normal")
        ax.set_xlim(-0.6, 0.6)
        ax.set_ylim(-0.6, 0.6)
        _clean(ax)
        if cost is None:
            for spine in ax.spines.values():
                spine.set_visible(True)
                spine.set_color("#999999")
    for ax in axes[k:]:
        ax.remove()
    if title is None:
        title = "candidates ranked by matching cost ψ(query, candidate), lowest first"
    if title:
        fig.suptitle(title, fontsize=10)
    return _finish(fig, path, dpi)
