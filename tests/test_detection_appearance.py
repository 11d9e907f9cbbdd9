"""The collection stage: appearance agreement across photos (``detection._appearance``)."""

from __future__ import annotations

import numpy as np
import pytest

from shapetree import ShapeTreeError
from shapetree.detection import (
    DetectParams,
    appearance_agreement,
    collection_scores,
    colour_bins,
    interior_histogram,
)

RED, GREY = (0.9, 0.1, 0.1), (0.5, 0.5, 0.5)


def _square(x0: float, y0: float, side: float) -> np.ndarray:
    return np.array([[x0, y0], [x0 + side, y0], [x0 + side, y0 + side], [x0, y0 + side]])


def test_colour_bins_known_colours_and_shapes() -> None:
    img = np.zeros((2, 3, 3))
    img[0, 0] = (1, 1, 1)  # white: L = 100, the last L bin
    img[0, 1] = RED
    bins = colour_bins(img)
    assert bins.shape == (2, 3) and bins.dtype.kind == "i"
    assert bins[0, 0] // 64 == 7 and bins[1, 2] // 64 == 0  # white, black (L only)
    assert bins[0, 1] // 8 % 8 >= 6  # red: a* about +60 or more, the top a bins
    assert np.array_equal(colour_bins(np.full((4, 4), 0.5)), colour_bins(np.full((4, 4, 3), 0.5)))
    with pytest.raises(ShapeTreeError, match=r"\(H, W\) or \(H, W, 3\)"):
        colour_bins(np.zeros((4, 4, 2)))


def test_interior_histogram_sees_inside_not_the_rim() -> None:
    img = np.ones((60, 60, 3)) * GREY
    img[10:50, 10:50] = RED
    img[10:12, 10:50] = (0, 0, 1)  # a blue rim, inside the outline but within 2 px of it
    bins = colour_bins(img)
    h = interior_histogram(bins, _square(10, 10, 40))
    assert h.shape == (512,) and h.sum() == pytest.approx(1.0)
    red_bin = bins[30, 30]
    assert h[red_bin] == pytest.approx(1.0)  # neither the grey outside nor the rim
    assert interior_histogram(bins, _square(200, 200, 10)).sum() == 0.0  # off the image
    tiny = interior_histogram(bins, _square(20, 20, 3))  # < 10 px inside the margin: all of it
    assert tiny[red_bin] == pytest.approx(1.0)
    with pytest.raises(ShapeTreeError, match="NaN"):
        interior_histogram(bins, [[0, 0], [np.nan, 1], [2, 2]])
    with pytest.raises(ShapeTreeError, match=r"\(m >= 3, 2\)"):
        interior_histogram(bins, [[0, 0], [1, 1]])


def test_agreement_against_a_direct_reading_of_the_rule() -> None:
    rng = np.random.default_rng(3)
    n = 14
    keys = [f"img{i % 6}" for i in range(n)]
    scores = rng.normal(size=n)
    hists = rng.random((n, 8))
    hists /= hists.sum(1, keepdims=True)
    for reference in (1, 3, 10):
        got = appearance_agreement(keys, scores, hists, reference=reference)
        # oracle: each image's best detection; the reference+1 best of those; drop own image
        best = {
            k: max((i for i in range(n) if keys[i] == k), key=lambda i: scores[i])
            for k in set(keys)
        }
        ref = sorted(best.values(), key=lambda i: -scores[i])[: reference + 1]
        for i in range(n):
            others = [r for r in ref if keys[r] != keys[i]][:reference]
            want = np.mean([np.minimum(hists[i], hists[r]).sum() for r in others])
            assert got[i] == pytest.approx(want)
        assert ((got >= 0) & (got <= 1 + 1e-12)).all()
    # identical looks agree fully; one image alone has nothing to compare with
    same = np.tile(hists[:1], (4, 1))
    assert appearance_agreement(["a", "b", "c", "d"], [1, 2, 3, 4], same) == pytest.approx(1.0)
    assert appearance_agreement(["a", "a"], [1, 2], hists[:2]).tolist() == [0.0, 0.0]


def test_agreement_errors_name_the_problem() -> None:
    h = np.full((3, 4), 0.25)
    with pytest.raises(ShapeTreeError, match="do not match"):
        appearance_agreement(["a", "b"], [1, 2, 3], h)
    with pytest.raises(ShapeTreeError, match="integer >= 1"):
        appearance_agreement(["a", "b", "c"], [1, 2, 3], h, reference=0)
    with pytest.raises(ShapeTreeError, match="NaN"):
        appearance_agreement(["a", "b", "c"], [1, np.nan, 3], h)
    with pytest.raises(ShapeTreeError, match="finite number >= 0"):
        collection_scores(["a", "b", "c"], [1, 2, 3], h, appearance_check=-0.1)
    with pytest.raises(ShapeTreeError, match="appearance_check"):
        DetectParams(appearance_check=float("inf"))
    with pytest.raises(ShapeTreeError, match="appearance_reference"):
        DetectParams(appearance_reference=0)


def test_consistent_object_outranks_one_off_distractors() -> None:
    """Six photos, each with a red object and a distractor of its own colour. In two of
    them the distractor scores a little higher; across the collection the red objects
    agree with each other and the distractors with nothing, so every object ranks above
    every distractor once the collection stage is on, and not before."""
    rng = np.random.default_rng(0)
    keys, scores, hists, is_obj = [], [], [], []
    for i in range(6):
        img = np.ones((80, 160, 3)) * GREY
        img[20:60, 10:50] = RED + rng.normal(0, 0.02, (40, 40, 3))
        img[20:60, 100:140] = rng.random(3)  # the distractor's colour: this photo's own
        bins = colour_bins(np.clip(img, 0, 1))
        obj, dis = 1.0 + 0.01 * i, 1.0 + (0.05 if i < 2 else -0.05)
        for pts, s, o in ((_square(10, 20, 40), obj, True), (_square(100, 20, 40), dis, False)):
            keys.append(f"photo{i}")
            scores.append(s)
            hists.append(interior_histogram(bins, pts))
            is_obj.append(o)
    is_obj = np.array(is_obj)
    plain, ag = collection_scores(keys, scores, np.array(hists), appearance_check=0.0)
    assert plain.tolist() == scores and plain[~is_obj].max() > plain[is_obj].min()
    cs, ag = collection_scores(keys, scores, np.array(hists), appearance_check=0.4)
    assert ag[is_obj].min() > 0.5 > ag[~is_obj].max()
    assert cs[is_obj].min() > cs[~is_obj].max()
    assert cs == pytest.approx(np.array(scores) + 0.4 * ag)
