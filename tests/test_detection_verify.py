"""Verification of kept detections: shape contexts and their agreement (detection/_verify.py)."""

from __future__ import annotations

import numpy as np
import pytest

from shapetree import ShapeTreeError
from shapetree.curves import resample
from shapetree.detection import DetectParams, context_agreement, detect, shape_contexts
from shapetree.detection._verify import N_ANGULAR, N_RADIAL, _shape_contexts_reference


def _mug(m: int = 30) -> np.ndarray:
    """A boxy mug with a round handle on its right side (closed, counter-clockwise)."""
    t = np.linspace(-np.pi / 2, np.pi / 2, 40)
    handle = np.c_[1.0 + 0.45 * np.cos(t), 0.3 * np.sin(t)][::-1]
    body = np.array([[-1.0, -1.2], [1.0, -1.2], [1.0, -0.3]])
    top = np.array([[1.0, 1.2], [-1.0, 1.2]])
    return resample(np.vstack([body, handle[::-1], [[1.0, 0.3]], top]), m, closed=True)


def test_shape_contexts_equal_the_reference() -> None:
    rng = np.random.default_rng(3)
    for n in (3, 7, 30):
        p = rng.normal(size=(n, 2)) * [40.0, 25.0] + [100.0, 80.0]
        h = shape_contexts(p)
        assert h.shape == (n, N_RADIAL * N_ANGULAR)
        np.testing.assert_allclose(h, _shape_contexts_reference(p), atol=1e-12)
        s = h.sum(axis=1)
        assert np.all((np.abs(s - 1) < 1e-12) | (s == 0))


def test_agreement_is_one_for_a_moved_and_scaled_copy_and_symmetric() -> None:
    m = _mug()
    assert context_agreement(m, 37.0 * m + [210.0, -4.0]) == pytest.approx(1.0)
    rng = np.random.default_rng(0)
    noisy = m + rng.normal(scale=0.08, size=m.shape)
    a = context_agreement(m, noisy)
    assert 0.0 <= a < 1.0
    assert context_agreement(noisy, m) == pytest.approx(a)


def test_agreement_sees_orientation() -> None:
    # in the image frame on purpose: the same outline on its side agrees less
    m = _mug()
    rot = m @ np.array([[0.0, -1.0], [1.0, 0.0]])
    assert context_agreement(m, rot) < 0.6 * context_agreement(m, m)


def test_agreement_falls_as_the_mugs_handle_is_flattened() -> None:
    # The ETHZ false positive: a picture frame matched as the mug, the handle's samples
    # laid on the frame's straight side. Flattening the handle step by step lowers the
    # agreement at every step, to below that of a mug 5% wider.
    m = _mug()
    bulge = np.maximum(m[:, 0] - 1.0, 0.0)
    agree = []
    for f in (1.0, 0.5, 0.0):
        placed = m.copy()
        placed[:, 0] = np.minimum(m[:, 0], 1.0) + f * bulge
        agree.append(context_agreement(m, placed))
    assert agree[0] == pytest.approx(1.0)
    assert agree[0] > agree[1] > agree[2]
    assert agree[2] < context_agreement(m, m * [1.05, 1.0]) - 0.05


def test_bad_inputs_name_the_problem() -> None:
    m = _mug()
    with pytest.raises(ShapeTreeError, match=r"\(n, 2\)"):
        shape_contexts(np.zeros((5, 3)))
    with pytest.raises(ShapeTreeError, match="at least 3"):
        shape_contexts(np.zeros((2, 2)))
    with pytest.raises(ShapeTreeError, match="NaN"):
        context_agreement(m, np.where(np.arange(30)[:, None] == 3, np.nan, m))
    with pytest.raises(ShapeTreeError, match="coincide"):
        context_agreement(m, np.ones_like(m))
    with pytest.raises(ShapeTreeError, match="row by row"):
        context_agreement(m, m[:-1])
    with pytest.raises(ShapeTreeError, match="context_check"):
        detect(m, None, contours=[50 * m[:20] + 100], context_check=-1.0)


def test_context_check_only_adds_its_term_to_the_score() -> None:
    # A broken mug among clutter: with the paper's cost-order suppression (the ranking
    # terms then only re-order the kept matches) the kept detections are the same with
    # the term on or off, and each score differs by exactly context_check * agreement.
    rng = np.random.default_rng(5)
    m = _mug(60)
    placed = 60.0 * m + [200.0, 150.0]
    pieces = [placed[0:18], placed[20:40], placed[42:58]]
    clutter = [
        rng.uniform([0, 0], [400, 300]) + np.linspace(0, 1, 25)[:, None] * rng.uniform(-60, 60, 2)
        for _ in range(8)
    ]
    conts = pieces + clutter
    on = detect(m, None, contours=conts, k=3, score_pool=0)
    off = detect(m, None, contours=conts, k=3, score_pool=0, context_check=0.0)
    assert len(on) == len(off) >= 1
    w = DetectParams().context_check
    assert w > 0
    by_box = {tuple(np.round(d.bbox, 6)): d for d in off}
    for d in on:
        d0 = by_box[tuple(np.round(d.bbox, 6))]
        agree = context_agreement(d.model_points, d.image_points)
        assert d.score == pytest.approx(d0.score + w * agree, abs=1e-9)
