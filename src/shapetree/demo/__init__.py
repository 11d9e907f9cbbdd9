"""Embedded demo shapes, made by the project itself (no downloads, no dataset copies).

Glyph outlines come from the fonts bundled with matplotlib; the others (square, star,
leaf, hand, ...) are drawn in code. See :func:`demo_shapes`.
"""

from shapetree.demo._run import Candidate, DemoRanking, demo_ranking, similarity
from shapetree.demo._shapes import (
    DEMO_GLYPHS,
    demo_shape,
    demo_shape_names,
    demo_shapes,
    glyph_outline,
    hand,
    leaf,
    regular_polygon,
    star,
)

__all__ = [
    "DEMO_GLYPHS",
    "Candidate",
    "DemoRanking",
    "demo_ranking",
    "similarity",
    "demo_shape",
    "demo_shape_names",
    "demo_shapes",
    "glyph_outline",
    "hand",
    "leaf",
    "regular_polygon",
    "star",
]
