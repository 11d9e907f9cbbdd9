"""The height-function distance and its fusion with ψ (``MatchConfig.height_weight``)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from shapetree import ShapeTreeError
from shapetree.curves import resample
from shapetree.matching import MatchConfig, match
from shapetree.matching._api import pair_cost
from shapetree.matching._height import (
    HeightParams,
    complexity,
    dp_cyclic,
    group_starts,
    height_descriptors,
    height_distance,
    height_matrix,
    heights,
)
from shapetree.matching._reference import reference_height_distance
from shapetree.retrieval import combine, directed_costs, distance_matrix


def _blob(rng: np.random.Generator, n: int = 60) -> np.ndarray:
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = 1 + 0.3 * rng.uniform(-1, 1) * np.cos(3 * t + rng.uniform(0, 6)) + 0.2 * np.sin(2 * t)
    return np.c_[r * np.cos(t), rng.uniform(0.5, 1) * r * np.sin(t)]


def _star(n: int = 200) -> np.ndarray:
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = 1 + 0.3 * np.cos(3 * t)
    return np.c_[r * np.cos(t), r * np.sin(t)]


def _bump(n: int = 200) -> np.ndarray:
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.c_[(1 + 0.2 * np.cos(t) ** 9) * np.cos(t), np.sin(t)]


def _dp_oracle(C: np.ndarray, pen: float) -> float:
    n, m = C.shape
    best = np.inf
    for s in range(m):
        D = np.zeros((n + 1, m + 1))
        D[0, :] = np.arange(m + 1) * pen
        D[:, 0] = np.arange(n + 1) * pen
        for i in range(1, n + 1):
            for j in range(1, m + 1):
                D[i, j] = min(
                    D[i - 1, j - 1] + C[i - 1, (j - 1 + s) % m],
                    D[i - 1, j] + pen,
                    D[i, j - 1] + pen,
                )
        best = min(best, D[n, m])
    return float(best)


def test_kernel_equals_the_pure_python_oracle() -> None:
    """The compiled descriptor + cyclic DP equal :func:`reference_height_distance` (built
    point by point, a memoised recursion over every start and both mirror images) on
    random closed curves, for both weightings and several group sizes."""
    rng = np.random.default_rng(0)
    # (n - 1) divisible by the group or not (then the groups come in pairs from both ends)
    cases = ((8, 1, "harmonic"), (12, 2, "harmonic"), (13, 3, "gauss"), (14, 3, "gauss"))
    for (n, group, weighting), norm in itertools.product(cases, (False, True)):
        hp = HeightParams(n, group, weighting, complexity=norm)
        for _ in range(3):
            a, b = _blob(rng), _blob(rng)
            got = height_distance(height_descriptors(a, hp), height_descriptors(b, hp), hp)
            pa, pb = resample(a, n, closed=True), resample(b, n, closed=True)
            want = reference_height_distance(pa, pb, group, hp.weights(), hp.skip, norm)
            assert got == pytest.approx(want, rel=1e-12, abs=1e-15)


def test_cyclic_dp_agrees_with_the_table_oracle_either_way_round() -> None:
    """``dp_cyclic`` (which abandons starts early) equals the full table over every start on
    random cost tables, square and not, and transposing the table leaves it unchanged (what
    makes ``h`` symmetric)."""
    rng = np.random.default_rng(1)
    for n, m in ((1, 1), (3, 3), (4, 6), (7, 5), (8, 8)):
        for _ in range(4):
            C = rng.random((n, m))
            pen = float(rng.uniform(0.05, 0.8))
            assert dp_cyclic(C, pen) == pytest.approx(_dp_oracle(C, pen))
            assert dp_cyclic(C.T.copy(), pen) == pytest.approx(dp_cyclic(C, pen))


def test_descriptor_is_invariant_and_rolls_with_the_start_point() -> None:
    """Rotation, scale and translation leave the descriptor unchanged; starting the points
    elsewhere rolls its rows; entries lie in [-1, 1] with a 1 in every column."""
    t = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    r = 1.0 + 0.3 * np.cos(3 * t) + 0.1 * np.sin(5 * t)
    p = np.stack([r * np.cos(t), r * np.sin(t)], 1)
    F = heights(p, 3)
    assert F.shape == (64, 21)
    assert np.allclose(np.abs(F).max(0), 1.0)
    a = 0.9
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    assert np.allclose(heights(3.5 * p @ R.T + [4.0, -2.0], 3), F, atol=1e-12)
    assert np.allclose(heights(np.roll(p, -11, 0), 3), np.roll(F, -11, 0), atol=1e-12)


def test_distance_properties() -> None:
    """``h`` is 0 for a shape against itself, a similar copy, its mirror image, a copy
    traced the other way or from another start; it is symmetric; another shape costs
    more; the harmonic weights put the most weight next to the point."""
    hp = HeightParams.of(64)
    assert (hp.group, hp.n_entries) == (3, 21)
    assert HeightParams.of(100).group == 5
    w = hp.weights()
    assert w.sum() == pytest.approx(1.0) and w[0] == w[-1] == w.max() and w[10] == w.min()
    bump, star = _bump(), _star()
    D = {k: height_descriptors(c, hp) for k, c in (("bump", bump), ("star", star))}
    a = 0.7
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    for copy in (bump, 2 * bump @ R.T + 5, bump * [-1, 1]):  # the same samples
        assert height_distance(D["bump"], height_descriptors(copy, hp), hp) == pytest.approx(
            0.0, abs=1e-9
        )
    ab = height_distance(D["bump"], D["star"], hp)
    for copy in (bump[::-1], np.roll(bump, 37, 0)):  # other samples of the same outline
        assert height_distance(D["bump"], height_descriptors(copy, hp), hp) < ab / 5
    assert ab > 0.01
    assert height_distance(D["star"], D["bump"], hp) == pytest.approx(ab, rel=1e-12)
    H = height_matrix([D["bump"], D["star"]], [D["star"], D["bump"]], hp)
    assert H[0, 0] == pytest.approx(ab) and H[1, 1] == pytest.approx(ab)
    assert H[0, 1] == pytest.approx(0, abs=1e-12) and H[1, 0] == pytest.approx(0, abs=1e-12)


def test_distance_is_symmetric_whether_or_not_the_groups_tile() -> None:
    """``h(A, B) = h(B, A)`` and ``h(A', B') = h(A, B)`` for mirror images ``A', B'`` (to
    rounding), at 64 points (groups of 3 tile the 63 other points) and at 100 (groups of 5
    do not tile 99: pairs of groups from both ends), because the mirror's descriptor is the
    descriptor with its columns reversed and its rows in reverse order."""
    rng = np.random.default_rng(7)
    for n in (64, 100, 37):
        hp = HeightParams.of(n)
        starts = group_starts(n, hp.group)
        k = (starts[:, None] + np.arange(hp.group)).ravel()
        assert sorted(n - k) == sorted(k) and len(set(k.tolist())) == len(k)
        a, b = _blob(rng, 150), _blob(rng, 150)
        da, db = height_descriptors(a, hp), height_descriptors(b, hp)
        f = heights(resample(a, n, closed=True), hp.group)
        mirror = resample(a, n, closed=True)[::-1] * [-1, 1]
        assert np.allclose(heights(mirror, hp.group), f[::-1, ::-1], atol=1e-12)
        ab = height_distance(da, db, hp)
        assert height_distance(db, da, hp) == pytest.approx(ab, rel=1e-12)
        am, bm = height_descriptors(a * [-1, 1], hp), height_descriptors(b * [-1, 1], hp)
        assert height_distance(am, bm, hp) == pytest.approx(ab, rel=1e-12)
        assert height_distance(am, db, hp) == pytest.approx(height_distance(da, bm, hp))


def test_complexity_normalisation() -> None:
    """The shape complexity is ~0 for a circle, larger for a wavier outline, invariant to
    similarity, start point, direction and mirroring; the normalised distance is
    ``h / (C(A) + C(B))``, symmetric, and ~0 (not rounding / rounding) for two circles; the engine's
    matrix holds the pair API's numbers."""
    hp = HeightParams.of(64, complexity=True)
    t = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    circle = np.c_[np.cos(t), np.sin(t)]
    d_circle = height_descriptors(circle, hp)
    assert complexity(d_circle) < 1e-9
    assert height_distance(d_circle, height_descriptors(2 * circle + 1, hp), hp) < 1e-12
    bump, star = _bump(), _star()
    cb, cs = complexity(height_descriptors(bump, hp)), complexity(height_descriptors(star, hp))
    assert 0.05 < cb < cs < 1.0
    a = 1.1
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    for copy in (3 * star @ R.T - 2, star * [-1, 1]):  # the same samples: exact
        assert complexity(height_descriptors(copy, hp)) == pytest.approx(cs, rel=1e-9)
    for copy in (np.roll(star, 50, 0), star[::-1]):  # other samples of the same outline
        assert complexity(height_descriptors(copy, hp)) == pytest.approx(cs, rel=1e-3)
    raw = HeightParams.of(64)
    db, ds = height_descriptors(bump, hp), height_descriptors(star, hp)
    h = height_distance(db, ds, raw)
    assert height_distance(db, ds, hp) == pytest.approx(h / (cb + cs), rel=1e-12)
    assert height_distance(ds, db, hp) == pytest.approx(h / (cb + cs), rel=1e-12)
    H = height_matrix([db, ds], [ds, db, d_circle], hp)
    assert H[0, 0] == pytest.approx(h / (cb + cs), rel=1e-12)
    assert H[0, 1] == pytest.approx(0, abs=1e-12) and np.isfinite(H).all()
    rng = np.random.default_rng(3)
    curves = [_blob(rng) for _ in range(3)] + [_star(80)]
    cfg = MatchConfig(n_points=16, height_points=24, height_weight=0.6, height_complexity=True)
    P = np.array([[match(a, b, cfg).cost for b in curves] for a in curves])
    assert np.allclose(distance_matrix(curves, config=cfg, progress=False), P, atol=1e-12)
    plain = cfg.replace(height_complexity=False)
    r0, r1 = match(curves[0], curves[3], plain), match(curves[0], curves[3], cfg)
    assert r1.forward_cost == r0.forward_cost and r1.height_cost < r0.height_cost * 3


