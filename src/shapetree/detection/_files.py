"""File outputs of one detection run (``shapetree detect``): a JSON report and a picture.

The picture itself is drawn by :func:`shapetree.plotting.plot_detections`.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from shapetree._atomic import atomic_write_bytes

from ._detect import Detection, DetectParams, detect_detailed
from ._edges import load_image

__all__ = ["detect_to_files"]


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
        :func:`edge_map` (method ``params.edge_method``, default ``"own"``) when None.
    out_png : path-like or None
        Fig. 5-style picture (image, edges, contours, detections; see
        :func:`shapetree.plotting.plot_detections`); the extension picks the format
        (``.png``, ``.pdf``, ``.svg``, ...).
    out_json : path-like or None
        JSON with ``model``, ``image``, ``edges`` (the map file or the edge method),
        ``params``, ``timings`` and
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
    if out_png is not None:
        from shapetree.plotting._save import check_figure_path

        check_figure_path(out_png)  # a bad picture name fails before the work
    image = load_image(image_path)
    run = detect_detailed(model_path, image, edges=edges_path, k=k, params=params, **overrides)
    if out_json is not None:
        doc = {
            "model": str(model_path),
            "image": str(image_path),
            "edges": str(edges_path) if edges_path is not None else run.params.edge_method,
            "image_size": [int(image.shape[1]), int(image.shape[0])],
            "params": run.params.as_dict(),
            "timings": run.timings,
            "n_contours": len(run.contours),
            "detections": [d.to_json() for d in run.detections],
        }
        atomic_write_bytes(out_json, json.dumps(doc, indent=1).encode(), fsync=False)
    if out_png is not None:
        from shapetree.plotting import plot_detections

        title = f"{Path(model_path).stem} in {Path(image_path).name}"
        plot_detections(run, image, title=title, path=out_png)
    return run.detections
