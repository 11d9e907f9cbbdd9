"""The stitching DP on synthetic scenes drawn by the test, where the answer is known."""

from __future__ import annotations

import numpy as np
import pytest

from shapetree import ShapeTreeError
from shapetree.detection import Detection, context_agreement, detect, make_model
from shapetree.detection._stitch import _dif
from shapetree.geometry import outline_dif


def _shape(t: np.ndarray) -> np.ndarray:
    r = 1 + 0.3 * np.cos(3 * t) + 0.15 * np.sin(2 * t)  # no symmetry
    return np.c_[r * np.cos(t), r * np.sin(t)]


def _place(p: np.ndarray, ang: float, scale: float, shift: tuple[float, float]) -> np.ndarray:
    rot = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
    return p @ rot.T * scale + np.asarray(shift)


def _arc(a: float, b: float, n: int = 300) -> np.ndarray:
    return np.linspace(a, b, n)


def _scene(seed: int, removed: list[tuple[float, float]], n_clutter: int = 20):
    cuts = sorted({0.3, 2.5, 5.2, *[x for ab in removed for x in ab]})
    bounds = [*cuts, cuts[0] + 2 * np.pi]
    ang, scale, shift = np.deg2rad(20.0), 60.0, (200.0, 150.0)
    pieces = []
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        if any(abs(a - ra) < 1e-9 and abs(b - rb) < 1e-9 for ra, rb in removed):
            continue
        pieces.append(_place(_shape(_arc(a, b)), ang, scale, shift))
    rng = np.random.default_rng(seed)
    clutter = []
    for i in range(n_clutter):
        c = rng.uniform([0, 0], [420, 320])
        th, length = rng.uniform(0, np.pi), rng.uniform(20, 80)
        if i % 2 == 0:
            s = np.linspace(0, 1, 30)[:, None]
            clutter.append(c + s * length * np.array([np.cos(th), np.sin(th)]))
        else:
            u = np.linspace(0, rng.uniform(1, 2.5), 30)
            clutter.append(c + length / 2 * np.c_[np.cos(u + th), np.sin(u + th)])
    conts = pieces + clutter
    order = rng.permutation(len(conts))
    conts = [conts[i] if rng.random() < 0.5 else conts[i][::-1] for i in order]
    full = _place(_shape(np.linspace(0, 2 * np.pi, 2000)), ang, scale, shift)
    box = (full[:, 0].min(), full[:, 1].min(), full[:, 0].max(), full[:, 1].max())
    return conts, box


def _iou(a, b) -> float:
    ix = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = ix * iy
    area = lambda r: (r[2] - r[0]) * (r[3] - r[1])  # noqa: E731
    return inter / (area(a) + area(b) - inter)


MODEL_T = np.linspace(0, 2 * np.pi, 400, endpoint=False)


@pytest.mark.parametrize("seed", [0, 1])
def test_stitch_finds_broken_shape_with_gaps(seed: int) -> None:
    removed = [(1.0, 1.6), (3.5, 4.2)]
    conts, true_box = _scene(seed, removed)
    model = make_model(_shape(MODEL_T), m=30)
    dets = detect(model, None, contours=conts, k=3)
    assert dets and isinstance(dets[0], Detection)
    best = dets[0]
    assert _iou(best.bbox, true_box) > 0.7
    # gaps are where the pieces are missing: every removed arc holds a gap,
    # and every gap lies in a removed arc (angles of the model samples)
    theta = np.array([MODEL_T[np.argmin(np.hypot(*(_shape(MODEL_T) - p).T))] for p in model.points])
    gap_mid = []
    for g0, g1, share in best.gaps:
        assert share > 0
        idx = (g0 + np.arange((g1 - g0) % 30 + 1)) % 30
        gap_mid.append(np.mean(np.unwrap(theta[idx])) % (2 * np.pi))
    assert len(best.gaps) == len(removed)
    for a, b in removed:
        assert any(a - 0.2 <= gm <= b + 0.2 for gm in gap_mid)
    assert 0.7 < best.coverage < 0.95
    # matched image points lie on the true outline
    full = _place(_shape(np.linspace(0, 2 * np.pi, 4000)), np.deg2rad(20.0), 60.0, (200.0, 150.0))
    ip = best.image_points[best.matched]
    dist = np.min(np.hypot(ip[:, None, 0] - full[None, :, 0], ip[:, None, 1] - full[None, :, 1]), 1)
    assert np.median(dist) < 3.0
    # other detections do not overlap it much
    for d in dets[1:]:
        assert _iou(d.bbox, best.bbox) <= 0.3 + 1e-9
        assert d.cost >= best.cost


