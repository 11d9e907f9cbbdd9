"""Models drawn as SVG: the outline of the first ``<path>`` (or ``<polygon>`` / ``<polyline>``).

An SVG file is the usual way a person draws a model in a vector editor (Inkscape,
Illustrator, a browser).  :func:`read_svg_outline` reads

- the ``d`` attribute of the first ``<path>`` element: the commands ``M L H V C S Q T Z``
  in absolute (upper case) and relative (lower case) form, with implicit repeats
  (``M 0 0 10 0 10 10`` is a move and two lines); cubic and quadratic Bézier segments
  are sampled densely (``bezier_samples`` points each, then the curve is resampled
  uniformly by the model);
- or, without a ``<path>``, the ``points`` of the first ``<polygon>`` (closed) or
  ``<polyline>`` (open unless its ends coincide).

``transform`` attributes of the element and its ancestors (``matrix``, ``translate``,
``scale``, ``rotate``, ``skewX``, ``skewY``) are applied.  A path with several sub-paths
(several ``M``) gives its longest sub-path, the outline; the others (holes, details) are
dropped.  Arcs (``A``), ``<circle>`` / ``<ellipse>`` / ``<rect>`` only files, text and
images are refused with a :class:`~shapetree.ShapeTreeError` saying what to do.  Coordinates
are SVG user units, ``y`` down, like image rows.
"""

from __future__ import annotations

import math
import os
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from shapetree._errors import ShapeTreeError

__all__ = ["read_svg_outline", "parse_path_d", "BEZIER_SAMPLES"]

#: Points per Bézier segment (the curve is resampled uniformly afterwards).
BEZIER_SAMPLES = 24

_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
_TOKEN = re.compile(r"([MmLlHhVvCcSsQqTtZzAa])|([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)")
_ARGS = {"M": 2, "L": 2, "H": 1, "V": 1, "C": 6, "S": 4, "Q": 4, "T": 2, "Z": 0, "A": 7}


def _cubic(p0, p1, p2, p3, n: int) -> list[tuple[float, float]]:
    t = np.linspace(0.0, 1.0, n + 1)[1:, None]
    pts = (
        (1 - t) ** 3 * np.asarray(p0)
        + 3 * (1 - t) ** 2 * t * np.asarray(p1)
        + 3 * (1 - t) * t**2 * np.asarray(p2)
        + t**3 * np.asarray(p3)
    )
    return [tuple(map(float, q)) for q in pts]


def _quadratic(p0, p1, p2, n: int) -> list[tuple[float, float]]:
    t = np.linspace(0.0, 1.0, n + 1)[1:, None]
    pts = (1 - t) ** 2 * np.asarray(p0) + 2 * (1 - t) * t * np.asarray(p1) + t**2 * np.asarray(p2)
    return [tuple(map(float, q)) for q in pts]


