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


def test_detection_scene_is_seeded_and_holds_the_broken_outline():
    from shapetree.demo._scene import box_iou, detection_scene

    a = detection_scene("star", seed=4, size=(150, 190), object_size=90.0)
    b = detection_scene("star", seed=4, size=(150, 190), object_size=90.0)
    assert a.image.shape == (150, 190, 3) and np.array_equal(a.image, b.image)
    assert a.image.min() >= 0.0 and a.image.max() <= 1.0
    x1, y1, x2, y2 = a.box
    assert max(x2 - x1, y2 - y1) == pytest.approx(90.0)
    assert 0 <= x1 < x2 <= 190 and 0 <= y1 < y2 <= 150
    assert np.allclose(a.box, [*a.outline.min(axis=0), *a.outline.max(axis=0)])
    # the outline is dark ink except in its gaps: some outline points lie on background
    grey = a.image.mean(axis=2)
    on = grey[np.rint(a.outline[:, 1]).astype(int), np.rint(a.outline[:, 0]).astype(int)]
    dark = on < 0.35
    assert 0.7 < dark.mean() < 0.97
    assert box_iou(a.box, a.box) == pytest.approx(1.0)
    assert box_iou(a.box, (x2, y2, x2 + 5, y2 + 5)) == 0.0
    with pytest.raises(ShapeTreeError, match="too small"):
        detection_scene("star", size=(60, 60))


def test_demo_detection_step_finds_the_star(tmp_path, capsys):
    import argparse

    from PIL import Image

    from shapetree.cli._demo import _detection_step

    pictures: list = []
    args = argparse.Namespace(detect_shape="star", seed=0)
    assert _detection_step(args, tmp_path, pictures) is True
    text = capsys.readouterr().out
    assert "found (IoU >= 0.5)" in text and "NOT" not in text
    assert pictures == [
        ("detection in a cluttered scene (Fig. 5)", tmp_path / "demo_detection.png")
    ]
    with Image.open(tmp_path / "demo_detection.png") as im:
        assert im.format == "PNG" and im.width > 400
