"""Demo shapes made by the project itself: font glyph outlines and curves drawn in code.

Nothing here is downloaded or copied from a dataset. Glyphs come from the DejaVu fonts that
ship with matplotlib (:class:`matplotlib.textpath.TextPath`); the other shapes are
parametric curves. Every shape is a closed curve in ordinary mathematical coordinates
(``y`` points up), counter-clockwise, without a repeated first point, resampled uniformly
in arc length and scaled so that its bounding box's larger side is 1 (centred at 0).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from shapetree._errors import ShapeTreeError
from shapetree.curves import as_curve, orient, resample, signed_area

__all__ = [
    "DEMO_GLYPHS",
    "demo_shape",
    "demo_shape_names",
    "demo_shapes",
    "glyph_outline",
    "hand",
    "leaf",
    "regular_polygon",
    "star",
]

#: Characters whose glyph outlines are part of :func:`demo_shapes`.
DEMO_GLYPHS = "ABGRSk4"

_DEFAULT_POINTS = 96


def _normalise(points: np.ndarray, n_points: int) -> np.ndarray:
    """Orient ccw, resample, centre the bounding box at 0 and scale its larger side to 1."""
    pts = as_curve(points, closed=True, name="demo shape")
    pts = orient(pts, "ccw")
    pts = resample(pts, n_points, closed=True)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    return (pts - 0.5 * (lo + hi)) / float(np.max(hi - lo))


def glyph_outline(
    char: str,
    *,
    n_points: int = _DEFAULT_POINTS,
    family: str = "DejaVu Sans",
    weight: str = "bold",
) -> np.ndarray:
    """Outer outline of a font glyph, as a closed curve.

    The glyph is rendered with :class:`matplotlib.textpath.TextPath` from a font that ships
    with matplotlib; its Bézier outline is flattened to polygons and the polygon of largest
    area (the outer boundary; holes such as the inside of ``"A"`` are dropped) is kept.

    Parameters
    ----------
    char : str
        A single character with a visible glyph (letters, digits, ...).
    n_points : int, default 96
        Number of points after uniform arc-length resampling.
    family : str, default "DejaVu Sans"
        Font family (DejaVu Sans is bundled with matplotlib).
    weight : str, default "bold"
        Font weight.

    Returns
    -------
    numpy.ndarray, shape (n_points, 2)
        Closed, counter-clockwise, ``y`` up, bounding box centred at 0 with larger side 1.

    Raises
    ------
    ShapeTreeError
        If ``char`` is not a single character or has no closed outline (e.g. a space).

    Examples
    --------
    >>> glyph_outline("G", n_points=64).shape
    (64, 2)
    """
    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import TextPath

    if not isinstance(char, str) or len(char) != 1:
        raise ShapeTreeError(f"glyph_outline needs a single character, got {char!r}")
    if char.isspace():
        raise ShapeTreeError(f"the character {char!r} has no glyph outline")
    try:
        path = TextPath((0, 0), char, size=1.0, prop=FontProperties(family=family, weight=weight))
        raw = path.to_polygons(closed_only=True)
    except (AttributeError, ValueError, RuntimeError) as exc:  # glyphs with no outline
        raise ShapeTreeError(f"cannot render the glyph {char!r}: {exc}") from None
    polys = [np.asarray(p, dtype=float) for p in raw]
    polys = [p[:-1] if len(p) > 1 and np.allclose(p[0], p[-1]) else p for p in polys]
    polys = [p for p in polys if len(p) >= 3]
    if not polys:
        raise ShapeTreeError(f"the glyph {char!r} has no closed outline")
    outer = max(polys, key=lambda p: abs(signed_area(p)))
    return _normalise(outer, n_points)


def regular_polygon(
    sides: int = 4, *, n_points: int = _DEFAULT_POINTS, angle: float = 0.0
) -> np.ndarray:
    """A regular polygon (``sides=4`` is the square of paper Fig. 4).

    Parameters
    ----------
    sides : int, default 4
        Number of sides, at least 3.
    n_points : int, default 96
        Number of points after resampling.
    angle : float, default 0
        Rotation in radians (0 puts the sides of a square parallel to the axes).

    Returns
    -------
    numpy.ndarray, shape (n_points, 2)
    """
    if sides < 3:
        raise ShapeTreeError(f"a polygon needs at least 3 sides, got {sides}")
    t = angle + np.pi / sides + 2 * np.pi * np.arange(sides) / sides
    return _normalise(np.c_[np.cos(t), np.sin(t)], n_points)


def star(arms: int = 5, *, inner: float = 0.45, n_points: int = _DEFAULT_POINTS) -> np.ndarray:
    """A star polygon with ``arms`` points.

    Parameters
    ----------
    arms : int, default 5
        Number of points of the star (at least 3).
    inner : float, default 0.45
        Radius of the inner vertices relative to the outer ones, in (0, 1).
    n_points : int, default 96

    Returns
    -------
    numpy.ndarray, shape (n_points, 2)
    """
    if arms < 3 or not 0 < inner < 1:
        raise ShapeTreeError(f"star needs arms >= 3 and 0 < inner < 1, got {arms}, {inner}")
    k = np.arange(2 * arms)
    r = np.where(k % 2 == 0, 1.0, inner)
    t = np.pi / 2 + np.pi * k / arms
    return _normalise(np.c_[r * np.cos(t), r * np.sin(t)], n_points)


def leaf(*, n_points: int = _DEFAULT_POINTS, teeth: int = 0) -> np.ndarray:
    """A leaf: rounded base, pointed tip and a short stalk, optionally serrated.

    Parameters
    ----------
    n_points : int, default 96
    teeth : int, default 0
        Number of small teeth along each margin (0 = smooth).

    Returns
    -------
    numpy.ndarray, shape (n_points, 2)
    """
    s = np.linspace(0.0, np.pi, 400)
    y = -np.cos(s)  # base (-1) to tip (+1), dense at both ends
    half = 0.62 * np.sqrt(1.0 + y) * (1.0 - y) ** 1.1
    if teeth:
        half = half * (1.0 + 0.08 * np.abs(np.sin(teeth * np.pi * (y + 1) / 2)))
    right = np.c_[half, y][1:-1]
    left = np.c_[-half, y][::-1][1:-1]
    stalk = np.array([[-0.025, -1.0], [-0.03, -1.3], [0.03, -1.3], [0.025, -1.0]])
    pts = np.vstack([right, [[0.0, 1.0]], left, stalk])
    return _normalise(pts, n_points)


def _finger(base: tuple[float, float], length: float, width: float, angle: float) -> np.ndarray:
    """A rounded finger from its base centre, traversed right side -> tip -> left side."""
    u = np.array([np.sin(angle), np.cos(angle)])  # along the finger (angle from +y)
    v = np.array([u[1], -u[0]])  # to its right
    b = np.asarray(base, dtype=float)
    th = np.linspace(0.0, np.pi, 11)
    tip = b + length * u + 0.5 * width * (np.cos(th)[:, None] * v + np.sin(th)[:, None] * u)
    return np.vstack([b + 0.5 * width * v, tip, b - 0.5 * width * v])


def hand(
    *, n_points: int = _DEFAULT_POINTS, spread: float = 1.0, missing: tuple[int, ...] = ()
) -> np.ndarray:
    """A hand-like silhouette: a palm with four fingers and a thumb.

    Parameters
    ----------
    n_points : int, default 96
    spread : float, default 1.0
        How far the fingers fan out (1 = natural, 0 = parallel fingers).
    missing : tuple of int, default ()
        Fingers left out (0 = thumb, 1 = index, ..., 4 = little finger), e.g. to make an
        "occluded" hand for matching with replaced parts.

    Returns
    -------
    numpy.ndarray, shape (n_points, 2)
    """
    s = float(spread)
    fingers = [  # base centre, length, width, angle from +y
        ((0.55, -0.32), 0.55, 0.26, 0.55 * s + 0.35),  # thumb, up and out
        ((0.33, 0.30), 0.72, 0.21, 0.10 * s),  # index
        ((0.105, 0.34), 0.82, 0.21, 0.02 * s),  # middle
        ((-0.12, 0.32), 0.76, 0.20, -0.07 * s),  # ring
        ((-0.34, 0.24), 0.56, 0.18, -0.18 * s),  # little
    ]
    parts = [np.array([[0.42, -1.0], [0.50, -0.45]])]  # right edge of the wrist and palm
    for k, (base, length, width, angle) in enumerate(fingers):
        f = _finger(base, length, width, angle)
        parts.append(f[[0, -1]] if k in missing else f)  # a missing finger: its base only
        if k == 0:
            parts.append(np.array([[0.47, 0.05]]))
    parts.append(np.array([[-0.47, -0.10], [-0.42, -1.0]]))  # left edge down to the wrist
    return _normalise(np.vstack(parts), n_points)


_MAKERS: dict[str, Callable[[int], np.ndarray]] = {
    "square": lambda n: regular_polygon(4, n_points=n),
    "triangle": lambda n: regular_polygon(3, n_points=n, angle=np.pi / 6),
    "star": lambda n: star(5, n_points=n),
    "leaf": lambda n: leaf(n_points=n),
    "hand": lambda n: hand(n_points=n),
    "hand-cut": lambda n: hand(n_points=n, missing=(2,)),
}


def demo_shape_names() -> list[str]:
    """Names accepted by :func:`demo_shape`: ``glyph-<char>`` for each demo glyph and the
    drawn shapes.

    Returns
    -------
    list of str
    """
    return [f"glyph-{c}" for c in DEMO_GLYPHS] + list(_MAKERS)


def demo_shape(name: str, *, n_points: int = _DEFAULT_POINTS) -> np.ndarray:
    """One demo shape by name.

    Parameters
    ----------
    name : str
        One of :func:`demo_shape_names`, or ``glyph-<c>`` for any single character ``c``.
    n_points : int, default 96

    Returns
    -------
    numpy.ndarray, shape (n_points, 2)
        Closed curve, counter-clockwise, ``y`` up.

    Raises
    ------
    ShapeTreeError
        Unknown name.
    """
    if name.startswith("glyph-") and len(name) == len("glyph-") + 1:
        return glyph_outline(name[-1], n_points=n_points)
    if name in _MAKERS:
        return _MAKERS[name](n_points)
    raise ShapeTreeError(
        f"unknown demo shape {name!r}; choose one of: {', '.join(demo_shape_names())}"
    )


def demo_shapes(*, n_points: int = _DEFAULT_POINTS) -> dict[str, np.ndarray]:
    """All demo shapes: glyph outlines of :data:`DEMO_GLYPHS` and shapes drawn in code.

    Parameters
    ----------
    n_points : int, default 96
        Points per shape (uniform in arc length).

    Returns
    -------
    dict of str to numpy.ndarray
        ``name -> (n_points, 2)`` closed curves (ccw, ``y`` up, unit bounding box).

    Examples
    --------
    >>> shapes = demo_shapes(n_points=48)
    >>> sorted(shapes)[:3]
    ['glyph-4', 'glyph-A', 'glyph-B']
    """
    return {name: demo_shape(name, n_points=n_points) for name in demo_shape_names()}
