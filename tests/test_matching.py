"""Elastic matching (eq. 1): the compiled kernel against the literal reference, and the
properties the paper's definition implies."""

from __future__ import annotations

import zlib

import numpy as np
import pytest
from _shapes import blob, similarity
from hypothesis import given, settings
from hypothesis import strategies as st

from shapetree import ShapeTreeError
from shapetree.matching import (
    PRESETS,
    MatchParams,
    match,
    match_cost,
    match_prepared,
    prepare_model,
    prepare_target,
    subcurve_table,
)
from shapetree.matching._batch import ModelStack
from shapetree.matching._prepare import tree_variants
from shapetree.matching._reference import (
    reference_correspondence,
    reference_match_cost,
    reference_subcurve_table,
)
from shapetree.retrieval import distance_matrix
from shapetree.tree import build_shape_tree, deform

#: match() as the oracle defines it: the points as given, one shape-tree, no mirror, no
#: band, one target phase, float64 tables (the "general" preset is none of these)
EXACT = PRESETS["paper"].replace(n_points=None, precision="float64")


def _seed(*key: object) -> int:
    """A seed that is the same in every run (``hash`` of a str is salted per process)."""
    return zlib.crc32(repr(key).encode())


def _fast(a, b, closed, **kw):
    occ = kw.pop("occlusion", None)
    return match_prepared(
        prepare_model(a, closed=closed, **kw),
        prepare_target(b, closed=closed),
        MatchParams(occlusion=occ),
    )


# --- the oracle -----------------------------------------------------------------------


