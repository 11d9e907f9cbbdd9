"""Figure creation without a display and atomic saving."""

from __future__ import annotations

import os
from pathlib import Path

from matplotlib.figure import Figure

from shapetree._atomic import atomic_open
from shapetree._errors import ShapeTreeError

__all__ = ["new_figure", "save_figure", "check_figure_path"]

#: Formats the Agg-based canvases can write.
_FORMATS = ("png", "pdf", "svg", "jpg", "jpeg", "eps", "ps", "webp", "tif", "tiff")


def new_figure(width: float, height: float) -> Figure:
    """A matplotlib figure that is not attached to pyplot or any GUI (no display needed).

    Parameters
    ----------
    width, height : float
        Size in inches.

    Returns
    -------
    matplotlib.figure.Figure
    """
    return Figure(figsize=(width, height), layout="constrained")


def check_figure_path(path: str | os.PathLike[str]) -> Path:
    """Validate an output picture path before any work is done.

    Parameters
    ----------
    path : str or os.PathLike
        Where the picture will go; the extension picks the format.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    ShapeTreeError
        Unsupported extension, or the path is an existing directory.
    """
    p = Path(path)
    ext = p.suffix.lower().lstrip(".")
    if ext not in _FORMATS:
        raise ShapeTreeError(
            f"{p}: unsupported picture format {p.suffix or '(no extension)'!r}; "
            f"use one of: {', '.join('.' + f for f in _FORMATS)}"
        )
    if p.is_dir():
        raise ShapeTreeError(f"{p}: is a directory, expected a picture file name")
    return p


def save_figure(fig: Figure, path: str | os.PathLike[str], *, dpi: float = 150) -> Path:
    """Write a figure atomically (:func:`shapetree._atomic.atomic_open`).

    A reader never sees a half-written picture, and on any error the temporary file is
    removed and an existing file at ``path`` is left untouched. Missing parent folders are
    created.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    path : str or os.PathLike
        Destination; the extension picks the format (``.png``, ``.pdf``, ``.svg``, ...).
    dpi : float, default 150
        Resolution for raster formats.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    ShapeTreeError
        Unsupported extension.
    OSError
        The folder cannot be created or written.
    """
    p = check_figure_path(path)
    fmt = p.suffix.lower().lstrip(".")
    fmt = {"jpg": "jpeg", "tif": "tiff"}.get(fmt, fmt)
    with atomic_open(p, "wb") as fh:  # creates missing folders
        fig.savefig(fh, format=fmt, dpi=dpi, facecolor="white")
    return p
