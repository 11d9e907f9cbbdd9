"""Pictures of detection (paper Fig. 5): contours, detections, ETHZ curves and galleries."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from numpy.typing import ArrayLike, NDArray

from shapetree.plotting._save import check_figure_path, new_figure, save_figure

__all__ = ["plot_contours", "plot_detections", "save_ethz_figures"]

PathArg = str | os.PathLike[str]

#: Colours of the detections drawn, best first.
_COLOURS = ("r", "b", "g", "m", "c")


def _faded(image: ArrayLike) -> NDArray[np.float64]:
    img = np.asarray(image, dtype=float)
    return img * 0.5 + 0.5 if img.ndim == 3 else img


def plot_contours(
    contours: Sequence[ArrayLike],
    shape: tuple[int, int] | None = None,
    *,
    ax: Axes | None = None,
    seed: int = 0,
    endpoints: bool = True,
) -> Axes:
    """Draw traced contours, each in its own colour (paper Fig. 5(c)).

    Parameters
    ----------
    contours : sequence of array_like, each shape (n_i, 2)
        Polylines ``(x, y)`` in pixels, e.g. from :func:`shapetree.detection.trace_contours`,
        in any form the ``contours=`` of :func:`shapetree.detection.detect` accepts: also
        OpenCV contours ``(n_i, 1, 2)`` (the list ``cv2.findContours`` returns) and
        geometries (a ``LineString``, a shapely ``Polygon``: its exterior, a
        ``LinearRing``). Drawn as detection reads them: open polylines through the points,
        first to last (a closed boundary's closing segment is not drawn).
    shape : (H, W), optional
        Image size: sets the axes limits (``y`` down).
    ax : matplotlib Axes, optional
        Where to draw; default a new figure.
    seed : int, default 0
        Colour seed.
    endpoints : bool, default True
        Mark contour endpoints with black dots.

    Returns
    -------
    matplotlib.axes.Axes

    Raises
    ------
    ShapeTreeError
        If a contour is none of the accepted forms (a ``CurveError`` naming
        ``contours[i]``), or one contour is given in place of the list.
    """
    from shapetree.detection._detect import _as_contours

    polylines = _as_contours(contours)
    if ax is None:
        ax = new_figure(5, 4).add_subplot()
    rng = np.random.default_rng(seed)
    for c in polylines:
        ax.plot(c[:, 0], c[:, 1], "-", color=rng.uniform(0.1, 0.9, 3), lw=1.2)
        if endpoints:
            ax.plot(c[[0, -1], 0], c[[0, -1], 1], "k.", ms=2)
    if shape is not None:
        ax.set_xlim(0, shape[1])
        ax.set_ylim(shape[0], 0)
    elif not ax.yaxis_inverted():
        ax.invert_yaxis()
    ax.set_aspect("equal")
    return ax


def _draw_detection(
    det: Any,
    contours: Sequence[ArrayLike],
    ax: Axes,
    *,
    color: str = "r",
    label: str | None = None,
) -> None:
    """One detection: its matched contours, mapped model points (x: in a gap) and box
    (dashed; where the box was refined, the match's own box dotted inside it)."""
    for pc in det.pieces:
        c = np.asarray(contours[pc["contour"]], dtype=float)
        ax.plot(c[:, 0], c[:, 1], "-", color=color, lw=2.2)
    ip = np.asarray(det.image_points, dtype=float)
    matched = np.asarray(det.matched, dtype=bool)
    closed = np.vstack([ip, ip[:1]])
    ax.plot(closed[:, 0], closed[:, 1], ":", color=color, lw=0.8)
    ax.plot(ip[matched, 0], ip[matched, 1], ".", color=color, ms=4)
    ax.plot(ip[~matched, 0], ip[~matched, 1], "x", color=color, ms=4)
    match = getattr(det, "match_bbox", None)
    if match is not None:  # box_refine: the reported box is the widened template's
        m1, n1, m2, n2 = match
        ax.plot([m1, m2, m2, m1, m1], [n1, n1, n2, n2, n1], ":", color=color, lw=0.8)
    x1, y1, x2, y2 = det.bbox
    ax.plot([x1, x2, x2, x1, x1], [y1, y1, y2, y2, y1], "--", color=color, lw=1)
    text = label if label is not None else f"{det.cost:.3f}"
    if text:
        ax.text(x1, y1, text, color=color, fontsize=7)


def plot_detections(
    run: Any,
    image: ArrayLike | None = None,
    *,
    n_show: int = 3,
    title: str | None = None,
    path: PathArg | None = None,
    dpi: float = 90,
) -> Figure:
    """Fig. 5-style picture of a detection run: image, soft edges, contours, detections.

    Parameters
    ----------
    run : DetectionRun
        From :func:`shapetree.detection.detect_detailed` (it keeps the edge map, the
        contours and the detections).
    image : array_like, shape (H, W, 3) or (H, W), optional
        The image (e.g. :func:`shapetree.detection.load_image`); panels (a) and (d) use
        it when given, else the edge map.
    n_show : int, default 3
        Detections drawn in the last panel (best in red, then blue, green, ...), with
        their scores and costs in the legend.
    title : str, optional
    path : path-like, optional
        Save the figure there (atomically, see :func:`save_figure`).
    dpi : float, default 90

    Returns
    -------
    matplotlib.figure.Figure
        Four axes: (a) image, (b) soft edges, (c) contours, (d) detections.
    """
    if path is not None:
        check_figure_path(path)
    img = None if image is None else np.asarray(image)
    edges = np.asarray(run.edges)
    shape = edges.shape if edges.size else (img.shape[:2] if img is not None else None)
    fig = new_figure(16, 4.4 + (0.3 if title else 0.0))
    axs = fig.subplots(1, 4)
    if img is not None:
        axs[0].imshow(img)
    axs[0].set_title("(a) image")
    if edges.size:
        axs[1].imshow(edges, cmap="gray_r")
    axs[1].set_title("(b) soft edges")
    plot_contours(run.contours, shape, ax=axs[2])
    axs[2].set_title(f"(c) {len(run.contours)} contours")
    if img is not None:
        axs[3].imshow(_faded(img))
    elif edges.size:
        axs[3].imshow(edges, cmap="gray_r")
    shown = range(min(n_show, len(run.detections)))
    for i in reversed(shown):
        _draw_detection(
            run.detections[i], run.contours, axs[3], color=_COLOURS[i % len(_COLOURS)], label=""
        )
    if len(shown):
        from matplotlib.lines import Line2D

        handles = [Line2D([], [], color=_COLOURS[i % len(_COLOURS)], lw=2) for i in shown]
        texts = [
            f"{i + 1}: score {run.detections[i].score:.3f}, cost {run.detections[i].cost:.3f}"
            for i in shown
        ]
        axs[3].legend(handles, texts, loc="lower left", fontsize=7, framealpha=0.8)
    axs[3].set_title("(d) detections (best in red)")
    for ax in axs:
        if shape is not None:
            ax.set_xlim(0, shape[1])
            ax.set_ylim(shape[0], 0)
        ax.set_xticks([])
        ax.set_yticks([])
    if title:
        fig.suptitle(title)
    if path is not None:
        save_figure(fig, path, dpi=dpi)
    return fig


def _dr_fppi_figure(curves: Mapping[tuple[str, float], tuple[np.ndarray, np.ndarray]]) -> Figure:
    """DR against FPPI per class, one panel per IoU threshold (0.2, 0.5)."""
    thresholds = sorted({thr for _, thr in curves})
    classes = list(dict.fromkeys(c for c, _ in curves))
    fig = new_figure(5.5 * len(thresholds), 4.5)
    axs = np.atleast_1d(fig.subplots(1, len(thresholds)))
    for ax, thr in zip(axs, thresholds, strict=True):
        for c in classes:
            fppi, dr = curves[(c, thr)]
            ax.plot(np.r_[0, fppi], np.r_[0, dr], label=c)
        ax.axvline(0.3, color="0.7", lw=0.8)
        ax.axvline(0.4, color="0.7", lw=0.8)
        ax.set_xlim(0, 1.5)
        ax.set_ylim(0, 1)
        ax.set_xlabel("false positives per image")
        ax.set_ylabel("detection rate")
        ax.set_title(f"IoU >= {thr}")
        ax.legend(fontsize=8)
    return fig


def _gallery_figure(entries: Sequence[tuple[str, Path, np.ndarray, dict | None]]) -> Figure:
    """One panel per image: ground-truth boxes (green) and the best detection (red)."""
    from shapetree.detection._edges import load_image

    ncol = 8
    nrow = int(np.ceil(len(entries) / ncol))
    fig = new_figure(2.2 * ncol, 2.0 * nrow)
    axs = fig.subplots(nrow, ncol, squeeze=False)
    for ax in axs.ravel():
        ax.axis("off")
    for ax, (name, image_path, boxes, best) in zip(axs.ravel(), entries, strict=False):
        ax.imshow(load_image(image_path))
        for g in boxes:
            ax.plot(g[[0, 2, 2, 0, 0]], g[[1, 1, 3, 3, 1]], "g-", lw=1)
        if best:
            ip = np.asarray(best["image_points"])
            mt = np.asarray(best["matched"], bool)
            cl = np.vstack([ip, ip[:1]])
            ax.plot(cl[:, 0], cl[:, 1], "r:", lw=0.8)
            ax.plot(ip[mt, 0], ip[mt, 1], "r.", ms=3)
            x1, y1, x2, y2 = best["bbox"]
            ax.plot([x1, x2, x2, x1, x1], [y1, y1, y2, y2, y1], "r--", lw=0.8)
        ax.set_title(name, fontsize=7)
    return fig


def save_ethz_figures(
    out_dir: PathArg,
    curves: Mapping[tuple[str, float], tuple[np.ndarray, np.ndarray]],
    galleries: Mapping[str, Sequence[tuple[str, Path, np.ndarray, dict | None]]],
    *,
    dpi: float = 80,
) -> list[Path]:
    """The pictures of :func:`shapetree.detection.evaluate_ethz` (``out_dir``).

    Parameters
    ----------
    out_dir : path-like
        Folder (created when missing).
    curves : mapping (class, IoU threshold) -> (fppi, dr)
        Written as ``ethz_dr_fppi.png``.
    galleries : mapping class -> sequence of (name, image path, ground-truth boxes, best)
        ``best`` is the image's best detection as stored by the evaluation (``bbox``,
        ``image_points``, ``matched``) or None; each class is written as
        ``ethz_gallery_<class>.png``.
    dpi : float, default 80

    Returns
    -------
    list of pathlib.Path
        The files written.
    """
    out = Path(out_dir)
    written = [save_figure(_dr_fppi_figure(curves), out / "ethz_dr_fppi.png", dpi=dpi)]
    for c, entries in galleries.items():
        if entries:
            fig = _gallery_figure(entries)
            written.append(save_figure(fig, out / f"ethz_gallery_{c}.png", dpi=dpi))
    return written
