"""Embedded demo shapes, made by the project itself (no downloads, no dataset copies).

Glyph outlines come from the fonts bundled with matplotlib (:func:`glyph_outline`); the
others (square, star, leaf, hand, ...) are drawn in code. See :func:`demo_shapes` and
:func:`demo_shape_names`; :func:`demo_ranking` is the ``shapetree demo`` ranking.
"""

from shapetree.demo._run import Candidate, DemoRanking, demo_ranking
from shapetree.demo._shapes import demo_shape, demo_shape_names, demo_shapes, glyph_outline

__all__ = [
    "Candidate",
    "DemoRanking",
    "demo_ranking",
    "demo_shape",
    "demo_shape_names",
    "demo_shapes",
    "glyph_outline",
]
