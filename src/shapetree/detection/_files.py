"""Pictures (Fig. 5 style) and file outputs for detection, for the CLI and the benchmark."""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from shapetree._atomic import atomic_write_bytes

from ._detect import Detection, DetectionRun, DetectParams, detect_detailed
from ._edges import load_image

__all__ = [
    "plot_contours",
    "plot_detection",
    "plot_detection_run",
    "detect_to_files",
]


def plot_contours(
    contours: Sequence[NDArray[np.float64]],
    shape: tuple[int, int] | None = None,
    *,
    ax: Any = None,
    seed: int = 0,
    endpoints: bool = True,
) -> Any:
    """Draw traced contours, each in its own colour (paper Fig. 5(c)).

    Parameters
    ----------
    contours : sequence of ndarray, each (n_i, 2)
        Polylines ``(x, y)`` in px.
    shape : (H, W) or None
        Image size, sets the axes limits (y down).
    ax : matplotlib Axes or None
        Created when None.
    seed : int
        Colour seed.
    endpoints : bool
        Mark contour endpoints with black dots.

    Returns
    -------
    matplotlib Axes
    """
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots()
    rng = np.random.default_rng(seed)
    for c in contours:
        ax.plot(c[:, 0], c[:, 1], "-", color=rng.uniform(0.1, 0.9, 3), lw=1.2)
        if endpoints:
            ax.plot(c[[0, -1], 0], c[[0, -1], 1], "k.", ms=2)
    if shape is not None:
        ax.set_xlim(0, shape[1])
        ax.set_ylim(shape[0], 0)
    ax.set_aspect("equal")
    return ax


def plot_detection(
    det: Detection,
    contours: Sequence[NDArray[np.float64]],
    *,
    ax: Any,
    image: NDArray | None = None,
    color: str = "r",
    label: str | None = None,
) -> Any:
    """Draw one detection: matched contours, mapped model points, gaps and box.

    Parameters
    ----------
    det : Detection
    contours : sequence of ndarray
        The run's contours (``Detection.pieces`` index into them).
    ax : matplotlib Axes
    image : ndarray or None
        Drawn faded underneath when given.
    color : str
        Matplotlib colour of this detection.
    label : str or None
        Text written at the box's corner (default: the cost; ``""`` writes none).

    Returns
    -------
    matplotlib Axes
    """
    if image is not None:
        ax.imshow(np.asarray(image, dtype=float) * 0.5 + 0.5 if image.ndim == 3 else image)
    for pc in det.pieces:
        c = contours[pc["contour"]]
        ax.plot(c[:, 0], c[:, 1], "-", color=color, lw=2.2)
    ip = det.image_points
    closed = np.vstack([ip, ip[:1]])
    ax.plot(closed[:, 0], closed[:, 1], ":", color=color, lw=0.8)
    ax.plot(ip[det.matched, 0], ip[det.matched, 1], ".", color=color, ms=4)
    ax.plot(ip[~det.matched, 0], ip[~det.matched, 1], "x", color=color, ms=4)
    x1, y1, x2, y2 = det.bbox
    ax.plot([x1, x2, x2, x1, x1], [y1, y1, y2, y2, y1], "--", color=color, lw=1)
    text = label if label is not None else f"{det.cost:.3f}"
    if text:
        ax.text(x1, y1, text, color=color, fontsize=7)
    return ax


def plot_detection_run(
    run: DetectionRun, image: NDArray | None, *, n_show: int = 3, title: str | None = None
) -> Any:
    """Fig. 5-style figure: image, soft edges, contours, detections.

    Parameters
    ----------
    run : DetectionRun
    image : ndarray, shape (H, W, 3), or None
    n_show : int
        Detections drawn in the last panel (best in red).
    title : str or None

    Returns
    -------
    matplotlib Figure
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    shape = run.edges.shape if run.edges.size else (image.shape[:2] if image is not None else None)
    fig, axs = plt.subplots(1, 4, figsize=(16, 4.4))
    if image is not None:
        axs[0].imshow(image)
    axs[0].set_title("(a) image")
    if run.edges.size:
        axs[1].imshow(run.edges, cmap="gray_r")
    axs[1].set_title("(b) soft edges")
    plot_contours(run.contours, shape, ax=axs[2])
    axs[2].set_title(f"(c) {len(run.contours)} contours")
    if image is not None:
        axs[3].imshow(np.asarray(image, dtype=float) * 0.5 + 0.5)
    elif run.edges.size:
        axs[3].imshow(run.edges, cmap="gray_r")
    colours = ["r", "b", "g", "m", "c"]
    shown = range(min(n_show, len(run.detections)))
    for i in reversed(shown):
        plot_detection(run.detections[i], run.contours, ax=axs[3], color=colours[i % 5], label="")
    if len(shown):
        from matplotlib.lines import Line2D

        handles = [Line2D([], [], color=colours[i % 5], lw=2) for i in shown]
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
    fig.tight_layout()
    return fig


def detect_to_files(
    model_path: str | os.PathLike[str],
    image_path: str | os.PathLike[str],
    *,
    edges_path: str | os.PathLike[str] | None = None,
    out_png: str | os.PathLike[str] | None = None,
    out_json: str | os.PathLike[str] | None = None,
    k: int = 5,
    params: DetectParams | None = None,
    **overrides: Any,
) -> list[Detection]:
    """Detect a model in an image file and write a picture and/or a JSON report.

    Parameters
    ----------
    model_path : path-like
        Outline drawing (e.g. ETHZ ``models/*.tif``) or point file.
    image_path : path-like
        The image.
    edges_path : path-like or None
        Stored soft edge map (e.g. ETHZ ``*_edges.tif``); computed by
        :func:`edge_map` when None.
    out_png : path-like or None
        Fig. 5-style picture (image, edges, contours, detections).
    out_json : path-like or None
        JSON with ``model``, ``image``, ``edges``, ``params``, ``timings`` and
        ``detections`` (each: score, cost, bbox, coverage, model_points,
        image_points, matched, gaps, pieces).  Both files are written
        atomically.
    k : int
        Number of detections.
    params : DetectParams or None
        Parameters; keyword ``overrides`` replace single fields.

    Returns
    -------
    list of Detection
    """
    image = load_image(image_path)
    run = detect_detailed(model_path, image, edges=edges_path, k=k, params=params, **overrides)
    if out_json is not None:
        doc = {
            "model": str(model_path),
            "image": str(image_path),
            "edges": str(edges_path) if edges_path is not None else "gradient",
            "image_size": [int(image.shape[1]), int(image.shape[0])],
            "params": run.params.as_dict(),
            "timings": run.timings,
            "n_contours": len(run.contours),
            "detections": [d.to_json() for d in run.detections],
        }
        atomic_write_bytes(out_json, json.dumps(doc, indent=1).encode(), fsync=False)
    if out_png is not None:
        import io

        import matplotlib.pyplot as plt

        fig = plot_detection_run(
            run, image, title=f"{Path(model_path).stem} in {Path(image_path).name}"
        )
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=90)
        plt.close(fig)
        atomic_write_bytes(out_png, buf.getvalue(), fsync=False)
    return run.detections
