"""Demo shapes made in code and the demo ranking."""

from __future__ import annotations

import numpy as np
import pytest

from shapetree import ShapeTreeError
from shapetree.curves import signed_area
from shapetree.demo import demo_ranking, demo_shape, demo_shape_names, demo_shapes, glyph_outline
from shapetree.demo._run import similarity
from shapetree.demo._shapes import hand


def test_demo_shapes_are_valid_closed_curves():
    shapes = demo_shapes(n_points=48)
    assert set(shapes) == set(demo_shape_names())
    assert {"glyph-G", "star", "square", "leaf", "hand"} <= set(shapes)
    for name, pts in shapes.items():
        assert pts.shape == (48, 2), name
        assert np.all(np.isfinite(pts)), name
        assert signed_area(pts) > 0, f"{name} is not counter-clockwise"
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        assert np.isclose(np.max(hi - lo), 1.0), name
        assert np.allclose(0.5 * (lo + hi), 0.0, atol=1e-12), name
        step = np.linalg.norm(np.diff(np.vstack([pts, pts[:1]]), axis=0), axis=1)
        assert step.min() > 0.2 * step.mean(), f"{name} is not resampled evenly"


def test_glyph_outline_keeps_the_outer_boundary():
    # "O" has an outer boundary and a hole: the outline must be the outer one, which
    # encloses the hole, so its area is far larger than the hole's
    o = glyph_outline("O", n_points=64)
    assert signed_area(o) > 0.4  # unit bounding box: the outer ellipse's area
    assert o.shape == (64, 2)


@pytest.mark.parametrize("bad", ["", "AB", " "])
def test_glyph_outline_rejects_bad_characters(bad):
    with pytest.raises(ShapeTreeError):
        glyph_outline(bad)


def test_demo_shape_names_and_errors():
    assert np.allclose(demo_shape("glyph-Q", n_points=40), glyph_outline("Q", n_points=40))
    with pytest.raises(ShapeTreeError, match="unknown demo shape"):
        demo_shape("no-such-shape")


def test_hand_with_missing_finger_is_shorter():
    full, cut = hand(n_points=200), hand(n_points=200, missing=(2,))
    per = [
        np.linalg.norm(np.diff(np.vstack([p, p[:1]]), axis=0), axis=1).sum() for p in (full, cut)
    ]
    assert per[1] < per[0]


def test_similarity_roll_and_rotation():
    pts = demo_shape("square", n_points=20)
    out = similarity(pts, angle=np.pi / 2, scale=2.0, shift=(1.0, 0.0), roll=3)
    assert np.allclose(out[0], 2.0 * np.array([-pts[3, 1], pts[3, 0]]) + [1.0, 0.0])


@pytest.mark.parametrize("query", ["G", "A", "k"])
def test_demo_ranking_puts_deformed_copies_first(query):
    rank = demo_ranking(query, n_points=48, copies=2, seed=0)
    costs = [c.cost for c in rank.candidates]
    assert costs == sorted(costs)
    assert [c.same_as_query for c in rank.candidates[:2]] == [True, True]
    assert not any(c.same_as_query for c in rank.candidates[2:])
    assert rank.candidates[2].cost > 3 * rank.candidates[1].cost


def test_demo_ranking_is_deterministic():
    a = demo_ranking("S", n_points=40, seed=3)
    b = demo_ranking("S", n_points=40, seed=3)
    assert [(c.name, c.cost) for c in a.candidates] == [(c.name, c.cost) for c in b.candidates]
