"""Arbitrary replacement (issue 15, item 3): the O(n^3 m^3) DP, kernel == oracle."""

from __future__ import annotations

import zlib

import numpy as np
import pytest
from _shapes import blob

from shapetree._errors import ShapeTreeError
from shapetree.matching import (
    MatchConfig,
    MatchParams,
    match,
    match_cost,
    prepare_model,
    prepare_target,
)
from shapetree.matching._subcurves import pair_curve, pair_tables, pair_top, pair_traceback
from shapetree.matching._subcurves_reference import reference_pair_cost
from shapetree.tree import build_shape_tree


def _seed(*key: object) -> int:
    return zlib.crc32(repr(key).encode())


def _pair(a, b, closed, *, replace_any, occlusion, dif="procrustes", symmetric=False, n_trees=1):
    ca = pair_curve(a, closed=closed, weight=1.0, length_power=1.0, dif=dif)
    cb = pair_curve(b, closed=closed, weight=1.0, length_power=1.0, dif=dif)
    S, H, ok = pair_tables(
        ca, cb, symmetric=symmetric, replace_any=replace_any, dif=dif, occlusion=occlusion
    )
    cost, top = pair_top(S, ca, cb, symmetric=symmetric, n_trees=n_trees)
    return cost, (S, H, ok, ca, cb, top)


@pytest.mark.parametrize("closed", [True, False])
@pytest.mark.parametrize("dif", ["procrustes", "hyperbolic"])
@pytest.mark.parametrize("symmetric", [False, True])
def test_replace_any_kernel_equals_its_oracle(closed, dif, symmetric):
    rng = np.random.default_rng(_seed("rep-oracle", closed, dif, symmetric))
    for _ in range(2):
        a = blob(int(rng.integers(5, 8)), rng, closed=closed)
        b = blob(int(rng.integers(5, 8)), rng, closed=closed)
        occ = float(rng.choice([0.2, 1.0]))
        got, _ = _pair(
            a, b, closed, replace_any=True, occlusion=occ, dif=dif, symmetric=symmetric, n_trees=2
        )
        want = reference_pair_cost(
            a,
            b,
            closed=closed,
            symmetric=symmetric,
            replace_any=True,
            dif=dif,
            occlusion=occ,
            n_trees=2,
        )
        assert got == pytest.approx(want, rel=1e-12)


@pytest.mark.parametrize("closed", [True, False])
def test_pair_dp_reproduces_the_shape_tree_matcher_and_never_exceeds_it(closed):
    rng = np.random.default_rng(_seed("rep-directed", closed))
    for _ in range(4):
        a, b = blob(11, rng, closed=closed), blob(13, rng, closed=closed)
        model = prepare_model(a, closed=closed, length_power=1.0)
        target = prepare_target(b, closed=closed, length_power=1.0)
        for occ in (0.3, 1e6):
            directed = match_cost(model, target, MatchParams(occlusion=occ))
            plain, _ = _pair(a, b, closed, replace_any=False, occlusion=occ)
            assert plain == pytest.approx(directed, rel=1e-12)  # the same recursion
            anyrep, _ = _pair(a, b, closed, replace_any=True, occlusion=occ)
            assert anyrep <= directed * (1 + 1e-12)
            if occ > 1e3:  # replacing never pays: no cut either
                assert anyrep == pytest.approx(directed, rel=1e-12)


def _bumped():
    t = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    b = np.c_[np.cos(t), 0.7 * np.sin(t)]
    a = b.copy()
    for i, f in ((5, 1.8), (6, 2.6), (7, 1.8)):
        a[i] = b[i] * f  # a spike on points 5..7 of A, across the boundary of two subtrees
    return a, b


def test_a_part_no_subtree_covers_is_replaced():
    a, b = _bumped()
    cfg = MatchConfig.preset(
        "paper", n_points=None, occlusion=0.2, phases=1, mirror=False, band=None
    )
    res = match(a, b, cfg, replace_any=True)
    directed = match(a, b, cfg)
    assert res.replaced == [(4, 8, 4, 8)]  # the spike and the stretch of B it stands for
    tree = build_shape_tree(a, closed=True)
    nodes = {(int(s) % 24, int(e) % 24) for s, e in zip(tree.start, tree.end, strict=True)}
    assert (4, 8) not in nodes  # no single subtree covers it
    assert all((r[0], r[1]) in nodes or r[1] - r[0] == 1 for r in directed.replaced)
    assert res.cost < 0.75 * directed.cost
    assert np.isnan(res.a_to_b[5:8]).all() and np.isfinite(np.delete(res.a_to_b, [5, 6, 7])).all()
    # the traceback's pieces are consistent with the table's optimum
    cost, (S, H, ok, ca, cb, top) = _pair(a, b, True, replace_any=True, occlusion=0.2)
    assert cost == pytest.approx(res.cost, rel=1e-12)
    _, _, rep = pair_traceback(S, H, ok, ca, cb, top, symmetric=False, dif="procrustes",
                               occlusion=0.2)  # fmt: skip
    assert rep == res.replaced


def test_replace_any_needs_occlusion_and_the_half_rule():
    with pytest.raises(ShapeTreeError, match="occlusion"):
        MatchConfig(replace_any=True)
    with pytest.raises(ShapeTreeError, match="split"):
        MatchConfig(replace_any=True, occlusion=1.0, split="best")
    cfg = MatchConfig(replace_any=True, occlusion=1.0, n_points=12, phases=2)
    rng = np.random.default_rng(0)
    a, b = blob(20, rng), blob(20, rng)
    assert match(a, b, cfg).cost <= match(a, b, cfg.replace(replace_any=False)).cost * (1 + 1e-6)
