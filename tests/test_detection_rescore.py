"""The collection re-scorer (``detection._rescore``)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from shapetree import ShapeTreeError
from shapetree.detection import (
    RESCORER_WEIGHTS,
    DetectParams,
    context_agreement,
    detection_terms,
    rescore_collection,
)
from shapetree.detection._detect import frame_term
from shapetree.detection._rescore import collection_table
from shapetree.geometry import outline_dif

RESULTS = Path(__file__).resolve().parents[1] / "benchmarks" / "results"
TERMS = (
    "context",
    "outline_dif",
    "frame",
    "coverage",
    "appearance",
    "template",
    "template_support",
    "template_gain",
    "box_density",
)


def _terms(n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    return {
        "context": rng.uniform(0, 1, n),
        "outline_dif": rng.uniform(0, 0.5, n),
        "frame": rng.uniform(-2, 0, n),
        "coverage": rng.uniform(0.3, 1, n),
        "appearance": rng.uniform(0, 1, n),
        "template": rng.uniform(0, 1, n),
        "template_support": rng.uniform(0, 1, n),
        "template_gain": rng.uniform(-0.3, 0.3, n),
        "box_density": rng.uniform(0, 0.3, n),
    }


def test_collection_score_is_the_documented_linear_form() -> None:
    """Against a direct reading of the rule: base = score - context_check * context;
    margin and lead from the bases within each image; then base + sum of weights."""
    rng = np.random.default_rng(3)
    keys = ["a", "a", "a", "b", "c", "c"]
    scores = rng.normal(-0.5, 0.1, len(keys))
    terms = _terms(len(keys), rng)
    cs, table = rescore_collection(keys, scores, terms, context_check=0.15)
    for i, k in enumerate(keys):
        base = scores[i] - 0.15 * terms["context"][i]
        mine = sorted(
            (scores[j] - 0.15 * terms["context"][j] for j in range(len(keys)) if keys[j] == k),
            reverse=True,
        )
        margin = base - mine[0]
        lead = mine[0] - mine[1] if base == mine[0] and len(mine) > 1 else 0.0
        want = base + RESCORER_WEIGHTS["margin"] * margin + RESCORER_WEIGHTS["lead"] * lead
        want += sum(RESCORER_WEIGHTS.get(t, 0.0) * terms[t][i] for t in TERMS)  # 0: unweighted
        assert table["base"][i] == pytest.approx(base)
        assert table["margin"][i] == pytest.approx(margin)
        assert table["lead"][i] == pytest.approx(lead)
        assert cs[i] == pytest.approx(want)
    assert table["lead"][keys.index("b")] == 0.0  # an image's only detection leads nothing


def test_weights_reward_agreement_and_penalise_distortion() -> None:
    """Raising a term that says "this is the object" raises the collection score,
    raising the outline distortion lowers it; the sign of every weight is as fitted."""
    rng = np.random.default_rng(4)
    keys = [f"img{i}" for i in range(4)]
    scores = rng.normal(-0.5, 0.1, 4)
    terms = _terms(4, rng)
    cs, _ = rescore_collection(keys, scores, terms, context_check=0.0)
    for t, sign in (("context", 1), ("coverage", 1), ("appearance", 1), ("outline_dif", -1)):
        bumped = dict(terms, **{t: terms[t] + 0.1})
        cs2, _ = rescore_collection(keys, scores, bumped, context_check=0.0)
        assert np.all(np.sign(cs2 - cs) == sign), t


def test_weights_are_the_committed_fit() -> None:
    """The constants are the committed fit of ``benchmarks/ethz_within_image.py``
    (``fit_all``): the global logistic fit over its term set plus ``gamma`` times the
    within-image fit over the twelve terms, each divided by its score's standard deviation,
    per unit of each term, scaled so ``base`` weighs 1, to the 4 decimals they are written
    with. Recomputed here from the two fits' full-precision constants."""
    fit = json.loads((RESULTS / "ethz_within_image_pb_upright_0.25.json").read_text())["fit_all"]
    assert fit["combination"] == f"sum_{fit['gamma']:g}"
    per_unit: dict[str, float] = {}
    for part, scale in (("global_fit", 1.0), ("within_fit", fit["gamma"])):
        f = fit[part]
        for t, w, sd in zip(f["terms"], f["weights"], f["std"], strict=True):
            per_unit[t] = per_unit.get(t, 0.0) + scale * w / sd / f["score_std"]
    base = per_unit.pop("base")
    assert base > 0
    assert set(per_unit) == set(RESCORER_WEIGHTS)
    for t, w in per_unit.items():
        assert RESCORER_WEIGHTS[t] == pytest.approx(w / base, abs=6e-5), t
        assert fit["weights_base_1"][t] == pytest.approx(w / base, abs=6e-5), t