@pytest.mark.parametrize("closed", [False, True])
@pytest.mark.parametrize("split", ["half", "best"])
@pytest.mark.parametrize("occlusion", [None, 0.3, 2.0])
def test_kernel_equals_reference_on_random_curves(closed, split, occlusion):
    rng = np.random.default_rng(_seed("kernel-vs-reference", closed, split, occlusion))
    for _ in range(12):
        n, m = (int(x) for x in rng.integers(3, 12, size=2))
        a, b = blob(n, rng, closed=closed), blob(m, rng, closed=closed)
        weight = float(rng.uniform(0.5, 2.0))
        tree = build_shape_tree(a, closed=closed, split=split)
        ref = reference_match_cost(tree, b, weight=weight, occlusion=occlusion)
        fast = _fast(a, b, closed, split=split, weight=weight, occlusion=occlusion).cost
        assert fast == pytest.approx(ref, rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("power", [0.5, 2.0])
def test_kernel_equals_reference_with_length_power(power):
    rng = np.random.default_rng(_seed("length-power", power))
    for closed in (False, True):
        for occlusion in (None, 0.7):
            a, b = blob(9, rng, closed=closed), blob(8, rng, closed=closed)
            tree = build_shape_tree(a, closed=closed)
            ref = reference_match_cost(tree, b, occlusion=occlusion, power=power)
            fast = match_prepared(
                prepare_model(a, closed=closed, length_power=power),
                prepare_target(b, closed=closed, length_power=power),
                MatchParams(occlusion=occlusion),
            ).cost
            assert fast == pytest.approx(ref, rel=1e-9, abs=1e-12)
    with pytest.raises(ShapeTreeError, match="length_power"):
        match_cost(prepare_model(a, length_power=power), prepare_target(b))


@pytest.mark.parametrize("segment_weight", [0.0, 0.4])
def test_kernel_equals_reference_with_segment_weight_and_dense_target(segment_weight):
    """The base case "segment vs target subcurve" scaled by segment_weight (0: free), with
    targets sampled up to twice as densely as the model."""
    rng = np.random.default_rng(_seed("segment-weight", segment_weight))
    for closed in (False, True):
        for occlusion in (None, 0.6):
            n = int(rng.integers(4, 8))
            a, b = blob(n, rng, closed=closed), blob(2 * n, rng, closed=closed)
            tree = build_shape_tree(a, closed=closed)
            ref = reference_match_cost(tree, b, occlusion=occlusion, segment_weight=segment_weight)
            fast = match_prepared(
                prepare_model(a, closed=closed),
                prepare_target(b, closed=closed),
                MatchParams(occlusion=occlusion, segment_weight=segment_weight),
            ).cost
            assert fast == pytest.approx(ref, rel=1e-9, abs=1e-12)
            full = reference_match_cost(tree, b, occlusion=occlusion)
            assert ref <= full + 1e-12  # a cheaper base case never raises the cost


def test_free_segments_let_a_dense_target_absorb_its_extra_points():
    """A model matched to a target that holds the model's own points plus extra ones in
    between costs exactly 0 when segment detail is free, and more with the paper's rule."""
    t = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    star = np.c_[np.cos(t), np.sin(t)] * (1 + 0.3 * np.cos(5 * t))[:, None]
    model = star[::2]  # 12 points; the target has a bumpy point between each pair
    mp0 = MatchParams(segment_weight=0.0)
    assert match_cost(prepare_model(model), prepare_target(star), mp0) == pytest.approx(
        0.0, abs=1e-12
    )
    assert match_cost(prepare_model(model), prepare_target(star)) > 1e-3
    res = match(model, star, EXACT, segment_weight=0.0)
    np.testing.assert_allclose(np.diff(res.a_to_b) % 24, 2.0)  # every other target point


def test_subcurve_table_equals_reference():
    rng = np.random.default_rng(11)
    for occlusion in (None, 0.5):
        contour, model = blob(7, rng, closed=False), blob(9, rng)
        tree = build_shape_tree(contour, closed=False)
        ref = reference_subcurve_table(tree, model, occlusion=occlusion, length_scale=3.0)
        fast = subcurve_table(tree, prepare_target(model), occlusion=occlusion, length_scale=3.0)
        assert fast.shape == (9, 9)
        assert np.all(np.isinf(fast[:, 0]))
        np.testing.assert_allclose(fast[:, 1:], ref[:, 1:], rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("closed", [False, True])
def test_correspondence_equals_reference_when_unique(closed):
    rng = np.random.default_rng(21 + closed)
    compared = 0
    for _ in range(25):
        n, m = (int(x) for x in rng.integers(4, 11, size=2))
        a, b = blob(n, rng, closed=closed), blob(m, rng, closed=closed)
        tree = build_shape_tree(a, closed=closed)
        cost, mapping, unique = reference_correspondence(tree, b)
        res = _fast(a, b, closed)
        assert res.cost == pytest.approx(cost, rel=1e-9, abs=1e-12)
        if not unique:
            continue
        compared += 1
        for ia, jb in mapping.items():
            if closed:
                assert res.a_to_b[ia % n] == pytest.approx(jb % m)
            else:
                assert res.a_to_b[ia] == pytest.approx(jb)
    assert compared >= 15


# --- properties -----------------------------------------------------------------------


@pytest.mark.parametrize("closed", [False, True])
@pytest.mark.parametrize("n_trees", [1, 2])
def test_self_match_costs_zero(closed, n_trees):
    a = blob(40, np.random.default_rng(1), closed=closed)
    res = match(a, a, EXACT, closed=closed, n_trees=n_trees)
    assert res.cost == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(res.a_to_b, np.arange(40))  # identity correspondence
    np.testing.assert_allclose(res.b_to_a, np.arange(40))


angles = st.floats(-np.pi, np.pi)
scales = st.floats(0.05, 20.0)
shifts = st.tuples(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3))


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10**6), angles, scales, shifts, st.booleans(), st.booleans())
def test_cost_invariant_to_similarity_of_either_curve(seed, angle, scale, shift, which, closed):
    rng = np.random.default_rng(seed)
    a, b = blob(16, rng, closed=closed), blob(19, rng, closed=closed)
    base = match(a, b, EXACT, closed=closed, occlusion=1.0).cost
    if which:
        a = similarity(a, angle, scale, shift)
    else:
        b = similarity(b, angle, scale, shift)
    assert match(a, b, EXACT, closed=closed, occlusion=1.0).cost == pytest.approx(base, rel=1e-9)


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 10**6), st.integers(1, 30))
def test_closed_cost_independent_of_b_start(seed, shift):
    rng = np.random.default_rng(seed)
    a, b = blob(20, rng), blob(31, rng)
    c0 = match(a, b, EXACT).cost
    rolled = match(a, np.roll(b, shift, axis=0), EXACT).cost
    assert rolled == pytest.approx(c0, rel=1e-9, abs=1e-13)


def _cyclic_monotone(pos: np.ndarray, period: int) -> bool:
    p = pos[np.isfinite(pos)]
    steps = np.mod(np.diff(np.r_[p, p[:1]]), period)
    return bool(np.isclose(steps.sum(), period) or np.isclose(steps.sum(), 0.0))