def parse_path_d(
    d: str, *, bezier_samples: int = BEZIER_SAMPLES
) -> list[tuple[NDArray[np.float64], bool]]:
    """Sub-paths of an SVG path ``d`` attribute as polylines.

    Parameters
    ----------
    d : str
        The path data (``M L H V C S Q T Z``, absolute and relative).
    bezier_samples : int
        Points per Bézier segment (default :data:`BEZIER_SAMPLES`).

    Returns
    -------
    list of (ndarray, shape (n_i, 2), bool)
        Each sub-path's points (``x, y``; a closed one without its closing point
        repeated) and whether it was closed with ``Z``.

    Raises
    ------
    ShapeTreeError
        On arcs (``A``), unknown characters, a missing initial ``M`` or a command with
        the wrong number of numbers.
    """
    pos = 0
    tokens: list[str | float] = []
    for mt in _TOKEN.finditer(d):
        gap = d[pos : mt.start()]
        if gap.strip(" \t\r\n,"):
            raise ShapeTreeError(f"SVG path data: unexpected {gap.strip()[:20]!r} in d={d[:60]!r}")
        tokens.append(mt.group(1) if mt.group(1) else float(mt.group(2)))
        pos = mt.end()
    if d[pos:].strip(" \t\r\n,"):
        raise ShapeTreeError(f"SVG path data: unexpected {d[pos:].strip()[:20]!r}")
    subpaths: list[tuple[list[tuple[float, float]], bool]] = []
    cur: list[tuple[float, float]] = []
    closed = False
    x = y = 0.0
    start = (0.0, 0.0)
    last_cubic = last_quad = None  # reflected control points for S / T
    i = 0
    cmd = None

    def flush() -> None:
        nonlocal cur, closed
        if len(cur) >= 2:
            subpaths.append((cur, closed))
        cur, closed = [], False

    while i < len(tokens):
        tok = tokens[i]
        if isinstance(tok, str):
            if cmd is None and tok not in "Mm":
                raise ShapeTreeError("SVG path data must start with a move (M or m)")
            cmd = tok
            i += 1
            if cmd in "Aa":
                raise ShapeTreeError(
                    "SVG arcs (the A command) are not supported; convert them to Bezier "
                    "curves first (e.g. Inkscape: Path > Object to Path, or export as "
                    "plain SVG with curves)"
                )
            if cmd in "Zz":
                if cur:
                    closed = True
                    x, y = start
                    flush()
                last_cubic = last_quad = None
                continue
        elif cmd is None:
            raise ShapeTreeError("SVG path data must start with a move (M or m)")
        elif cmd in "Zz":
            raise ShapeTreeError("SVG path data: numbers after Z without a command")
        up = cmd.upper()
        nargs = _ARGS[up]
        vals = tokens[i : i + nargs]
        if len(vals) < nargs or any(isinstance(v, str) for v in vals):
            raise ShapeTreeError(
                f"SVG path data: the {cmd} command needs {nargs} numbers, got {vals!r}"
            )
        i += nargs
        v = [float(t) for t in vals]
        rel = cmd.islower()
        ox, oy = (x, y) if rel else (0.0, 0.0)
        if up == "M":
            flush()
            x, y = ox + v[0], oy + v[1]
            start = (x, y)
            cur = [(x, y)]
            cmd = "l" if rel else "L"  # implicit repeats of a move are lines
            last_cubic = last_quad = None
            continue
        if not cur:  # drawing after Z starts at the sub-path's start
            cur = [(x, y)]
        if up == "L":
            x, y = ox + v[0], oy + v[1]
            cur.append((x, y))
            last_cubic = last_quad = None
        elif up == "H":
            x = (x if rel else 0.0) + v[0]
            cur.append((x, y))
            last_cubic = last_quad = None
        elif up == "V":
            y = (y if rel else 0.0) + v[0]
            cur.append((x, y))
            last_cubic = last_quad = None
        elif up in "CS":
            if up == "C":
                c1 = (ox + v[0], oy + v[1])
                c2, end = (ox + v[2], oy + v[3]), (ox + v[4], oy + v[5])
            else:
                c1 = (2 * x - last_cubic[0], 2 * y - last_cubic[1]) if last_cubic else (x, y)
                c2, end = (ox + v[0], oy + v[1]), (ox + v[2], oy + v[3])
            cur.extend(_cubic((x, y), c1, c2, end, bezier_samples))
            last_cubic, last_quad = c2, None
            x, y = end
        else:  # Q / T
            if up == "Q":
                c1, end = (ox + v[0], oy + v[1]), (ox + v[2], oy + v[3])
            else:
                c1 = (2 * x - last_quad[0], 2 * y - last_quad[1]) if last_quad else (x, y)
                end = (ox + v[0], oy + v[1])
            cur.extend(_quadratic((x, y), c1, end, bezier_samples))
            last_quad, last_cubic = c1, None
            x, y = end
    flush()
    out = []
    for pts, was_closed in subpaths:
        a = np.asarray(pts, dtype=np.float64)
        keep = np.r_[True, np.any(np.diff(a, axis=0) != 0, axis=1)]  # repeated points
        a = a[keep]
        if was_closed and len(a) > 1 and np.allclose(a[0], a[-1]):
            a = a[:-1]
        if len(a) >= 2:
            out.append((a, was_closed))
    return out