def test_complete_shape_without_gaps_and_json() -> None:
    from shapetree.detection import DetectParams

    conts, true_box = _scene(3, removed=[], n_clutter=10)
    dets = detect(make_model(_shape(MODEL_T), m=24), None, contours=conts, k=2)
    best = dets[0]
    assert _iou(best.bbox, true_box) > 0.8
    assert best.gaps == [] and best.coverage == pytest.approx(1.0)
    js = best.to_json()
    assert set(js) >= {"score", "bbox", "model_points", "image_points", "gaps", "matched"}
    assert len(js["image_points"]) == 24
    # no image: the score is the cost, the outline check and the context check (no frame
    # prior)
    d2 = outline_dif(best.model_points, best.image_points)
    agree = context_agreement(best.model_points, best.image_points)
    w, wc = DetectParams().outline_check, DetectParams().context_check
    assert w > 0 and 0 <= d2 < 0.05 and wc > 0 and 0.5 < agree <= 1.0
    assert js["score"] == pytest.approx(-best.cost - w * d2 + wc * agree)


def test_clutter_only_gives_weak_or_no_detections() -> None:
    conts, _ = _scene(5, removed=[(0.3, 2.5), (2.5, 5.2)], n_clutter=15)  # one arc of the object
    dets = detect(make_model(_shape(MODEL_T), m=24), None, contours=conts[:15], k=3)
    full, _ = _scene(5, removed=[(1.0, 1.6)], n_clutter=15)
    good = detect(make_model(_shape(MODEL_T), m=24), None, contours=full, k=1)
    assert good and all(d.cost > good[0].cost for d in dets)


def test_triangle_dif_properties() -> None:
    z = (0j, 1 + 0j, 0.3 + 0.8j)
    w = tuple(2.0 * np.exp(0.7j) * v + (3 - 1j) for v in z)  # similar copy
    assert _dif(*z, *w) == pytest.approx(0.0, abs=1e-12)
    assert 0.0 < _dif(*z, 0j, 1 + 0j, 0.5 - 0.1j) <= 1.0
    assert _dif(*z, 1j, 1j, 1j) == 1.0  # degenerate


def test_bad_inputs() -> None:
    model = make_model(_shape(MODEL_T), m=20)
    with pytest.raises(ShapeTreeError):
        detect(model, None, contours=[np.zeros((3, 3))])
    with pytest.raises(ShapeTreeError):
        detect(model, None, contours=[np.ones((5, 2))], k=0)
    with pytest.raises(ShapeTreeError):
        make_model(np.zeros((2, 2)))
    assert detect(model, None, contours=[]) == []


def test_size_prior_prefers_object_sized_matches() -> None:
    # the same complete outline twice: a 12-px speck (perimeter ~ 90 px) and a real-size copy
    small = _place(_shape(_arc(0.0, 2 * np.pi - 0.05)), 0.3, 12.0, (60.0, 60.0))
    large = _place(_shape(_arc(0.0, 2 * np.pi - 0.05)), 0.3, 60.0, (250.0, 200.0))
    model = make_model(_shape(MODEL_T), m=24)
    off = detect(model, None, contours=[small, large], k=2, size_cost=0.0, min_perimeter=0.0)
    assert len(off) == 2  # both found when there is no size prior
    on = detect(model, None, contours=[small, large], k=2)  # defaults: size prior on
    assert on and on[0].bbox[0] > 150  # the large copy ranks first
    assert all(d.bbox[0] > 150 for d in on) or on[-1].cost > on[0].cost + 0.2
    # a piece implying a perimeter below min_perimeter / 2 is not used at all: the
    # ~90 px speck may then only cover model shares f with 90 / f >= 200 px
    cut = detect(model, None, contours=[small], k=2, min_perimeter=400.0, full_perimeter=800.0)
    assert all(d.coverage < 0.5 for d in cut)


