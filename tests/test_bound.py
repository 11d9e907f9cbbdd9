"""The lower bound of :mod:`shapetree.matching._bound`: never above the full cost.

``BoundStack.bounds`` must be ``<=`` ``ModelStack.costs`` (zero tolerance: the bound's own
slack covers float32 rounding) on thousands of random closed curves, under every kernel
option (occlusion, band, segment weight, several trees combined by their minimum or mean,
length power, both precisions)
and every choice of kept levels; keeping every node gives the cost itself; keeping more
levels never loosens it; on real shapes (Kimia-99) ``lower_bounds`` is ``<=`` the
distances ``distance_matrix`` gives, for every preset and ``symmetrize``.
"""

from __future__ import annotations

import zlib

import numpy as np
import pytest
from _shapes import blob

from shapetree._errors import ShapeTreeError
from shapetree.matching import MatchParams, prepare_model, prepare_target
from shapetree.matching._batch import ModelStack
from shapetree.matching._bound import BOUND_SLACK, BoundStack, keep_mask, table_marks
from shapetree.retrieval import distance_matrix
from shapetree.retrieval._knn import lower_bounds


def _seed(*key: object) -> int:
    return zlib.crc32(repr(key).encode())


def _random_case(rng: np.random.Generator):
    n = int(rng.integers(6, 26))
    m = int(rng.integers(6, 26))
    a, b = blob(n, rng), blob(m, rng)
    power = float(rng.choice([1.0, 1.5]))
    n_trees = int(rng.integers(1, 4))
    params = MatchParams(
        occlusion=[None, 0.3, 2.0][int(rng.integers(3))],
        band=[None, 1.5, 3.0][int(rng.integers(3))],
        segment_weight=float(rng.choice([1.0, 0.0, 0.5])),
        tree_combine=str(rng.choice(["min", "mean"])),
    )
    dtype = [np.float64, np.float32][int(rng.integers(2))]
    model = prepare_model(a, n_trees=n_trees, length_power=power, weight=float(rng.uniform(0.5, 2)))
    target = prepare_target(b, length_power=power, dtype=dtype)
    return model, target, params, dtype


KEEPS = [(0, 0), (1, 0), (2, 0), (3, 0), (None, 1), (None, 2), (None, 3), (2, 1), (None, 0)]


def test_bound_never_above_cost_on_random_curves():
    rng = np.random.default_rng(_seed("bound-random"))
    checked = 0
    for _ in range(250):
        model, target, params, dtype = _random_case(rng)
        m = target.n_points
        cost = ModelStack([model], m, params, dtype).costs(target)[0]
        for kf, kt in KEEPS:
            b = BoundStack([model], m, params, dtype, keep_from=kf, keep_top=kt).bounds(target)[0]
            assert 0.0 <= b <= cost, (kf, kt, b, cost, params, dtype)
            checked += 1
    assert checked >= 2000


def test_keeping_every_node_gives_the_cost():
    rng = np.random.default_rng(_seed("bound-exact"))
    for _ in range(60):
        model, target, params, dtype = _random_case(rng)
        m = target.n_points
        cost = ModelStack([model], m, params, dtype).costs(target)[0]
        b = BoundStack([model], m, params, dtype, keep_from=0).bounds(target)[0]
        assert b == pytest.approx(cost * (1 - BOUND_SLACK), rel=1e-6, abs=1e-12)


def test_more_kept_levels_never_loosen_the_bound():
    rng = np.random.default_rng(_seed("bound-monotone"))
    for _ in range(60):
        model, target, params, dtype = _random_case(rng)
        m = target.n_points
        prev = np.inf
        for kf in range(0, 6):  # fewer levels kept as keep_from grows
            b = BoundStack([model], m, params, dtype, keep_from=kf).bounds(target)[0]
            assert b <= prev * (1 + 1e-6) + 1e-12
            prev = b
        prev = 0.0
        for kt in range(0, 6):  # more top levels kept as keep_top grows
            b = BoundStack([model], m, params, dtype, keep_from=None, keep_top=kt).bounds(target)[0]
            assert b >= prev * (1 - 1e-6) - 1e-12
            prev = b


def test_stacked_bounds_equal_one_by_one():
    rng = np.random.default_rng(_seed("bound-stack"))
    models = [prepare_model(blob(16, rng), n_trees=2) for _ in range(5)]
    target = prepare_target(blob(16, rng))
    params = MatchParams(band=2.0, occlusion=0.5)
    stacked = BoundStack(models, 16, params, keep_from=1).bounds(target)
    single = [BoundStack([mod], 16, params, keep_from=1).bounds(target)[0] for mod in models]
    np.testing.assert_array_equal(stacked, single)
    assert np.all(stacked <= ModelStack(models, 16, params).costs(target))


def test_marks_and_masks():
    rng = np.random.default_rng(_seed("bound-marks"))
    td = prepare_model(blob(20, rng)).trees[0]
    depth = td.tree.depth
    np.testing.assert_array_equal(keep_mask(td, 2), depth >= 2)
    np.testing.assert_array_equal(keep_mask(td, None, 2), depth < 2)
    mark = table_marks(td, 2)
    k = depth.shape[0]
    assert np.all(mark[k:] & 1)  # segments are always exact
    assert np.all((mark[:k] & 1).astype(bool) == (depth >= 2))
    for half, r in enumerate(td.tree.roots):  # dropped roots are read entry by entry
        t = td.table_of_root(r, half)
        assert mark[t] & 4