def test_fused_cost_is_the_same_number_everywhere() -> None:
    """With ``height_weight`` the pair API, ``distance_matrix`` (set against itself and
    queries against a database, every ``symmetrize``) and ``combine`` of the engine's
    layers give the same ``ψ^(1 - w) h^w``; ``w = 0`` is ψ and ``w = 1`` is ``h``."""
    rng = np.random.default_rng(2)
    curves = [_blob(rng) for _ in range(4)] + [_star(80)]
    base = MatchConfig(n_points=16, height_points=24)
    for sym in ("none", "min", "reverse"):
        cfg = base.replace(symmetrize=sym, height_weight=0.4)
        P = np.array([[match(a, b, cfg).cost for b in curves] for a in curves])
        assert np.allclose(distance_matrix(curves, config=cfg, progress=False), P, atol=1e-12)
        Q = distance_matrix(curves[:2], curves, config=cfg, progress=False)
        assert np.allclose(Q, P[:2], atol=1e-12)
    cfg = base.replace(height_weight=0.4)
    costs = directed_costs(curves, None, cfg, progress=False)
    assert costs.shape == (cfg.n_pass + 1, 5, 5)
    psi = combine(costs[:-1], "none")
    assert np.allclose(combine(costs, "none", 0.4), psi**0.6 * costs[-1] ** 0.4)
    res = match(curves[0], curves[4], cfg)
    assert res.cost == pytest.approx(res.forward_cost**0.6 * res.height_cost**0.4)
    assert pair_cost(curves[0], curves[4], cfg) == pytest.approx(res.cost)
    assert match(curves[0], curves[4], cfg.replace(height_weight=1.0)).cost == pytest.approx(
        res.height_cost
    )
    plain = match(curves[0], curves[4], base)
    assert plain.height_cost is None and plain.cost == pytest.approx(res.forward_cost)


