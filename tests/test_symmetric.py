"""The symmetric matcher (issue 15, item 2): ψ(A, B) = ψ(B, A) exactly, kernel == oracle."""

from __future__ import annotations

import zlib

import numpy as np
import pytest
from _shapes import blob, similarity

from shapetree._errors import ShapeTreeError
from shapetree.matching import MatchConfig, match
from shapetree.matching._api import kernel_params, model_passes, pair_cost
from shapetree.matching._subcurves import pair_curve, pair_tables, pair_top
from shapetree.matching._subcurves_reference import reference_pair_cost


def _seed(*key: object) -> int:
    return zlib.crc32(repr(key).encode())


def _tables(a, b, closed, dif="procrustes", occlusion=None, band=None, power=1.5):
    ca = pair_curve(a, closed=closed, weight=1.0, length_power=power, dif=dif)
    cb = pair_curve(b, closed=closed, weight=1.0, length_power=power, dif=dif)
    S, _, _ = pair_tables(
        ca, cb, symmetric=True, replace_any=False, dif=dif, occlusion=occlusion, band=band
    )
    return S, ca, cb


@pytest.mark.parametrize("closed", [True, False])
@pytest.mark.parametrize("dif", ["procrustes", "hyperbolic"])
@pytest.mark.parametrize("occlusion", [None, 0.5])
def test_symmetric_kernel_equals_its_oracle(closed, dif, occlusion):
    rng = np.random.default_rng(_seed("sym-oracle", closed, dif, occlusion))
    for _ in range(2):
        a = blob(int(rng.integers(5, 9)), rng, closed=closed)
        b = blob(int(rng.integers(5, 9)), rng, closed=closed)
        S, ca, cb = _tables(a, b, closed, dif, occlusion)
        got, _ = pair_top(S, ca, cb, symmetric=True, n_trees=2)
        want = reference_pair_cost(
            a,
            b,
            closed=closed,
            symmetric=True,
            replace_any=False,
            dif=dif,
            occlusion=occlusion,
            power=1.5,
            n_trees=2,
        )
        assert got == pytest.approx(want, rel=1e-12)


@pytest.mark.parametrize("closed", [True, False])
def test_symmetric_tables_are_exact_transposes(closed):
    rng = np.random.default_rng(_seed("sym-transpose", closed))
    a, b = blob(9, rng, closed=closed), blob(12, rng, closed=closed)
    for dif, band in (("procrustes", None), ("hyperbolic", 2.0)):
        sab, ca, cb = _tables(a, b, closed, dif, 0.7, band)
        sba, _, _ = _tables(b, a, closed, dif, 0.7, band)
        # S_AB[la, lb, sa, sb] == S_BA[lb, la, sb, sa], bit for bit
        np.testing.assert_array_equal(sab, sba.transpose(1, 0, 3, 2))
        c1 = pair_top(sab, ca, cb, symmetric=True, n_trees=2)[0]
        c2 = pair_top(sba, cb, ca, symmetric=True, n_trees=2)[0]
        assert c1 == c2


def test_match_with_the_symmetric_matcher_is_exactly_symmetric():
    rng = np.random.default_rng(_seed("sym-match"))
    cfg = MatchConfig.preset("general", n_points=14, matcher="symmetric", phases=2)
    for _ in range(3):
        a, b = blob(30, rng), blob(26, rng)
        ab, ba = match(a, b, cfg), match(b, a, cfg)
        assert ab.cost == ba.cost > 0
        assert ab.forward_cost == ab.backward_cost == ab.cost
        assert pair_cost(a, b, cfg) == ab.cost
        # the directed matcher is not symmetric on the same pairs
        d = MatchConfig.preset("general", n_points=14, phases=2)
        assert match(a, b, d).cost != match(b, a, d).cost


def test_symmetric_matcher_costs_nothing_on_similar_copies():
    rng = np.random.default_rng(_seed("sym-copy"))
    a = blob(12, rng)
    opts = dict(matcher="symmetric", n_points=None, phases=1)
    res = match(a, similarity(a, 0.8, 2.5, (1, -2)), None, **opts)
    assert res.cost < 1e-12
    np.testing.assert_allclose(res.a_to_b, np.arange(12), atol=1e-12)
    b = blob(12, rng)
    c = match(a, b, None, **opts).cost
    moved = match(a, similarity(b, -0.4, 0.3, (4, 4)), None, **opts)
    assert moved.cost == pytest.approx(c, rel=1e-9)


def test_symmetric_matcher_options_are_validated_and_the_engine_refuses_it():
    with pytest.raises(ShapeTreeError, match="target_factor"):
        MatchConfig(matcher="symmetric", target_factor=2)
    with pytest.raises(ShapeTreeError, match="symmetrize"):
        MatchConfig(matcher="symmetric", symmetrize="min")
    with pytest.raises(ShapeTreeError, match="matcher"):
        MatchConfig(matcher="both")
    cfg = MatchConfig(matcher="symmetric")
    for fn in (kernel_params, lambda c: model_passes(np.eye(4, 2), c)):
        with pytest.raises(ShapeTreeError, match=r"match\(a, b, config\)"):
            fn(cfg)
    with pytest.raises(ShapeTreeError, match="n_trees=1"):
        match(blob(8, np.random.default_rng(0), closed=False), blob(8, np.random.default_rng(1),
              closed=False), cfg, closed=False, n_trees=2)  # fmt: skip
