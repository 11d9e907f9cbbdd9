"""Helpers shared by the command modules: argument types, shape loading, output files."""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from shapetree._atomic import atomic_open
from shapetree._errors import ShapeTreeError

#: Prefix that names an embedded demo shape instead of a file (``demo:hand``, ``demo:G``).
DEMO_PREFIX = "demo:"

DEFAULT_POINTS = 100


class Formatter(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """Show defaults and keep the hand-made line breaks of descriptions and epilogs."""


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a number >= 1, got {v}")
    return v


def points_int(text: str) -> int:
    """argparse type: a number of sample points, >= 3."""
    v = positive_int(text)
    if v < 3:
        raise argparse.ArgumentTypeError(f"a curve needs at least 3 points, got {v}")
    return v


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text}")
    return v


def nonneg_float(text: str) -> float:
    """argparse type: a finite number >= 0."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(v) and v >= 0):
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {text}")
    return v


@dataclass
class Shape:
    """A curve read for the command line."""

    points: np.ndarray
    closed: bool
    label: str
    image_coords: bool  # y points down (traced from an image)


def load_shape(spec: str, *, n_points: int | None, closed: bool) -> Shape:
    """Read a shape from an image, a point file, or ``demo:NAME``.

    Parameters
    ----------
    spec : str
        A file path, or ``demo:NAME`` (see ``shapetree demo --list``; ``demo:G`` is the
        outline of the glyph "G").
    n_points : int or None
        Resample to this many points.
    closed : bool
        Whether the curve is closed (demo shapes always are).

    Returns
    -------
    Shape
    """
    if spec.startswith(DEMO_PREFIX):
        from shapetree.demo import demo_shape

        name = spec[len(DEMO_PREFIX) :]
        if len(name) == 1:
            name = f"glyph-{name}"
        pts = demo_shape(name, n_points=n_points or DEFAULT_POINTS)
        if not closed:
            raise ShapeTreeError(f"{spec}: demo shapes are closed curves; drop --open")
        return Shape(pts, True, name, image_coords=False)
    from shapetree.curves import load_curve
    from shapetree.curves._image import IMAGE_EXTENSIONS

    pts, is_closed = load_curve(spec, n_points=n_points, closed=closed)
    is_image = Path(spec).suffix.lower() in IMAGE_EXTENSIONS
    return Shape(pts, is_closed, Path(spec).name, image_coords=is_image)


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, np.generic):
        return _jsonable(value.item())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, Path):
        return str(value)
    return value


def write_json(path: str | os.PathLike[str], data: Any) -> Path:
    """Write ``data`` as JSON atomically (NaN/inf become ``null``)."""
    p = Path(path)
    if p.is_dir():
        raise ShapeTreeError(f"{p}: is a directory, expected a .json file name")
    parent = p.parent if str(p.parent) else Path(".")
    parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(_jsonable(data), indent=2, allow_nan=False) + "\n"
    with atomic_open(p, "w") as fh:
        fh.write(text)
    return p


def require(module: str, name: str, what: str) -> Any:
    """Import ``module.name`` lazily, with a clear error when it is not available yet."""
    import importlib

    try:
        mod = importlib.import_module(module)
    except ImportError as exc:
        raise ShapeTreeError(f"{what} is not available: cannot import {module} ({exc})") from None
    func = getattr(mod, name, None)
    if func is None:
        raise ShapeTreeError(
            f"{what} is not available in this version of shapetree ({module}.{name} is missing)"
        )
    return func


def info(msg: str = "") -> None:
    """Print a line to stdout and flush (so it interleaves well with progress bars)."""
    print(msg, flush=True)


def warn(msg: str) -> None:
    """Print a line to stderr."""
    print(f"shapetree: {msg}", file=sys.stderr, flush=True)