def test_fusion_ranks_a_deformed_copy_first() -> None:
    """The fused distance of a stretched, noisy copy of a shape is smaller than that of
    another shape (a sanity check of the fusion's direction, not of its benefit: that is
    measured in ``benchmarks/eval_height_variants.py``)."""
    rng = np.random.default_rng(5)
    bump = _bump(120)
    copy = bump * [1.0, 1.15] + 0.01 * rng.standard_normal(bump.shape)
    cfg = MatchConfig(n_points=24, height_weight=0.5, height_points=32)
    assert match(bump, copy, cfg).cost < match(bump, _star(120), cfg).cost


def test_options_are_validated_and_refused_where_unsupported() -> None:
    """Bad values name the option; open curves refuse the fusion with a sentence, not a
    traceback."""
    with pytest.raises(ShapeTreeError, match="height_weight"):
        MatchConfig(height_weight=1.5)
    with pytest.raises(ShapeTreeError, match="height_weight"):
        MatchConfig(height_weight=float("nan"))
    with pytest.raises(ShapeTreeError, match="height_points"):
        MatchConfig(height_points=4)
    with pytest.raises(ShapeTreeError, match="height_complexity"):
        MatchConfig(height_complexity="yes")
    cfg = MatchConfig(n_points=16, height_weight=0.3, height_points=16)
    line = np.c_[np.linspace(0, 1, 20), np.sin(np.linspace(0, 3, 20))]
    with pytest.raises(ShapeTreeError, match="closed curves only"):
        match(line, line, cfg, closed=False)
    with pytest.raises(ShapeTreeError, match="height distances"):
        combine(np.zeros((4, 4)), "none", 0.5)