def test_bound_stack_refuses_bad_input():
    rng = np.random.default_rng(_seed("bound-bad"))
    a = prepare_model(blob(12, rng))
    with pytest.raises(ShapeTreeError):
        BoundStack([], 12)
    with pytest.raises(ShapeTreeError):
        BoundStack([a, prepare_model(blob(14, rng))], 12)
    with pytest.raises(ShapeTreeError):
        BoundStack([prepare_model(blob(12, rng, closed=False), closed=False)], 12)
    stack = BoundStack([a], 12)
    with pytest.raises(ShapeTreeError):
        stack.bounds(prepare_target(blob(13, rng)))
    with pytest.raises(ShapeTreeError):
        stack.bounds(prepare_target(blob(12, rng), dtype=np.float32))


@pytest.fixture(scope="module")
def kimia():
    from shapetree.datasets import load

    return load("kimia99", n_points=None, progress=False).curves


@pytest.mark.parametrize(
    ("preset", "options"),
    [
        ("paper", {}),
        ("kimia99", {}),
        ("mpeg7", {}),
        ("general", {}),
        ("swedish_leaf", {}),
        ("kimia99", {"symmetrize": "min", "occlusion": 0.5}),
        ("mpeg7", {"symmetrize": "mean"}),
        ("paper", {"symmetrize": "max", "band": 2.0}),
        ("general", {"symmetrize": "reverse", "n_trees": 2}),
        ("kimia99", {"tree_combine": "mean"}),
        ("mpeg7", {"tree_combine": "mean", "symmetrize": "min"}),
        ("fused", {"height_points": 16}),  # B^(1 - w) h^w with h exact
        ("fused", {"height_points": 16, "symmetrize": "reverse", "height_weight": 0.9}),
    ],
)
def test_bound_never_above_distance_on_kimia99(kimia, preset, options):
    rng = np.random.default_rng(_seed("kimia-bound", preset, sorted(options.items())))
    q = [kimia[i] for i in rng.choice(len(kimia), 6, replace=False)]
    cfg = dict(options, n_points=16)
    d = distance_matrix(q, kimia, preset, progress=False, **cfg)
    for kf, kt in [(1, 0), (2, 0), (None, 2)]:
        b = lower_bounds(q, kimia, preset, keep_from=kf, keep_top=kt, **cfg)
        assert b.shape == d.shape
        assert np.all(b <= d), (preset, options, kf, kt, float(np.max(b - d)))
        assert np.all(b >= 0)
    # dropping only the roots leaves an informative bound (at 16 points the trees have
    # three levels; the default drops two)
    ratio = lower_bounds(q, kimia, preset, keep_from=1, **cfg) / np.maximum(d, 1e-12)
    assert float(np.mean(ratio)) > 0.1


def test_bound_never_above_cost_with_the_hyperbolic_dif():
    rng = np.random.default_rng(_seed("bound-hyperbolic"))
    for _ in range(80):
        model, target, params, dtype = _random_case(rng)
        hp = MatchParams(
            occlusion=params.occlusion,
            band=params.band,
            segment_weight=params.segment_weight,
            dif="hyperbolic",
        )
        hmodel = prepare_model(
            model.points,
            n_trees=len(model.trees),
            length_power=model.length_power,
            weight=model.weight,
            dif="hyperbolic",
        )
        m = target.n_points
        cost = ModelStack([hmodel], m, hp, dtype).costs(target)[0]
        for kf, kt in KEEPS:
            b = BoundStack([hmodel], m, hp, dtype, keep_from=kf, keep_top=kt).bounds(target)[0]
            assert 0.0 <= b <= cost, (kf, kt, b, cost, hp, dtype)
        full = BoundStack([hmodel], m, hp, dtype, keep_from=0).bounds(target)[0]
        assert full == pytest.approx(cost * (1 - BOUND_SLACK), rel=1e-6)
    with pytest.raises(ShapeTreeError, match="dif"):
        ModelStack([model], target.n_points, hp, dtype)


def test_fused_bound_is_exact_where_h_alone_counts(kimia):
    """With ``height_weight = 1`` the distance is ``h`` and the bound equals it exactly; at
    ``w = 0.6`` it is ``B^0.4 h^0.6``, so it is tighter, relative to the distance, than the
    ψ bound it is made of."""
    q = kimia[:4]
    kw = dict(n_points=16, height_points=16)
    d1 = distance_matrix(q, kimia, "fused", progress=False, height_weight=1.0, **kw)
    assert np.array_equal(lower_bounds(q, kimia, "fused", height_weight=1.0, **kw), d1)
    d = distance_matrix(q, kimia, "fused", progress=False, **kw)
    b = lower_bounds(q, kimia, "fused", **kw)
    d0 = distance_matrix(q, kimia, "fused", progress=False, height_weight=0.0, **kw)
    b0 = lower_bounds(q, kimia, "fused", height_weight=0.0, **kw)
    pos = (d0 > 0) & (d > 0)  # not a shape against itself
    assert np.all(b <= d) and np.mean(b[pos] / d[pos]) > np.mean(b0[pos] / d0[pos])
