"""The upright template check (``detection._template``)."""

from __future__ import annotations

import numpy as np
import pytest

from shapetree import ShapeTreeError
from shapetree.detection import detect
from shapetree.detection._template import (
    ASPECTS,
    ON_SIDE,
    ROTATIONS,
    SCALES,
    SHIFTS,
    TAU,
    TEMPLATE_TERMS,
    UPRIGHT,
    _variants,
    box_density,
    template_fields,
    template_model,
    template_terms,
)


def _reference_best(fields, model, bbox, turns) -> tuple[float, float]:
    """The search written plainly with NumPy, one placement batch at a time (the oracle)."""
    dt, theta, _ = fields
    h, w = dt.shape
    x1, y1, x2, y2 = bbox
    bw, bh = max(x2 - x1, 1.0), max(y2 - y1, 1.0)
    side = float(np.sqrt(bw * bh))
    vp, vn = _variants(model, turns, (bw, bh))
    best = (np.inf, 0.0)
    for sc in SCALES:
        t = TAU * sc * side
        for dx in SHIFTS:
            for dy in SHIFTS:
                xy = vp * sc + np.array([(x1 + x2) / 2 + dx * side, (y1 + y2) / 2 + dy * side])
                c = np.rint(xy[..., 0]).astype(int)
                r = np.rint(xy[..., 1]).astype(int)
                ins = (c >= 0) & (c < w) & (r >= 0) & (r < h)
                c, r = np.clip(c, 0, w - 1), np.clip(r, 0, h - 1)
                d = np.where(ins, dt[r, c], np.inf)
                near = d < t
                sin = np.abs(np.sin(vn - theta[r, c]))
                cost = 0.5 * np.minimum(d / t, 1.0) + 0.5 * np.where(near, sin, 1.0)
                mean = cost.mean(1)
                i = int(np.argmin(mean))
                if mean[i] < best[0]:
                    best = (float(mean[i]), float(np.mean(near[i] & (sin[i] < 0.5))))
    return best


def _bottle(n: int = 60) -> np.ndarray:
    """A tall, top-narrow outline (a bottle): upright it differs from itself on its side."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    x, y = np.cos(t), 2.5 * np.sin(t)
    x = np.where(y < -0.8, 0.35 * x, x)  # the neck (image y points down: top is y < 0)
    return np.c_[x, y]


def _draw(shape: tuple[int, int], outline: np.ndarray) -> np.ndarray:
    """A 1-px edge map of a closed outline (value 1 on it)."""
    from skimage.draw import polygon_perimeter

    e = np.zeros(shape)
    rr, cc = polygon_perimeter(outline[:, 1], outline[:, 0], shape=shape, clip=True)
    e[rr, cc] = 1.0
    return e


def _scene(turn: float = 0.0) -> tuple[np.ndarray, np.ndarray, tuple[float, ...]]:
    model = _bottle()
    rot = np.array([[np.cos(turn), np.sin(turn)], [-np.sin(turn), np.cos(turn)]])
    placed = (model @ rot) * 30 + [100, 110]
    bbox = (*placed.min(0), *placed.max(0))
    return model, _draw((220, 220), placed), bbox


def test_search_equals_the_numpy_reference() -> None:
    rng = np.random.default_rng(0)
    e = np.clip(rng.normal(0.0, 0.3, (90, 120)), 0, 1)
    model = template_model(_bottle())
    fields = template_fields(e, 0.15)
    for _ in range(6):
        x1, y1 = rng.uniform(-20, 80), rng.uniform(-20, 60)
        bbox = (x1, y1, x1 + rng.uniform(5, 70), y1 + rng.uniform(5, 70))
        got = template_terms(fields, model, bbox)
        up = _reference_best(fields, model, bbox, UPRIGHT)
        side = _reference_best(fields, model, bbox, ON_SIDE)
        assert got["template"] == pytest.approx(1 - up[0], abs=1e-12)
        assert got["template_support"] == pytest.approx(up[1], abs=1e-12)
        assert got["template_gain"] == pytest.approx(side[0] - up[0], abs=1e-12)
        assert 0.0 <= got["template"] <= 1.0 and 0.0 <= got["box_density"] <= 1.0


def test_upright_object_fits_and_gains_over_its_side() -> None:
    model, e, bbox = _scene(0.0)
    got = template_terms(template_fields(e, 0.5), template_model(model), bbox)
    assert got["template"] > 0.85
    assert got["template_support"] > 0.85
    assert got["template_gain"] > 0.2


def test_object_on_its_side_has_negative_gain() -> None:
    """The same outline turned by 90 degrees: the upright model fits its box worse than
    the model turned on its side does."""
    model, e, bbox = _scene(np.pi / 2)
    got = template_terms(template_fields(e, 0.5), template_model(model), bbox)
    assert got["template_gain"] < -0.2


def test_mirrored_object_fits_as_well() -> None:
    model, e, bbox = _scene(0.0)
    mirrored = model * [-1.0, 1.0]
    fields = template_fields(e, 0.5)
    a = template_terms(fields, template_model(model), bbox)
    b = template_terms(fields, template_model(mirrored), bbox)
    assert b["template"] == pytest.approx(a["template"], abs=0.02)


def test_empty_box_and_empty_map() -> None:
    model, e, _bbox = _scene(0.0)
    fields = template_fields(e, 0.5)
    far = template_terms(fields, template_model(model), (150, 150, 200, 210))
    assert far["template"] < 0.2 and far["box_density"] == 0.0
    none = template_terms(template_fields(np.zeros((50, 50)), 0.5), template_model(model), _bbox)
    assert none["template"] == 0.0 and none["template_support"] == 0.0


def test_box_density_counts_edge_pixels() -> None:
    on = np.zeros((10, 10), bool)
    on[2:4, 2:4] = True
    assert box_density(on, (2, 2, 4, 4)) == 1.0
    assert box_density(on, (0, 0, 10, 10)) == pytest.approx(0.04)
    assert box_density(on, (20, 20, 30, 30)) == 0.0  # outside the image


def test_bad_inputs() -> None:
    model = template_model(_bottle())
    fields = template_fields(np.zeros((20, 20)), 0.5)
    with pytest.raises(ShapeTreeError, match="bbox"):
        template_terms(fields, model, (0, 0, np.nan, 5))
    with pytest.raises(ShapeTreeError, match="edge map"):
        template_fields(np.zeros(5), 0.5)


def test_detections_carry_the_template_terms() -> None:
    """``detect`` on a drawn scene: each detection's record has the four terms, equal to
    the check computed on its match's box (``match_box``: the box before any refinement)."""
    model, e, bbox = _scene(0.0)
    dets = detect(model * 30, None, edges=e, k=2)
    assert dets
    fields = template_fields(e, 0.15)
    for d in dets:
        rec = d.to_json()
        want = template_terms(fields, template_model(d.model_points), d.match_box)
        for t in TEMPLATE_TERMS:
            assert rec[t] == pytest.approx(want[t])
    assert dets[0].template > 0.8


def test_search_grid_is_the_documented_one() -> None:
    assert len(SCALES) * len(SHIFTS) ** 2 * 2 * len(ROTATIONS) * len(ASPECTS) == 486
