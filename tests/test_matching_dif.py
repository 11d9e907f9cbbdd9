"""The hyperbolic ``dif`` option of the matcher (issue 15, item 1): kernel == oracle."""

from __future__ import annotations

import zlib

import numpy as np
import pytest
from _shapes import blob, similarity

from shapetree._errors import ShapeTreeError
from shapetree.matching import (
    MatchParams,
    match,
    match_cost,
    match_prepared,
    prepare_model,
    prepare_target,
)
from shapetree.matching._batch import ModelStack
from shapetree.matching._reference import reference_match_cost, reference_score
from shapetree.tree import build_shape_tree


def _seed(*key: object) -> int:
    return zlib.crc32(repr(key).encode())


@pytest.mark.parametrize("closed", [True, False])
@pytest.mark.parametrize("occlusion", [None, 0.4])
@pytest.mark.parametrize("power", [1.0, 1.5])
def test_hyperbolic_kernel_equals_the_oracle(closed, occlusion, power):
    rng = np.random.default_rng(_seed("hyp-oracle", closed, occlusion, power))
    for _ in range(3):
        a = blob(int(rng.integers(6, 11)), rng, closed=closed)
        b = blob(int(rng.integers(6, 12)), rng, closed=closed)
        params = MatchParams(occlusion=occlusion, dif="hyperbolic")
        model = prepare_model(a, closed=closed, length_power=power, dif="hyperbolic")
        target = prepare_target(b, closed=closed, length_power=power)
        want = reference_match_cost(
            build_shape_tree(a, closed=closed),
            b,
            occlusion=occlusion,
            power=power,
            dif="hyperbolic",
        )
        assert match_cost(model, target, params) == pytest.approx(want, rel=1e-9, abs=1e-12)
        res = match_prepared(model, target, params)
        assert res.cost == pytest.approx(want, rel=1e-9, abs=1e-12)
        # the traceback's correspondence scores to the optimum under the literal dif
        tree = model.trees[res.tree_index].tree
        scored = reference_score(
            tree, b, res.a_to_b, res.replaced, occlusion=occlusion, power=power, dif="hyperbolic"
        )
        assert scored == pytest.approx(want, rel=1e-9, abs=1e-12)
        # the Procrustes and hyperbolic costs differ (a different measure)
        proc = match_cost(prepare_model(a, closed=closed, length_power=power), target)
        assert proc != pytest.approx(want)


def test_hyperbolic_match_is_similarity_invariant_and_zero_on_copies():
    rng = np.random.default_rng(_seed("hyp-inv"))
    a, b = blob(24, rng), blob(24, rng)
    for precision in ("float32", "float64"):
        cfg = dict(dif="hyperbolic", precision=precision, n_points=None, phases=1)
        c = match(a, b, **cfg).cost
        moved = similarity(b, 0.7, 3.0, (2.0, -1.0))
        assert match(a, moved, **cfg).cost == pytest.approx(c, rel=1e-4)
        assert match(a, similarity(a, -1.1, 0.2, (5, 5)), **cfg).cost < 1e-6
        assert c > 0


def test_hyperbolic_stack_equals_match_cost_and_mixing_difs_is_refused():
    rng = np.random.default_rng(_seed("hyp-stack"))
    models = [prepare_model(blob(12, rng), dif="hyperbolic") for _ in range(3)]
    target = prepare_target(blob(14, rng))
    params = MatchParams(dif="hyperbolic", band=2.0)
    got = ModelStack(models, 14, params).costs(target)
    want = [match_cost(mod, target, params) for mod in models]
    np.testing.assert_allclose(got, want, rtol=1e-12)
    with pytest.raises(ShapeTreeError, match="dif"):
        match_cost(models[0], target, MatchParams())
    with pytest.raises(ShapeTreeError, match="dif"):
        MatchParams(dif="poincare")


def test_stitching_dif_option():
    from shapetree.detection._stitch import _difn, _shape
    from shapetree.geometry import hyperbolic_dif, triangle_dif

    p = np.array([[0, 0], [0.4, 0.3], [1, 0]], float)
    q = np.array([[0, 0], [0.6, 0.5], [1.2, 0.1]], float)
    z = [complex(*x) for x in q]
    sh = _shape(*(complex(*x) for x in p))
    assert _difn(sh, *z) == pytest.approx(float(triangle_dif(p, q)), rel=1e-12)
    assert _difn(sh, *z, True) == pytest.approx(float(hyperbolic_dif(p, q)), rel=1e-12)
