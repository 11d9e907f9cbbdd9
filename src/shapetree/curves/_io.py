"""Reading curves from files: ``load_points`` (point files) and ``load_curve`` (any file)."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np

from shapetree._errors import CurveError, ImageError
from shapetree.curves._image import IMAGE_EXTENSIONS, curve_from_image
from shapetree.curves._resample import resample
from shapetree.curves._validate import _as_xy, as_curve, orient

__all__ = ["load_points", "load_curve"]

_SEPARATORS = re.compile(r"[,;\s]+")


def _check_file(path: Path) -> None:
    if not path.exists():
        raise CurveError(f"{path}: file not found")
    if not path.is_file():
        raise CurveError(f"{path}: not a file")


def _read_text(path: Path) -> np.ndarray:
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise CurveError(f"{path}: unreadable text file ({exc})") from None
    rows: list[list[float]] = []
    first_data = True
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        fields = [f for f in _SEPARATORS.split(line) if f]
        try:
            values = [float(f) for f in fields]
        except ValueError:
            if first_data:  # one optional header line, e.g. "x,y"
                first_data = False
                continue
            raise CurveError(
                f"{path}: line {lineno} is not numeric: {line[:60]!r}; "
                "expected two numbers (x, y) per line"
            ) from None
        first_data = False
        if len(values) != 2:
            raise CurveError(
                f"{path}: line {lineno} has {len(values)} values, expected 2 (x, y): {line[:60]!r}"
            )
        rows.append(values)
    if not rows:
        raise CurveError(f"{path}: the file contains no points")
    return np.array(rows, dtype=np.float64)


def _read_npy(path: Path) -> np.ndarray:
    try:
        data = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError) as exc:
        raise CurveError(f"{path}: unreadable .npy file ({exc})") from None
    if not isinstance(data, np.ndarray) or data.dtype.kind not in "iufc":
        raise CurveError(
            f"{path}: expected a numeric (n, 2) or (n, 1, 2) array, or a 1-D complex array "
            "x + iy, in the .npy file"
        )
    return data


def _read_json(path: Path) -> tuple[object, bool | None]:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CurveError(f"{path}: unreadable JSON file ({exc})") from None
    closed = None
    if isinstance(data, dict):
        if "points" not in data:
            raise CurveError(
                f"{path}: JSON object has no 'points' key; expected a list of [x, y] pairs "
                "or an object {'points': [[x, y], ...], 'closed': bool}"
            )
        closed = data.get("closed")
        if closed is not None and not isinstance(closed, bool):
            raise CurveError(f"{path}: JSON key 'closed' must be true or false, got {closed!r}")
        data = data["points"]
    if not isinstance(data, list) or not all(
        isinstance(p, list) and len(p) == 2 and all(_is_number(v) for v in p) for p in data
    ):
        raise CurveError(f"{path}: JSON points must be a list of [x, y] number pairs")
    return data, closed


def _is_number(v: object) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def _read_points(path: str | os.PathLike) -> tuple[np.ndarray, bool | None]:
    """Points of a point file and the file's own ``closed`` flag (JSON only; else None)."""
    path = Path(path)
    _check_file(path)
    ext = path.suffix.lower()
    closed = None
    if ext in IMAGE_EXTENSIONS:
        raise CurveError(f"{path}: is an image, not a point file; use curve_from_image/load_curve")
    if ext == ".npy":
        data = _read_npy(path)
    elif ext == ".json":
        data, closed = _read_json(path)
    else:
        data = _read_text(path)
    return _as_xy(data, name=str(path)), closed


def load_points(path: str | os.PathLike) -> np.ndarray:
    """Read the points of a curve from a point file.

    Formats (by extension):

    * ``.npy``: a numeric array of shape ``(n, 2)``, an OpenCV contour saved as it is,
      ``(n, 1, 2)``, or a 1-D complex array of points ``x + iy``.
    * ``.json``: a list of ``[x, y]`` pairs, or an object ``{"points": [[x, y], ...]}`` (an
      optional ``"closed": true|false`` key is used by :func:`load_curve`).
    * anything else (``.csv``, ``.txt``, ...): text, two numbers per line separated by commas,
      semicolons or whitespace; one optional non-numeric header line (e.g. ``x,y``); blank lines
      and lines starting with ``#`` are ignored.

    Parameters
    ----------
    path : str or os.PathLike
        The file.

    Returns
    -------
    numpy.ndarray, shape (n, 2), float64
        The ``(x, y)`` points as stored (no duplicates removed; see :func:`as_curve`).

    Raises
    ------
    CurveError
        If the file is missing or unreadable, or its content is not an ``(n, 2)`` table of finite
        numbers; the message names the file (and the line for text files).
    """
    return _read_points(path)[0]


def load_curve(
    path: str | os.PathLike,
    *,
    n_points: int | None = None,
    closed: bool | None = None,
    orientation: str | None = "ccw",
) -> tuple[np.ndarray, bool]:
    """Read a curve from an image or a point file, validated, oriented and optionally resampled.

    Parameters
    ----------
    path : str or os.PathLike
        An image (extensions ``.gif .png .bmp .tif .tiff .pgm .pbm .ppm .pnm .jpg .jpeg``): its
        silhouette's outer boundary (:func:`curve_from_image` with default settings); otherwise a
        point file (:func:`load_points`).
    n_points : int, optional
        If given, resample to this many points uniformly spaced in arc length (:func:`resample`).
    closed : bool, optional
        Whether the curve is closed. Default: True for images; for point files the JSON
        ``"closed"`` key if present, else False.
    orientation : {"ccw", "cw", "keep", None}, optional
        Orientation applied to closed curves (see :func:`orient`); ignored for open curves.

    Returns
    -------
    points : numpy.ndarray, shape (n, 2), float64
        The curve, in the file's coordinates (pixels, ``x`` = column, ``y`` = row, for images).
    closed : bool
        Whether the curve is closed.

    Raises
    ------
    CurveError
        Bad point file or invalid curve (the message names the file).
    ImageError
        Bad image (missing, unreadable, blank, too small).
    """
    p = Path(path)
    if p.suffix.lower() in IMAGE_EXTENSIONS:
        if not p.exists():
            raise ImageError(f"{p}: image file not found")
        pts = curve_from_image(p)
        is_closed = True if closed is None else bool(closed)
    else:
        pts, file_closed = _read_points(p)
        is_closed = bool(closed) if closed is not None else bool(file_closed)
    pts = as_curve(pts, closed=is_closed, name=str(p))
    if is_closed:
        pts = orient(pts, orientation)
    if n_points is not None:
        pts = resample(pts, n_points, closed=is_closed)
    return pts, is_closed
