"""End-to-end detection on a few real ETHZ images (skipped when the data is absent)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from shapetree import ImageError
from shapetree.detection import (
    detect,
    detect_to_files,
    dr_at_fppi,
    dr_fppi_curve,
    load_model,
    outline_strokes,
    recall_any,
)

_DEFAULT = Path(__file__).resolve().parents[1] / ".." / "shared" / "datasets"
DATA = Path(os.environ.get("SHAPETREE_DATA", _DEFAULT))
ROOT = DATA / "ethz_shape" / "ETHZShapeClasses-V1.2"
needs_data = pytest.mark.skipif(not (ROOT / "models").is_dir(), reason="ETHZ data not available")


def _iou(a, b) -> float:
    ix = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = ix * iy
    return inter / ((a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter)


@needs_data
@pytest.mark.parametrize("stem", ["aal", "big", "blackneck"])
def test_swan_best_detection_overlaps_ground_truth(stem: str) -> None:
    model = load_model(ROOT / "models" / "swan.tif")
    gt = np.loadtxt(ROOT / "Swans" / f"{stem}_swans.groundtruth", ndmin=2)
    # ranked by cost alone (no ranking terms), the best detection is the swan in all three
    # (measured in the full ETHZ run: IoU 0.72, 0.88, 0.94); the 20% rule is asserted
    edges = ROOT / "Swans" / f"{stem}_edges.tif"
    plain = detect(model, None, edges=edges, k=3, frame_prior=0.0, outline_check=0.0)
    assert plain and max(_iou(plain[0].bbox, g) for g in gt) >= 0.2
    # the default ranking terms keep the same detections and the swan first; in "big" the
    # frame prior alone would put a frame-filling person (cost 0.366 vs 0.340) ahead of
    # the small swan, and the outline check puts the swan back in front
    dets = detect(model, None, edges=edges, k=3)
    assert sorted(d.cost for d in dets) == pytest.approx(sorted(d.cost for d in plain))
    assert max(_iou(dets[0].bbox, g) for g in gt) >= 0.2
    if stem == "big":
        framed = detect(model, None, edges=edges, k=3, outline_check=0.0)
        assert max(_iou(framed[0].bbox, g) for g in gt) < 0.2


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
