"""The pruned ``band`` mode: what it must keep of exact matching.

A band only removes admissible target lengths, so its optimum is over a subset of the
exact one's matchings: it is never cheaper than exact matching, never cheaper for a
narrower band, equal to it for a band wide enough to remove nothing, and every entry
point (``match_cost``, ``match_prepared`` with its traceback, ``ModelStack``) must agree
on it, also with occlusion. The traceback's correspondence, scored literally by the
oracle (:func:`shapetree.matching._reference.reference_score`), must cost what the
kernel says it costs.
"""

from __future__ import annotations

import zlib

import numpy as np
import pytest
from _shapes import blob

from shapetree.demo import demo_shape
from shapetree.matching import (
    MatchParams,
    match_cost,
    match_prepared,
    prepare_model,
    prepare_target,
)
from shapetree.matching._batch import ModelStack
from shapetree.matching._reference import reference_match_cost, reference_score
from shapetree.tree import build_shape_tree, deform

BANDS = [1.0, 1.5, 2.0, 3.0]
WIDE = 1e6  # lmin = 1, lmax = m - 1 for every table: nothing is pruned


def _seed(*key: object) -> int:
    return zlib.crc32(repr(key).encode())


def _pairs(closed: bool, key: str, count: int = 6):
    """Random curve pairs of different sizes (stable seeds) and a few shaped ones."""
    rng = np.random.default_rng(_seed(key, closed))
    out = []
    for _ in range(count):
        n, m = (int(x) for x in rng.integers(6, 22, size=2))
        out.append((blob(n, rng, closed=closed), blob(m, rng, closed=closed)))
    if closed:
        hand, star, leaf = (demo_shape(s, n_points=24) for s in ("hand", "star", "leaf"))
        bent = deform(build_shape_tree(hand, closed=True), 0.08, rng=_seed(key, "bent"))
        out += [(hand, star), (leaf, demo_shape("glyph-S", n_points=20)), (hand, bent)]
    else:
        arc = demo_shape("hand", n_points=30)[:18]
        out += [(arc, demo_shape("leaf", n_points=30)[5:25])]
    return out


def _prep(a, b, closed, n_trees=1):
    return prepare_model(a, closed=closed, n_trees=n_trees), prepare_target(b, closed=closed)


@pytest.mark.parametrize("closed", [False, True])
@pytest.mark.parametrize("occlusion", [None, 0.5])
def test_band_cost_is_never_below_exact_and_grows_as_the_band_narrows(closed, occlusion):
    for a, b in _pairs(closed, "monotone"):
        model, target = _prep(a, b, closed)
        exact = match_cost(model, target, MatchParams(occlusion=occlusion))
        costs = [match_cost(model, target, MatchParams(occlusion=occlusion, band=r)) for r in BANDS]
        tol = 1e-12 * (1 + exact)
        assert all(c >= exact - tol for c in costs)
        assert all(c1 >= c2 - tol for c1, c2 in zip(costs, costs[1:]))  # narrower: dearer


@pytest.mark.parametrize("closed", [False, True])
@pytest.mark.parametrize("occlusion", [None, 0.3])
def test_a_band_that_prunes_nothing_is_exact_matching(closed, occlusion):
    for a, b in _pairs(closed, "wide"):
        model, target = _prep(a, b, closed, n_trees=2 if closed else 1)
        exact = match_prepared(model, target, MatchParams(occlusion=occlusion))
        wide = match_prepared(model, target, MatchParams(occlusion=occlusion, band=WIDE))
        np.testing.assert_allclose(wide.costs, exact.costs, rtol=1e-12, atol=1e-15)
        np.testing.assert_array_equal(wide.a_to_b, exact.a_to_b)
        assert wide.replaced == exact.replaced


def test_wide_band_equals_the_oracle_on_small_curves():
    rng = np.random.default_rng(_seed("wide-oracle"))
    for closed in (False, True):
        for occlusion in (None, 0.6):
            a, b = blob(8, rng, closed=closed), blob(10, rng, closed=closed)
            ref = reference_match_cost(build_shape_tree(a, closed=closed), b, occlusion=occlusion)
            model, target = _prep(a, b, closed)
            got = match_cost(model, target, MatchParams(occlusion=occlusion, band=WIDE))
            assert got == pytest.approx(ref, rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("band", [1.5, 3.0])
@pytest.mark.parametrize("occlusion", [None, 0.3, 1.0])
def test_entry_points_agree_under_band_and_occlusion(band, occlusion):
    """ModelStack.costs, match_cost and match_prepared's cost, and the oracle's score of
    the traceback, all in float64 to 1e-9 relative."""
    params = MatchParams(band=band, occlusion=occlusion)
    pairs = _pairs(True, "agree")
    # ModelStack stacks models of one size: resample every model and target to a common n
    from shapetree.curves import resample

    n, m = 20, 23
    models = [prepare_model(resample(a, n, closed=True), n_trees=2) for a, _ in pairs]
    targets = [prepare_target(resample(b, m, closed=True)) for _, b in pairs]
    stack = ModelStack(models, m, params)
    replaced_any = False
    for target in targets:
        from_stack = stack.costs(target)
        for i, model in enumerate(models):
            cost = match_cost(model, target, params)
            res = match_prepared(model, target, params)
            assert res.cost == pytest.approx(cost, rel=1e-9, abs=1e-15)
            assert from_stack[i] == pytest.approx(cost, rel=1e-9, abs=1e-15)
            tree = model.trees[res.tree_index].tree
            score = reference_score(
                tree, target.points, res.a_to_b, res.replaced, occlusion=occlusion
            )
            assert score == pytest.approx(cost, rel=1e-9, abs=1e-12)
            replaced_any |= bool(res.replaced)
    if occlusion == 0.3:
        assert replaced_any  # the occlusion branch of the traceback is exercised


@pytest.mark.parametrize("band", [1.0, 2.0])
@pytest.mark.parametrize("occlusion", [None, 0.4])
def test_open_traceback_is_scored_to_its_cost(band, occlusion):
    params = MatchParams(band=band, occlusion=occlusion)
    for a, b in _pairs(False, "open-score"):
        model, target = _prep(a, b, False, n_trees=2)
        res = match_prepared(model, target, params)
        assert res.cost == pytest.approx(match_cost(model, target, params), rel=1e-9)
        tree = model.trees[res.tree_index].tree
        score = reference_score(tree, b, res.a_to_b, res.replaced, occlusion=occlusion)
        assert score == pytest.approx(res.cost, rel=1e-9, abs=1e-12)