def test_evidence_costs_terms() -> None:
    from shapetree.detection import DetectParams
    from shapetree.detection._detect import _evidence_costs

    frac = np.tile(np.linspace(0.0, 0.9, 10), (10, 1))
    p = DetectParams(weak_cost=0.5, strong_edge=0.4, size_cost=0.5)
    out = _evidence_costs(p, frac, np.array([0.1, 0.6]), [400.0, 400.0])
    assert out.shape == (4, 10, 10)
    assert np.array_equal(out[0], out[1])  # both directions of a contour
    # weak contour pays weak_cost * f * (1 - 0.1 / 0.4); the strong one pays nothing
    big = out[2, :, -1]  # f = 0.9: implied perimeter 444 px, no size term
    assert np.allclose(big, 0.0)
    assert np.allclose(out[0, :, -1], 0.5 * 0.9 * 0.75)
    # short contour on a big model share: implied perimeter below min_perimeter / 2 -> unusable
    tiny = _evidence_costs(p, frac, np.array([1.0]), [20.0])
    assert np.isinf(tiny[0, 0, -1])  # f = 0.9: 22 px < 120 / 2
    # f = 0.2: 100 px, below min_perimeter: the full size term size_cost * f
    assert tiny[0, 0, 2] == pytest.approx(0.5 * 0.2)
    # f = 0.1: 200 px, between min (120) and full (240) perimeter: a partial term
    r = np.log(240 / 200) / np.log(240 / 120)
    assert tiny[0, 0, 1] == pytest.approx(0.5 * 0.1 * r)
    off = _evidence_costs(DetectParams(size_cost=0.0, min_perimeter=0.0), frac, [1.0], [20.0])
    assert np.all(off == 0.0)


def test_frame_prior_reorders_by_image_share() -> None:
    from shapetree.detection import DetectParams

    conts, true_box = _scene(2, removed=[(1.0, 1.6)], n_clutter=20)
    model = make_model(_shape(MODEL_T), m=24)
    image = np.zeros((320, 420))
    # the paper's cost-order suppression, under which a ranking term only re-orders
    off = {"outline_check": 0.0, "context_check": 0.0, "score_pool": 0}
    plain = detect(model, image, contours=conts, k=4, frame_prior=0.0, **off)
    assert [d.score for d in plain] == pytest.approx([-d.cost for d in plain])
    w = DetectParams().frame_prior
    assert w > 0
    ranked = detect(model, image, contours=conts, k=4, **off)  # image size known
    # the same detections (the prior does not change which are kept) ...
    assert sorted(d.cost for d in ranked) == pytest.approx(sorted(d.cost for d in plain))
    for d in ranked:
        x1, y1, x2, y2 = d.bbox
        share = min((x2 - x1) * (y2 - y1) / (320 * 420), 1.0)
        assert d.score == pytest.approx(-d.cost + w * 0.5 * np.log(share))
    # ... ranked by the new score, and the object still comes first
    assert [d.score for d in ranked] == sorted((d.score for d in ranked), reverse=True)
    assert _iou(ranked[0].bbox, true_box) > 0.7
    # without an image the size of the frame is unknown: scores stay -cost
    none = detect(model, None, contours=conts, k=4, **off)
    assert [d.score for d in none] == pytest.approx([-d.cost for d in none])


def test_outline_dif_and_outline_check() -> None:
    pts = _shape(np.linspace(0, 2 * np.pi, 30, endpoint=False))
    moved = _place(pts, 1.1, 37.0, (120.0, -40.0))
    assert outline_dif(pts, moved) == pytest.approx(0.0, abs=1e-12)  # similarity invariant
    squashed = moved * np.array([1.0, 0.3])
    shuffled = moved[np.random.default_rng(0).permutation(30)]
    assert 0.01 < outline_dif(pts, squashed) < outline_dif(pts, shuffled) <= 1.0
    assert outline_dif(pts, np.zeros_like(pts)) == 1.0  # a collapsed placement
    # the check is a ranking term: with only it on, score = -cost - w * d2
    conts, _ = _scene(2, removed=[(1.0, 1.6)], n_clutter=20)
    model = make_model(_shape(MODEL_T), m=24)
    dets = detect(model, None, contours=conts, k=4, outline_check=0.5, context_check=0.0)
    for d in dets:
        assert d.score == pytest.approx(-d.cost - 0.5 * outline_dif(d.model_points, d.image_points))
    assert [d.score for d in dets] == sorted((d.score for d in dets), reverse=True)


