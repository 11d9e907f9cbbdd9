"""End-to-end detection on a few real ETHZ images (skipped when the data is absent)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from shapetree import ImageError, ShapeTreeError
from shapetree.detection import detect, detect_to_files, dr_at_fppi, dr_fppi_curve, load_model
from shapetree.detection._ethz_eval import recall_any
from shapetree.detection._model import outline_strokes

_DEFAULT = Path(__file__).resolve().parents[1] / ".." / "shared" / "datasets"
DATA = Path(os.environ.get("SHAPETREE_DATA", _DEFAULT))
ROOT = DATA / "ethz_shape" / "ETHZShapeClasses-V1.2"
needs_data = pytest.mark.skipif(not (ROOT / "models").is_dir(), reason="ETHZ data not available")


def _iou(a, b) -> float:
    ix = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = ix * iy
    return inter / ((a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter)


def _image_size(path: Path) -> tuple[int, int]:
    from PIL import Image

    with Image.open(path) as im:
        return im.size


RANKINGS = {
    "default": {},
    "cost alone": {"frame_prior": 0.0, "outline_check": 0.0, "context_check": 0.0},
    "frame prior only": {"outline_check": 0.0, "context_check": 0.0},
}


@needs_data
@pytest.mark.parametrize("ranking", list(RANKINGS))
@pytest.mark.parametrize("stem", ["aal", "big", "blackneck"])
def test_swan_detections_find_the_swan(stem: str, ranking: str) -> None:
    """Behaviour, under every ranking: some top-3 detection is the swan (ETHZ 20% rule).

    The detections are sorted by score (best first), have finite scores and costs, their
    matched image points lie inside the image, and their boxes are the extent of their
    placed points (a gap's points, placed by the similarity fitted to the matched ones,
    may fall past the border, as a partly visible object's would).
    """
    model = load_model(ROOT / "models" / "swan.tif")
    gt = np.loadtxt(ROOT / "Swans" / f"{stem}_swans.groundtruth", ndmin=2)
    w, h = _image_size(ROOT / "Swans" / f"{stem}.jpg")
    edges = ROOT / "Swans" / f"{stem}_edges.tif"
    dets = detect(model, None, edges=edges, k=3, **RANKINGS[ranking])
    assert 1 <= len(dets) <= 3
    scores = [d.score for d in dets]
    assert all(np.isfinite(scores)) and all(np.isfinite(d.cost) for d in dets)
    assert scores == sorted(scores, reverse=True)
    for d in dets:
        pts = np.asarray(d.image_points)
        assert pts.shape == (len(model.points), 2) and np.isfinite(pts).all()
        on = pts[np.asarray(d.matched)]
        assert len(on) and (on >= 0).all() and (on[:, 0] <= w).all() and (on[:, 1] <= h).all()
        # the match's box is the box of its placement; a refined box lies in the image
        assert d.match_box == pytest.approx((*pts.min(0), *pts.max(0)))
        x1, y1, x2, y2 = d.bbox
        assert x1 < w and y1 < h and x2 > 0 and y2 > 0, (d.bbox, (w, h))
        if d.match_bbox is not None:
            assert 0 <= x1 < x2 <= w and 0 <= y1 < y2 <= h
    assert max(_iou(d.bbox, g) for d in dets for g in gt) >= 0.2


@needs_data
@pytest.mark.parametrize("stem", ["aal", "big", "blackneck"])
def test_swan_ranking_terms_only_reorder(stem: str) -> None:
    """Under the paper's cost-order suppression (``score_pool=0``) the ranking terms
    re-order the kept detections, never change them (which benchmarks/ethz_rescore.py
    relies on); with the default ranking (score order) the best detection is the swan."""
    model = load_model(ROOT / "models" / "swan.tif")
    gt = np.loadtxt(ROOT / "Swans" / f"{stem}_swans.groundtruth", ndmin=2)
    edges = ROOT / "Swans" / f"{stem}_edges.tif"
    off = dict(frame_prior=0.0, outline_check=0.0, context_check=0.0)
    plain = detect(model, None, edges=edges, k=3, score_pool=0, **off)
    dets = detect(model, None, edges=edges, k=3, score_pool=0)
    assert sorted(d.cost for d in dets) == pytest.approx(sorted(d.cost for d in plain))
    assert sorted(map(tuple, (d.bbox for d in dets))) == sorted(map(tuple, (d.bbox for d in plain)))
    assert max(_iou(dets[0].bbox, g) for g in gt) >= 0.2
    best = detect(model, None, edges=edges, k=3)[0]
    assert max(_iou(best.bbox, g) for g in gt) >= 0.2


@needs_data
def test_evaluate_ethz_cache_default_and_key(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Default cache under $SHAPETREE_CACHE/ethz_detect, keyed by the code fingerprint;
    a second run reads it back instead of detecting again."""
    import shapetree.detection._ethz_eval as ev

    monkeypatch.setenv("SHAPETREE_CACHE", str(tmp_path / "c"))
    kw = dict(classes=["swans"], images=[("Swans", "aal")], workers=1, progress=False, k=2)
    first = ev.evaluate_ethz(DATA, **kw)
    cache = Path(first["cache_dir"])
    assert cache.parent == tmp_path / "c" / "ethz_detect"
    assert (cache / "swans" / "Swans__aal.json").is_file()
    assert first["overlap_20"]["recall_any_k"]["swans"] == 1.0
    assert first["ranked_by"] == "score"  # one image: no collection to compare with
    assert not list(cache.rglob("*.tmp"))

    def no_detection(*args, **kwargs):
        raise AssertionError("cached result not reused")

    monkeypatch.setattr(ev, "detect_detailed", no_detection)
    again = ev.evaluate_ethz(DATA, **kw)
    assert again["cache_dir"] == str(cache)
    assert again["overlap_20"] == first["overlap_20"]
    # other code (another version, an edit) -> another key: the old results are not reused
    monkeypatch.setattr(ev, "code_fingerprint", lambda: "0" * 64)
    with pytest.raises(AssertionError, match="not reused"):
        ev.evaluate_ethz(DATA, **kw)
    # an explicit cache_dir still wins
    monkeypatch.undo()
    monkeypatch.setenv("SHAPETREE_CACHE", str(tmp_path / "c"))
    mine = ev.evaluate_ethz(DATA, cache_dir=tmp_path / "mine", **kw)
    assert Path(mine["cache_dir"]).parent == tmp_path / "mine"


@needs_data
def test_evaluate_ethz_pictures(tmp_path: Path) -> None:
    """out_dir gets the DR/FPPI curves and the swan gallery, drawn by shapetree.plotting."""
    from PIL import Image

    import shapetree.detection._ethz_eval as ev

    imgs = [("Swans", "aal"), ("Swans", "big")]
    kw = dict(classes=["swans"], images=imgs, workers=1, progress=False, k=1)
    ev.evaluate_ethz(DATA, out_dir=tmp_path / "fig", cache_dir=tmp_path / "c", **kw)
    names = sorted(p.name for p in (tmp_path / "fig").iterdir())
    assert names == ["ethz_dr_fppi.png", "ethz_gallery_swans.png"]
    for name in names:
        with Image.open(tmp_path / "fig" / name) as im:
            assert im.format == "PNG" and im.width > 300


@needs_data
def test_models_from_outlines() -> None:
    for name, closed in [("swan", True), ("bottle", True), ("mug", True), ("giraffe", False)]:
        m = load_model(ROOT / "models" / f"{name}.tif", m=30)
        assert m.closed is closed
        assert m.points.shape == (30, 2)
        assert m.gap_weight.sum() == pytest.approx(1.0)
        if not closed:
            # segments on the free chords (between strokes, closing) weigh less
            assert m.gap_weight.min() < 0.5 * m.gap_weight.max()
    # the giraffe drawing: outer outline + a separate belly / inner-legs stroke, both kept
    strokes, closed = outline_strokes(ROOT / "models" / "giraffe.tif")
    assert closed is False and len(strokes) == 2
    gir = load_model(ROOT / "models" / "giraffe.tif", m=40, all_strokes=True)
    span = np.ptp(gir.curve, axis=0)
    assert len(gir.curve) == sum(len(s) for s in strokes) and span.min() > 150


@needs_data
def test_detect_to_files_writes_png_and_json(tmp_path: Path) -> None:
    out_png, out_json = tmp_path / "d.png", tmp_path / "d.json"
    dets = detect_to_files(
        ROOT / "models" / "swan.tif",
        ROOT / "Swans" / "aal.jpg",
        edges_path=ROOT / "Swans" / "aal_edges.tif",
        out_png=out_png,
        out_json=out_json,
        k=2,
    )
    assert out_png.stat().st_size > 1000
    doc = json.loads(out_json.read_text())
    assert len(doc["detections"]) == len(dets) >= 1
    d0 = doc["detections"][0]
    assert set(d0) >= {"score", "bbox", "model_points", "image_points", "gaps"}
    assert not list(tmp_path.glob(".*.tmp"))
    with pytest.raises(ImageError):
        detect_to_files(ROOT / "models" / "swan.tif", tmp_path / "missing.jpg", out_json=out_json)


def test_dr_fppi_curve_counts() -> None:
    gts = {"a": np.array([[0, 0, 10, 10.0]]), "b": np.zeros((0, 4))}
    dets = [("a", 0.9, [0, 0, 10, 10]), ("a", 0.8, [0, 0, 10, 10]), ("b", 0.7, [0, 0, 5, 5])]
    fppi, dr, _ = dr_fppi_curve(dets, gts, n_images=2, iou_thr=0.5)
    assert dr.tolist() == [1.0, 1.0, 1.0]
    assert fppi.tolist() == [0.0, 0.5, 1.0]  # a duplicate is a false positive
    assert dr_at_fppi(fppi, dr, 0.3) == 1.0
    assert dr_at_fppi(np.array([0.5]), np.array([1.0]), 0.4) == 0.0


def test_greedy_claims_best_first_each_box_once() -> None:
    """Best score first; each detection claims the unclaimed box it overlaps most; a box is
    claimed once; ``n`` stops the claim after the n best (the curve's own claim)."""
    from shapetree.detection._ethz_eval import greedy_claims

    gts = {"a": np.array([[0, 0, 10, 10.0], [8, 0, 18, 10.0]])}
    dets = [
        ("a", 0.5, [8, 0, 18, 10]),  # second: box 1 exactly
        ("a", 0.9, [0, 0, 12, 10]),  # first: more of box 0 than of box 1
        ("a", 0.1, [8, 0, 18, 10]),  # third: box 1 taken, box 0 below the threshold
    ]
    order, hit, claimed = greedy_claims(dets, gts, 0.5)
    assert order == [1, 0, 2] and hit.tolist() == [True, True, False]
    assert claimed["a"].tolist() == [True, True]
    order, hit, claimed = greedy_claims(dets, gts, 0.5, n=1)
    assert order == [1] and claimed["a"].tolist() == [True, False]
    fppi, dr, scores = dr_fppi_curve(dets, gts, n_images=1, iou_thr=0.5)
    assert dr.tolist() == [0.5, 1.0, 1.0] and scores.tolist() == [0.9, 0.5, 0.1]


def test_recall_any_is_the_ceiling_of_the_curve() -> None:
    gts = {"a": np.array([[0, 0, 10, 10.0]]), "b": np.array([[0, 0, 10, 10.0], [20, 20, 30, 30.0]])}
    dets = [
        ("b", 0.9, [0, 0, 5, 5]),  # IoU 0.25: a hit at 0.2, a miss at 0.5
        ("a", 0.1, [0, 0, 10, 10]),  # ranked last, still counts for the ceiling
        ("b", 0.5, [40, 40, 50, 50]),  # overlaps nothing
    ]
    assert recall_any(dets, gts, 0.2) == pytest.approx(2 / 3)
    assert recall_any(dets, gts, 0.5) == pytest.approx(1 / 3)
    fppi, dr, _ = dr_fppi_curve(dets, gts, n_images=2, iou_thr=0.2)
    assert dr.max() == pytest.approx(recall_any(dets, gts, 0.2))
    assert recall_any([], {"a": np.zeros((0, 4))}, 0.5) == 0.0


@needs_data
def test_evaluate_ethz_collection_stage_reranks_the_cache(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Over several images the detections are ranked by their collection score (the
    re-scorer by default), and other collection settings re-rank the cached detections
    without detecting again (the cache key leaves the collection fields out)."""
    import shapetree.detection._ethz_eval as ev
    from shapetree.detection import RESCORER_WEIGHTS

    imgs = [("Swans", "aal"), ("Swans", "blackneck"), ("Mugs", "apple")]
    kw = dict(classes=["swans"], images=imgs, workers=1, progress=False, k=3)
    kw["cache_dir"] = tmp_path / "c"
    on = ev.evaluate_ethz(DATA, **kw)
    assert on["ranked_by"] == "collection_score" and on["params"]["collection_rescore"]
    assert "re-scorer" in on["ranked_by_note"]
    assert on["seconds_breakdown_median"]["appearance"] > 0

    def no_detection(*args, **kwargs):
        raise AssertionError("cached result not reused")

    monkeypatch.setattr(ev, "detect_detailed", no_detection)
    colour = ev.DetectParams(collection_rescore=False, appearance_check=0.4)
    col = ev.evaluate_ethz(DATA, params=colour, **kw)
    assert col["ranked_by"] == "collection_score" and col["cache_dir"] == on["cache_dir"]
    off = ev.evaluate_ethz(DATA, params=ev.DetectParams(collection_rescore=False), **kw)
    assert off["cache_dir"] == on["cache_dir"] and off["ranked_by"] == "score"
    assert off["overlap_20"]["recall_any_k"] == on["overlap_20"]["recall_any_k"]
    assert off["seconds_breakdown_median"]["appearance"] == 0.0
    # the re-ranked detections carry their terms, and the collection score is their form
    results: dict = {}
    real = ev._collection_rank

    def keep(res, *args):
        real(res, *args)
        results.update(res)

    monkeypatch.setattr(ev, "_collection_rank", keep)
    ev.evaluate_ethz(DATA, **kw)
    dets = [d for doc in results.values() for d in doc["detections"]]
    # k = 3 per image, fewer where the suppression leaves fewer (8 with the shipped settings)
    assert len(results) == 3 and all(1 <= len(doc["detections"]) <= 3 for doc in results.values())
    for d in dets:
        want = d["base"] + sum(w * d[t] for t, w in RESCORER_WEIGHTS.items())
        assert d["collection_score"] == pytest.approx(want)
        assert d["base"] == pytest.approx(d["score"] - 0.15 * d["context"])
        assert 0.0 <= d["template"] <= 1.0 and 0.0 <= d["box_density"] <= 1.0
    for doc in results.values():
        cs = [d["collection_score"] for d in doc["detections"]]
        assert cs == sorted(cs, reverse=True)


@needs_data
@pytest.mark.parametrize("edges", ["pb", "own"])
def test_evaluate_ethz_swan_with_either_edge_source(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, edges: str
) -> None:
    """The protocol on two swan images with the shipped Pb maps and with the project's own
    edge map computed from the photos: both find both swans among an image's detections
    (20% rule; Pb: DR 1 at 0.4 FPPI), the results say which source and time every stage,
    and the two sources never share a cache folder.  ``k = 5`` as in the protocol: with
    the own map, aal's swan is the 4th hypothesis by stitched cost and the first after
    verification (which re-orders only the kept ones)."""
    import shapetree.detection._ethz_eval as ev

    monkeypatch.setenv("SHAPETREE_CACHE", str(tmp_path / "c"))
    kw = dict(classes=["swans"], images=[("Swans", "aal"), ("Swans", "blackneck")], k=5)
    res = ev.evaluate_ethz(DATA, workers=1, progress=False, edges=edges, **kw)
    assert res["edges"] == edges
    assert res["overlap_20"]["recall_any_k"]["swans"] == 1.0
    assert res["overlap_20"]["dr_fppi_0.4"]["swans"] >= (1.0 if edges == "pb" else 0.5)
    assert set(res["seconds_breakdown_median"]) == set(ev.STAGES) == set(res["stages"])
    assert res["seconds_breakdown_median"]["stitch"] > 0
    if edges == "own":  # computing the edge map is a real stage; reading Pb is not
        assert res["seconds_breakdown_median"]["edges"] > 0.01
    other = "pb" if edges == "own" else "own"
    assert ev._params_key(ev.DetectParams(), 3, edges) != ev._params_key(
        ev.DetectParams(), 3, other
    )
    with pytest.raises(ShapeTreeError, match="unknown edge source"):
        ev.evaluate_ethz(DATA, edges="canny", **kw)


@needs_data
def test_own_edges_find_the_swan_on_water() -> None:
    """Swans/aal, a swan on rippled water: with the own edge map the best detection is the
    swan (the plain gradient map's was on the neck and the rocks)."""
    model = load_model(ROOT / "models" / "swan.tif")
    gt = np.loadtxt(ROOT / "Swans" / "aal_swans.groundtruth", ndmin=2)
    dets = detect(model, ROOT / "Swans" / "aal.jpg", k=5, edge_method="own")
    assert _iou(dets[0].bbox, gt[0]) >= 0.5


@needs_data
@pytest.mark.parametrize("stem", ["snack", "sun"])
def test_box_refinement_reports_the_whole_giraffe(stem: str) -> None:
    """Two photos where the best match covers the giraffe's neck and back: the reported
    box is the whole animal's (IoU >= 0.5 with the ground truth, PASCAL's hit) while the
    match's own box is not, and the match, its score and its box are those of the run
    without the refinement."""
    model = load_model(ROOT / "models" / "giraffe.tif")
    gt = np.loadtxt(ROOT / "Giraffes" / f"{stem}_giraffes.groundtruth", ndmin=2)
    edges = ROOT / "Giraffes" / f"{stem}_edges.tif"
    best = detect(model, None, edges=edges, k=2)[0]
    plain = detect(model, None, edges=edges, k=2, box_refine=None)[0]
    assert best.match_bbox is not None and plain.match_bbox is None
    assert best.match_box == pytest.approx(plain.bbox) and best.score == plain.score
    assert max(_iou(best.bbox, g) for g in gt) >= 0.5
    assert max(_iou(best.match_box, g) for g in gt) < 0.5