def _transform(text: str) -> NDArray[np.float64]:
    """The 3x3 matrix of an SVG ``transform`` attribute."""
    total = np.eye(3)
    for mt in re.finditer(r"(\w+)\s*\(([^)]*)\)", text):
        name, args = mt.group(1), [float(a) for a in _NUMBER.findall(mt.group(2))]
        m = np.eye(3)
        if name == "matrix" and len(args) == 6:
            a, b, c, d, e, f = args
            m = np.array([[a, c, e], [b, d, f], [0, 0, 1]])
        elif name == "translate" and len(args) in (1, 2):
            m[0, 2], m[1, 2] = args[0], args[1] if len(args) == 2 else 0.0
        elif name == "scale" and len(args) in (1, 2):
            m[0, 0], m[1, 1] = args[0], args[1] if len(args) == 2 else args[0]
        elif name == "rotate" and len(args) in (1, 3):
            t = math.radians(args[0])
            r = np.array([[math.cos(t), -math.sin(t), 0], [math.sin(t), math.cos(t), 0], [0, 0, 1]])
            if len(args) == 3:
                cx, cy = args[1], args[2]
                pre, post = np.eye(3), np.eye(3)
                pre[:2, 2], post[:2, 2] = (cx, cy), (-cx, -cy)
                r = pre @ r @ post
            m = r
        elif name == "skewX" and len(args) == 1:
            m[0, 1] = math.tan(math.radians(args[0]))
        elif name == "skewY" and len(args) == 1:
            m[1, 0] = math.tan(math.radians(args[0]))
        else:
            raise ShapeTreeError(f"SVG transform {mt.group(0)!r} is not understood")
        total = total @ m
    return total


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _polyline_points(text: str, what: str) -> NDArray[np.float64]:
    vals = [float(v) for v in _NUMBER.findall(text or "")]
    if len(vals) % 2 or len(vals) < 4:
        raise ShapeTreeError(f"SVG <{what}> needs an even count of at least 4 numbers in points")
    return np.asarray(vals, dtype=np.float64).reshape(-1, 2)


def read_svg_outline(
    path: str | os.PathLike[str], *, bezier_samples: int = BEZIER_SAMPLES
) -> tuple[NDArray[np.float64], bool]:
    """The model outline drawn in an SVG file.

    Parameters
    ----------
    path : path-like
        An ``.svg`` file.
    bezier_samples : int
        Points per Bézier segment.

    Returns
    -------
    points : ndarray, shape (n, 2), float64
        The outline in SVG user units (``x`` right, ``y`` down), transforms applied; a
        closed outline does not repeat its first point.
    closed : bool
        True for a path closed with ``Z``, a ``<polygon>``, or ends that coincide.

    Raises
    ------
    ShapeTreeError
        If the file is not readable XML, holds no ``<path>`` / ``<polygon>`` /
        ``<polyline>``, or uses what is not supported (arcs, unknown transforms).
    """
    p = Path(path)
    try:
        root = ET.parse(p).getroot()
    except FileNotFoundError:
        raise ShapeTreeError(f"model file not found: {p}") from None
    except (ET.ParseError, OSError, UnicodeDecodeError) as exc:
        raise ShapeTreeError(f"cannot read SVG model {p}: {exc}") from None
    parents = {c: par for par in root.iter() for c in par}
    found = None
    for tag in ("path", "polygon", "polyline"):
        found = next((e for e in root.iter() if _local(e.tag) == tag), None)
        if found is not None:
            break
    if found is None:
        kinds = sorted({_local(e.tag) for e in root.iter()} - {"svg", "g", "defs", "metadata"})
        raise ShapeTreeError(
            f"SVG model {p}: no <path>, <polygon> or <polyline> to read (found: "
            f"{', '.join(kinds) or 'nothing'}); draw the outline as a path"
        )
    tag = _local(found.tag)
    try:
        if tag == "path":
            subs = parse_path_d(found.get("d", ""), bezier_samples=bezier_samples)
            if not subs:
                raise ShapeTreeError("the path's d attribute draws no line")
            lengths = [np.hypot(*np.diff(s, axis=0).T).sum() for s, _ in subs]
            pts, closed = subs[int(np.argmax(lengths))]
        else:
            pts = _polyline_points(found.get("points", ""), tag)
            closed = tag == "polygon"
        mat = np.eye(3)
        node = found
        while node is not None:
            if node.get("transform"):
                mat = _transform(node.get("transform")) @ mat
            node = parents.get(node)
    except ShapeTreeError as exc:
        raise ShapeTreeError(f"SVG model {p}: {exc}") from None
    pts = pts @ mat[:2, :2].T + mat[:2, 2]
    if len(pts) > 2 and np.allclose(pts[0], pts[-1], atol=1e-9 * (1 + np.abs(pts).max())):
        pts, closed = pts[:-1], True
    if len(pts) < 3:
        raise ShapeTreeError(f"SVG model {p}: the outline has fewer than 3 distinct points")
    return np.ascontiguousarray(pts, dtype=np.float64), bool(closed)