@pytest.mark.parametrize("occlusion", [None, 0.2])
def test_correspondences_monotone_along_both_curves(occlusion):
    rng = np.random.default_rng(4)
    for _ in range(10):
        a, b = blob(30, rng), blob(26, rng)
        res = match(a, b, EXACT, occlusion=occlusion)
        assert _cyclic_monotone(res.a_to_b, 26)
        assert _cyclic_monotone(res.b_to_a, 30)
        ao, bo = blob(30, rng, closed=False), blob(26, rng, closed=False)
        r2 = match(ao, bo, EXACT, closed=False, occlusion=occlusion)
        for pos in (r2.a_to_b, r2.b_to_a):
            p = pos[np.isfinite(pos)]
            assert np.all(np.diff(p) >= -1e-12)
        assert r2.a_to_b[0] == 0 and r2.a_to_b[-1] == 25


def test_larger_deformations_cost_more_on_average():
    rng = np.random.default_rng(8)
    a = blob(48, rng, wobble=0.15)
    tree = build_shape_tree(a, closed=True)
    means = []
    for scale in (0.02, 0.06, 0.15):
        costs = [match(a, deform(tree, scale, rng=seed), EXACT).cost for seed in range(12)]
        means.append(np.mean(costs))
    assert means[0] < means[1] < means[2]


def test_several_trees_take_the_best():
    rng = np.random.default_rng(9)
    a, b = blob(32, rng), blob(32, rng)
    res = match(a, b, EXACT, n_trees=4)
    assert len(res.costs) == 4
    assert res.cost == pytest.approx(res.costs.min())
    for t in range(4):  # each entry is the cost of a single tree started at offset t*n/8
        model = prepare_model(np.roll(a, -(t * 32) // 8, axis=0))
        assert match_cost(model, prepare_target(b)) == pytest.approx(res.costs[t], rel=1e-9)
    assert res.cost <= match(a, b, EXACT).cost + 1e-12
    # trees are really different: a tree started half-way round would repeat the first
    assert len(set(np.round(res.costs, 12))) == 4


@pytest.mark.parametrize("occlusion", [None, 0.4])
def test_tree_combine_mean_is_the_mean_of_the_oracle_tree_costs(occlusion):
    rng = np.random.default_rng(_seed("tree-mean", occlusion))
    a, b = blob(14, rng), blob(13, rng)
    cfg = EXACT.replace(n_trees=3, occlusion=occlusion)
    best, mean = match(a, b, cfg), match(a, b, cfg.replace(tree_combine="mean"))
    np.testing.assert_array_equal(best.costs, mean.costs)  # the same three trees
    for t, kw in enumerate(tree_variants(14, True, 3, "half")):  # each one is the oracle's
        tree = build_shape_tree(a, closed=True, **kw)
        want = reference_match_cost(tree, b, occlusion=occlusion)
        assert mean.costs[t] == pytest.approx(want, rel=1e-9, abs=1e-12)
    assert best.cost == pytest.approx(best.costs.min(), rel=1e-12)
    assert mean.cost == pytest.approx(best.costs.mean(), rel=1e-12)
    assert mean.cost > best.cost  # the trees differ, so the mean is above the best
    # the drawn correspondence is the cheapest tree's either way
    assert mean.tree_index == best.tree_index == int(np.argmin(best.costs))
    np.testing.assert_array_equal(mean.a_to_b, best.a_to_b)
    # one tree: nothing to combine
    one = EXACT.replace(occlusion=occlusion)
    assert match(a, b, one.replace(tree_combine="mean")).cost == match(a, b, one).cost


def test_tree_combine_mean_in_every_cost_path():
    rng = np.random.default_rng(_seed("tree-mean-paths"))
    curves = [blob(20, rng) for _ in range(4)]
    cfg = PRESETS["general"].replace(n_points=16, n_trees=3, tree_combine="mean", phases=2)
    D = distance_matrix(curves, config=cfg, progress=False)
    for i in range(4):
        for j in range(4):
            assert D[i, j] == pytest.approx(match(curves[i], curves[j], cfg).cost, rel=1e-6)
    # the kernel level: a stack of models against one target equals one by one
    params = MatchParams(band=3.0, tree_combine="mean")
    models = [prepare_model(c, n_trees=3) for c in curves]
    target = prepare_target(curves[0])
    stacked = ModelStack(models, 20, params).costs(target)
    single = [match_cost(mod, target, params) for mod in models]
    np.testing.assert_allclose(stacked, single, rtol=1e-12)
    assert np.all(stacked >= ModelStack(models, 20, MatchParams(band=3.0)).costs(target))


def test_tree_combine_is_validated():
    with pytest.raises(ShapeTreeError, match="tree_combine must be one of"):
        PRESETS["general"].replace(tree_combine="max")
    with pytest.raises(ShapeTreeError, match="tree_combine='mean' is an option of the shape-tree"):
        PRESETS["general"].replace(tree_combine="mean", matcher="symmetric")
    with pytest.raises(ShapeTreeError, match="tree_combine must be 'min' or 'mean'"):
        MatchParams(tree_combine="median")


def test_occlusion_replaces_a_missing_part():
    # a square versus the same square with a big bump on one side: only the bump's side
    # should be replaced, and replacement must lower the cost
    t = np.linspace(0, 4, 80, endpoint=False)
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]], float)
    sq = np.array([np.interp(t, np.arange(5), square[:, i]) for i in (0, 1)]).T
    bumped = sq.copy()
    side = (sq[:, 1] == 0) & (sq[:, 0] > 0.25) & (sq[:, 0] < 0.75)
    bumped[side, 1] -= 0.6 * np.sin(np.pi * (sq[side, 0] - 0.25) / 0.5)
    plain = match(sq, bumped, EXACT, n_trees=4)
    occl = match(sq, bumped, EXACT, n_trees=4, occlusion=0.5)
    assert occl.cost < plain.cost
    assert occl.replaced, "the bump should be replaced"
    covered = np.zeros(80, bool)
    for _a0, _a1, b0, b1 in occl.replaced:
        covered[np.arange(b0, b1 + (80 if b1 < b0 else 0) + 1) % 80] = True
    assert covered[side].mean() >= 0.6  # most of the bump is what got replaced
    assert covered.sum() < 40  # and not half the square
    inside = np.isnan(occl.a_to_b)
    assert inside.any() and not inside.all()


