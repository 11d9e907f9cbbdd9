"""The upright template check (``detection._template``)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from shapetree import ShapeTreeError
from shapetree.detection import detect
from shapetree.detection._detect import REFINE_IOU, refine_plan
from shapetree.detection._template import (
    ASPECTS,
    GROWN_SCALES,
    GROWN_SHIFTS,
    ON_SIDE,
    ROTATIONS,
    SCALES,
    SHIFTS,
    TAU,
    TEMPLATE_TERMS,
    UPRIGHT,
    _variants,
    box_density,
    grown_fit,
    template_fields,
    template_model,
    template_terms,
)


def _reference_best(fields, model, bbox, turns, scales=SCALES, shifts=SHIFTS, box=False):
    """The search written plainly with NumPy, one placement batch at a time (the oracle):
    the least mean cost and its support share (and, with ``box``, the placed box)."""
    dt, theta, _ = fields
    h, w = dt.shape
    x1, y1, x2, y2 = bbox
    bw, bh = max(x2 - x1, 1.0), max(y2 - y1, 1.0)
    side = float(np.sqrt(bw * bh))
    vp, vn = _variants(model, turns, (bw, bh))
    best = (np.inf, 0.0)
    placed = None
    for sc in scales:
        t = TAU * sc * side
        for dx in shifts:
            for dy in shifts:
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
                    placed = (*xy[i].min(0), *xy[i].max(0))
    return (*best, placed) if box else best


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


def test_grown_fit_equals_the_numpy_reference() -> None:
    rng = np.random.default_rng(1)
    e = np.clip(rng.normal(0.0, 0.3, (90, 120)), 0, 1)
    model = template_model(_bottle())
    fields = template_fields(e, 0.15)
    for _ in range(4):
        x1, y1 = rng.uniform(0, 60), rng.uniform(0, 40)
        bbox = (x1, y1, x1 + rng.uniform(8, 50), y1 + rng.uniform(8, 50))
        cost, box = grown_fit(fields, model, bbox)
        want_cost, _, want_box = _reference_best(
            fields, model, bbox, UPRIGHT, GROWN_SCALES, GROWN_SHIFTS, box=True
        )
        assert cost == pytest.approx(want_cost, abs=1e-12)
        assert box == pytest.approx(want_box, abs=1e-9)
        # the widened search holds the template's own placements: never a worse fit
        assert cost <= 1 - template_terms(fields, model, bbox)["template"] + 1e-12
    assert set(SCALES) <= set(GROWN_SCALES) and set(SHIFTS) <= set(GROWN_SHIFTS)
    with pytest.raises(ShapeTreeError, match="bbox"):
        grown_fit(fields, model, (0, 0, np.nan, 5))


def _part_scene():
    """A drawn bottle's template fields and model, a box of 0.6 times it a little above its
    centre (the part a match may cover) and the whole bottle's box."""
    model, e, whole = _scene(0.0)
    x1, y1, x2, y2 = whole
    w, h = x2 - x1, y2 - y1
    cx, cy = (x1 + x2) / 2, (y1 + y2) / 2 - 0.1 * h
    part = (cx - 0.3 * w, cy - 0.3 * h, cx + 0.3 * w, cy + 0.3 * h)
    return template_fields(e, 0.15), template_model(model), part, whole


def test_grown_fit_finds_the_whole_object_around_its_part() -> None:
    """A box of 0.6 times a drawn bottle, off its centre (the part a match may cover): the
    widened fit's box is the whole bottle's, and it fits far better than the template
    inside the part's box; a box that is already the whole stays there."""
    fields, tm, part, whole = _part_scene()
    cost, box = grown_fit(fields, tm, part)
    in_box = 1 - template_terms(fields, tm, part)["template"]
    assert cost < in_box - 0.3
    assert _iou(box, whole) > 0.85
    cost_w, box_w = grown_fit(fields, tm, whole)
    assert _iou(box_w, whole) > 0.85 and cost_w < 0.3


def test_refine_boxes_gives_the_whole_box_and_keeps_the_match_box() -> None:
    """The detector's stage on a detection whose match covers the part above: its box
    becomes the whole bottle's, ``match_bbox`` keeps the part's, the score stays."""
    import dataclasses

    from shapetree.detection import Detection
    from shapetree.detection._detect import _refine_boxes

    fields, tm, part, whole = _part_scene()
    pts = np.zeros((4, 2))
    det = Detection(-1.0, -1.0, part, pts, pts, np.ones(4, bool), [], 0.5)
    det = dataclasses.replace(det, **template_terms(fields, tm, part))
    (got,) = _refine_boxes([det], fields, tm, 0.05, fields.dt.shape)
    assert got.match_bbox == part and got.match_box == part
    assert _iou(got.bbox, whole) > 0.85 and got.score == det.score
    assert got.to_json()["match_bbox"] == pytest.approx(list(part))
    # with a threshold above the gain, the box stays the match's
    (same,) = _refine_boxes([det], fields, tm, 0.9, fields.dt.shape)
    assert same.bbox == part and same.match_bbox is None
    assert "match_bbox" not in same.to_json()


def test_refine_plan_replaces_clips_and_drops_duplicates() -> None:
    scores = [3.0, 2.0, 1.0]
    boxes = [[10, 10, 20, 20], [100, 100, 140, 140], [12, 12, 22, 22]]
    template = [0.6, 0.9, 0.6]  # in-box costs 0.4, 0.1, 0.4
    grown_cost = [0.2, 0.08, 0.3]
    grown_box = [[5, 5, 60, 60], [90, 90, 150, 150], [0, 0, 58, 58]]
    box, refined, keep = refine_plan(
        scores, boxes, template, grown_cost, grown_box, 0.05, (50, 200)
    )
    # the first and third fit better by more than 0.05 (0.2, 0.1); the second by 0.02
    assert refined.tolist() == [True, False, True]
    np.testing.assert_allclose(box[0], [5, 5, 60, 50])  # clipped to the image (H 50)
    np.testing.assert_allclose(box[1], boxes[1])
    np.testing.assert_allclose(box[2], [0, 0, 58, 50])
    # the third, grown onto the first's object, overlaps its box by IoU > REFINE_IOU
    assert _iou(box[2], box[0]) > REFINE_IOU
    assert keep.tolist() == [True, True, False]
    # a larger delta refines nothing and keeps all three (their match boxes are apart)
    box, refined, keep = refine_plan(
        scores, boxes, template, grown_cost, grown_box, 0.25, (50, 200)
    )
    assert not refined.any() and keep.all()
    np.testing.assert_allclose(box, boxes)


def test_box_refine_parameter() -> None:
    from shapetree.detection import DetectParams

    assert DetectParams().box_refine == 0.05
    # off is recorded (None), not left out: the protocol's workers rebuild the parameters
    # from as_dict(), and a missing field would come back as the default, 0.05
    assert DetectParams(box_refine=None).as_dict()["box_refine"] is None
    for p in (
        DetectParams(),
        DetectParams(box_refine=None),
        DetectParams(box_refine=None, nms_nested=0.8, upright_cost=0.25),
    ):
        assert DetectParams(**p.as_dict()) == p
        assert DetectParams(**json.loads(json.dumps(p.as_dict()))) == p
    for bad in (-0.1, 1.0, float("nan"), True, "0.05"):
        with pytest.raises(ShapeTreeError, match="box_refine"):
            DetectParams(box_refine=bad)


def _iou(a, b) -> float:
    ix = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = ix * iy
    area = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return inter / area