def test_border_margin_ignores_the_picture_frame() -> None:
    from shapetree.detection._detect import _without_border

    e = np.ones((50, 60))
    out = _without_border(e, 6.0)
    assert out[6:-6, 6:-6].min() == 1.0 and out[6:-6, 6:-6].size == 38 * 48
    assert out.sum() == 38 * 48 and e.min() == 1.0  # input untouched
    assert _without_border(e, 0.0) is e
    # an edge map holding only a frame 2 px inside the border: nothing is traced
    frame = np.zeros((120, 160))
    frame[2, 2:-2] = frame[-3, 2:-2] = frame[2:-2, 2] = frame[2:-2, -3] = 1.0
    square = make_model(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]), m=16)
    from shapetree.detection import detect_detailed

    run = detect_detailed(square, None, edges=frame, k=2)
    assert run.contours == [] and run.detections == []
    kept = detect_detailed(square, None, edges=frame, k=2, border_margin=0.0)
    assert kept.contours  # the frame itself is traced when the margin is off
    for bad in (
        {"border_margin": -1.0},
        {"frame_prior": float("nan")},
        {"outline_check": -1},
        {"context_check": float("inf")},
    ):
        with pytest.raises(ShapeTreeError, match=next(iter(bad))):
            detect_detailed(square, None, edges=frame, k=2, **bad)


def _stitch_inputs(monkeypatch: pytest.MonkeyPatch, seed: int, m: int) -> tuple[tuple, dict]:
    """The arguments ``detect`` passes to the stitching DP on a synthetic scene."""
    from shapetree.detection import _detect

    got: list[tuple[tuple, dict]] = []
    real = _detect.run_stitch

    def spy(*args, **kw):
        got.append((args, kw))
        return real(*args, **kw)

    monkeypatch.setattr(_detect, "run_stitch", spy)
    conts, _ = _scene(seed, removed=[(1.0, 1.6), (3.5, 4.2)], n_clutter=14)
    detect(make_model(_shape(MODEL_T), m=m), None, contours=conts, k=3, beam=8, gap_beam=4)
    return got[0]