def test_match_resamples_when_asked():
    rng = np.random.default_rng(2)
    res = match(blob(200, rng), blob(90, rng), EXACT, n_points=40)
    assert res.a.shape == (40, 2) and res.b.shape == (40, 2)
    assert res.pairs().shape[1] == 4


def test_bad_input_is_reported():
    rng = np.random.default_rng(0)
    a = blob(10, rng)
    with pytest.raises(ShapeTreeError, match="closed"):
        match_prepared(prepare_model(a), prepare_target(a, closed=False))
    with pytest.raises(ShapeTreeError, match="occlusion"):
        MatchParams(occlusion=-1)
    with pytest.raises(ShapeTreeError, match="weight"):
        prepare_model(a, weight=0)
    with pytest.raises(ShapeTreeError, match="n_trees"):
        prepare_model(a, n_trees=0)
    with pytest.raises(ShapeTreeError, match="NaN"):
        match(np.array([[0, 0], [1, np.nan], [1, 1]]), a, EXACT)
    with pytest.raises(ShapeTreeError, match="fewer than 3"):
        match(np.array([[0.0, 0.0], [1.0, 0.0]]), a, EXACT)
    with pytest.raises(ShapeTreeError, match=r"\(n, 2\)"):
        match(np.zeros((5, 3)), a, EXACT)


def test_float32_tables_agree_and_bad_dtypes_are_named():
    """float32 tables (the retrieval engine's precision) give the float64 costs to ~1e-6;
    an unsupported dtype, or a target of the wrong precision for a ModelStack, is refused."""
    from shapetree.matching._batch import ModelStack

    rng = np.random.default_rng(4)
    a, b, c = (blob(24, rng) for _ in range(3))
    models = [prepare_model(x, n_trees=2) for x in (a, c)]
    t64 = prepare_target(b)
    t32 = prepare_target(b, dtype=np.float32)
    assert t32.tri.dtype == np.float32 and t32.g.dtype == np.float32
    exact = [match_cost(mod, t64) for mod in models]
    np.testing.assert_allclose([match_cost(mod, t32) for mod in models], exact, rtol=1e-5)
    stack = ModelStack(models, 24, dtype=np.float32)
    np.testing.assert_allclose(stack.costs(t32), exact, rtol=1e-5)
    assert match_cost(models[0], prepare_target(a, dtype=np.float32)) < 1e-6  # self-match
    with pytest.raises(ShapeTreeError, match="runs in float32"):
        stack.costs(t64)
    with pytest.raises(ShapeTreeError, match="dtype must be float64 or float32"):
        prepare_target(b, dtype=np.int32)