def test_detection_terms_are_the_detector_quantities() -> None:
    rng = np.random.default_rng(5)
    t = np.linspace(0, 2 * np.pi, 30, endpoint=False)
    model = np.c_[np.cos(t), 1.5 * np.sin(t)]
    placed = 40 * model + [100, 80] + rng.normal(0, 1.5, model.shape)
    bbox = (*placed.min(0), *placed.max(0))
    got = detection_terms(model, placed, bbox, 0.8, (200, 300))
    assert got["context"] == pytest.approx(context_agreement(model, placed))
    assert got["outline_dif"] == pytest.approx(outline_dif(model, placed))
    assert got["frame"] == pytest.approx(frame_term(bbox, (200, 300)))
    assert got["coverage"] == 0.8
    # a placement collapsed to a point agrees in nothing (no error)
    flat = np.zeros_like(model) + 5.0
    assert detection_terms(model, flat, (5, 5, 5, 5), 0.3, (20, 20))["context"] == 0.0


def test_collection_table_modes() -> None:
    """The re-scorer by default; ``collection_rescore=False`` gives score +
    appearance_check * agreement."""
    t = np.linspace(0, 2 * np.pi, 20, endpoint=False)
    model = np.c_[np.cos(t), np.sin(t)]
    dets, keys = [], []
    for i, s in enumerate((-0.4, -0.6, -0.5)):
        pts = 30 * model + 50 + i
        dets.append(
            {
                "score": s,
                "bbox": [*pts.min(0), *pts.max(0)],
                "coverage": 0.9,
                "image_points": pts.tolist(),
                "template": 0.5 + 0.1 * i,
                "template_support": 0.6,
                "template_gain": 0.1 * i,
                "box_density": 0.05,
            }
        )
        keys.append(f"im{i % 2}")
    hists = np.full((3, 4), 0.25)
    shapes = {"im0": (120, 120), "im1": (120, 120)}
    cs, table = collection_table(keys, dets, model, shapes, hists, DetectParams())
    assert {"base", "margin", "lead", "appearance", *TERMS} <= set(table)
    assert table["appearance"] == pytest.approx(1.0)  # identical histograms
    ref, _ = rescore_collection(
        keys, [d["score"] for d in dets], {k: table[k] for k in TERMS}, 0.15
    )
    assert cs == pytest.approx(ref)
    p = DetectParams(collection_rescore=False, appearance_check=0.4)
    cs2, table2 = collection_table(keys, dets, model, shapes, hists, p)
    assert set(table2) == {"appearance"}
    assert cs2 == pytest.approx(np.array([-0.4, -0.6, -0.5]) + 0.4)
    old = [{k: v for k, v in d.items() if k != "template_gain"} for d in dets]
    with pytest.raises(ShapeTreeError, match="no 'template_gain'"):
        collection_table(keys, old, model, shapes, hists, DetectParams())
    # a refined box (box_refine) changes what is reported, not the terms: they are
    # computed from the match's box, so the collection scores stay the same
    grown = [{**d, "bbox": [0.0, 0.0, 120.0, 120.0], "match_bbox": d["bbox"]} for d in dets]
    cs3, table3 = collection_table(keys, grown, model, shapes, hists, DetectParams())
    assert cs3 == pytest.approx(cs)
    assert table3["frame"] == pytest.approx(table["frame"])
    moved = [{**d, "bbox": [0.0, 0.0, 120.0, 120.0]} for d in dets]  # no match_bbox
    assert not np.allclose(
        collection_table(keys, moved, model, shapes, hists, DetectParams())[0], cs
    )


def test_errors_name_the_problem() -> None:
    rng = np.random.default_rng(6)
    terms = _terms(3, rng)
    with pytest.raises(ShapeTreeError, match=r"\['coverage'\] missing"):
        rescore_collection("abc", [1, 2, 3], {k: v for k, v in terms.items() if k != "coverage"}, 0)
    with pytest.raises(ShapeTreeError, match="context has shape"):
        rescore_collection("abc", [1, 2, 3], dict(terms, context=[1.0, 2.0]), 0)
    with pytest.raises(ShapeTreeError, match="NaN or infinite values in scores"):
        rescore_collection("abc", [1, np.nan, 3], terms, 0)
    with pytest.raises(ShapeTreeError, match="has its own colour weight"):
        DetectParams(appearance_check=0.4)
    with pytest.raises(ShapeTreeError, match="collection_rescore must be True or False"):
        DetectParams(collection_rescore="yes")
    p = DetectParams(collection_rescore=False)
    assert not p.collection_stage and DetectParams().collection_stage
    assert DetectParams(collection_rescore=False, appearance_check=0.4).collection_stage