@pytest.mark.parametrize(("seed", "m", "dif"), [(0, 12, "procrustes"), (1, 10, "hyperbolic")])
def test_stitch_kernel_agrees_with_reference(
    monkeypatch: pytest.MonkeyPatch, seed: int, m: int, dif: str
) -> None:
    """The pruned kernel keeps exactly the matches of the literal oracle, which lists
    every candidate of every model interval with all its triangle terms (the kernel
    skips candidates early and computes the gap terms lazily)."""
    from shapetree.detection._stitch import run_stitch
    from shapetree.detection._stitch_reference import reference_stitch

    args, kw = _stitch_inputs(monkeypatch, seed, m)
    kw = {**kw, "dif": dif}
    model, gw, base, piece_p, piece_q, piece_contour, piece_box, ends = args
    # piece costs of short intervals tie (the table of a one-segment match is 0), and
    # which of tied candidates is kept is arbitrary in both: break the ties
    base = base + np.random.default_rng(seed).uniform(0, 1e-6, base.shape)
    args = (model, gw, base, piece_p, piece_q, piece_contour, piece_box, ends)
    assert len(set(piece_contour.tolist())) < 128  # the kernel's contour hash is exact
    res = run_stitch(*args, **kw)
    ref = reference_stitch(
        model[:, 0] + 1j * model[:, 1],
        res.frac,
        res.gapc,
        base,
        piece_p,
        piece_q,
        piece_contour,
        piece_box,
        ends[:, 0] + 1j * ends[:, 1],
        res.near,
        kw["lam"],
        kw["beam"],
        kw["per_end"],
        kw["max_gap"],
        kw["gap_beam"],
        dif,
    )
    # every kind of composition is exercised, and many intervals had more candidates
    # than the kernel's heap holds (4 beam), so the early skips were taken
    kinds = np.bincount(res.kind, minlength=3)
    assert np.all(kinds > 20), kinds
    assert np.mean(np.bincount(res.a * (m + 1) + res.L) == kw["beam"]) > 0.5
    assert len(ref) == len(res.cost)
    for name in ("a", "L", "p", "q", "kind", "left", "right", "gap"):
        np.testing.assert_array_equal(getattr(res, name), [e[name] for e in ref], err_msg=name)
    np.testing.assert_allclose(res.cost, [e["cost"] for e in ref], rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(res.box, [e["box"] for e in ref])


def test_score_pool_suppresses_in_score_order() -> None:
    from shapetree.detection import DetectParams

    conts, true_box = _scene(2, removed=[(1.0, 1.6)], n_clutter=20)
    model = make_model(_shape(MODEL_T), m=24)
    image = np.zeros((320, 420))
    # the rotation-invariant stitching of the paper, so that only the order of the
    # suppression differs between the two runs (the scene's object stands turned by 20 deg)
    for prior in (0.075, 0.3):
        kw = dict(k=4, frame_prior=prior, upright_cost=0.0)
        cost_order = detect(model, image, contours=conts, score_pool=0, **kw)
        score_order = detect(model, image, contours=conts, **kw)
        assert len(score_order) == len(cost_order) == 4
        scores = [d.score for d in score_order]
        assert scores == sorted(scores, reverse=True)
        for i, d in enumerate(score_order):  # the suppression still holds
            for e in score_order[:i]:
                assert _iou(d.bbox, e.bbox) <= 0.3 + 1e-9
        # the object first either way, and on this scene every rank scores at least as
        # well when the score, not the cost, decides which overlapping box survives
        assert _iou(score_order[0].bbox, true_box) > 0.7
        assert score_order[0].score == pytest.approx(cost_order[0].score)
        assert all(a.score >= b.score - 1e-12 for a, b in zip(score_order, cost_order))
        assert sum(scores) > sum(d.score for d in cost_order)
    assert DetectParams().score_pool == 30  # the default; 0 is the paper's cost order
    for bad in (-1, 1.5, True):
        with pytest.raises(ShapeTreeError, match="score_pool"):
            DetectParams(score_pool=bad)


def _boxed(score: float, bbox: tuple[float, float, float, float]) -> Detection:
    pts = np.zeros((4, 2))
    return Detection(
        cost=-score,
        score=score,
        bbox=bbox,
        model_points=pts,
        image_points=pts,
        matched=np.ones(4, bool),
        gaps=[],
        coverage=1.0,
    )


def test_nms_nested_keeps_a_whole_beside_its_better_part() -> None:
    from shapetree.detection import DetectParams
    from shapetree.detection._detect import _suppress

    neck = _boxed(2.0, (40.0, 0.0, 60.0, 50.0))  # 1000 px2, wholly inside the animal
    whole = _boxed(1.0, (0.0, 0.0, 60.0, 50.0))  # 3000 px2: IoU with the neck 1/3 > 0.3
    shifted = _boxed(0.5, (50.0, 0.0, 70.0, 50.0))  # IoU 1/3 with the neck, half of it inside
    elsewhere = _boxed(0.2, (200.0, 200.0, 240.0, 260.0))
    ranked = [neck, whole, shifted, elsewhere]
    assert _suppress(ranked, 0.3, 5) == [neck, elsewhere]
    # the neck lies wholly inside the whole box: it no longer suppresses it; the shifted
    # box holds only half of the neck and is still suppressed at 0.8, kept at 0.5 (its
    # IoU with the whole box, 1/7, is below 0.3)
    assert _suppress(ranked, 0.3, 5, nested=0.8) == [neck, whole, elsewhere]
    assert _suppress(ranked, 0.3, 5, nested=0.5) == [neck, whole, shifted, elsewhere]
    # a box inside a kept whole is still suppressed by it (only the container is spared)
    assert _suppress([whole, neck], 0.3, 5, nested=0.8) == [whole]
    assert _suppress(ranked, 0.3, 2, nested=0.8) == [neck, whole]
    assert DetectParams().nms_nested is None  # off by default, and left out of the keys
    assert "nms_nested" not in DetectParams().as_dict()
    assert DetectParams(nms_nested=0.8).as_dict()["nms_nested"] == 0.8
    for bad in (0, -0.1, 1.5, float("nan"), True, "0.8"):
        with pytest.raises(ShapeTreeError, match="nms_nested"):
            DetectParams(nms_nested=bad)
    with pytest.raises(ShapeTreeError, match="score_pool"):
        DetectParams(nms_nested=0.8, score_pool=0)
