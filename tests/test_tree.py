"""Shape-tree construction, reconstruction and deformation (paper §2, §2.1)."""

from __future__ import annotations

import numpy as np
import pytest
from _shapes import blob, similarity

from shapetree import CurveError, ShapeTreeError
from shapetree.geometry import bookstein
from shapetree.tree import build_shape_tree, deform, reconstruct


@pytest.mark.parametrize("closed", [False, True])
@pytest.mark.parametrize("split", ["half", "best"])
@pytest.mark.parametrize("n", [3, 4, 5, 17, 64])
def test_structure(closed, split, n):
    pts = blob(n, np.random.default_rng(n), closed=closed)
    tree = build_shape_tree(pts, closed=closed, split=split)
    assert tree.n_nodes == n - 2  # every sample point but the anchors is a midpoint once
    u = tree.unrolled
    assert len(u) == (n + 1 if closed else n)
    mids = sorted(tree.mid.tolist())
    anchors = {0, tree.split_index, len(u) - 1}
    assert set(mids) | anchors == set(range(len(u)))
    for v in range(tree.n_nodes):
        s, i, e = tree.start[v], tree.mid[v], tree.end[v]
        assert s < i < e
        for child, (cs, ce) in ((tree.left[v], (s, i)), (tree.right[v], (i, e))):
            if child >= 0:
                assert child < v  # post-order: children first
                assert (tree.start[child], tree.end[child]) == (cs, ce)
                assert tree.depth[child] == tree.depth[v] + 1
            else:
                assert ce - cs == 1  # a missing child is a line segment
        np.testing.assert_allclose(tree.coords[v], bookstein(u[s], u[e], u[i]))
    if split == "half":
        np.testing.assert_array_equal(tree.mid, tree.start + (tree.end - tree.start) // 2)
        assert tree.max_depth <= int(np.ceil(np.log2(n))) + 1


def test_best_split_picks_the_corner():
    # an L-shaped open polyline: the best midpoint of the root is the corner
    pts = np.r_[np.c_[np.zeros(7), np.arange(7.0)[::-1]], np.c_[np.arange(1.0, 12), np.zeros(11)]]
    tree = build_shape_tree(pts, closed=False, split="best")
    root = tree.roots[0]
    assert tree.mid[root] == 6
    assert build_shape_tree(pts, closed=False).mid[root] == 8


@pytest.mark.parametrize("closed", [False, True])
@pytest.mark.parametrize("split", ["half", "best"])
def test_round_trip_exact(closed, split):
    rng = np.random.default_rng(5)
    for n in (3, 6, 33, 100):
        pts = blob(n, rng, closed=closed)
        for offset in (0, n // 3) if closed else (0,):
            tree = build_shape_tree(pts, closed=closed, split=split, offset=offset)
            rec = reconstruct(tree)
            expected = np.roll(pts, -offset, axis=0)
            assert np.abs(rec - expected).max() <= 1e-9


@pytest.mark.parametrize("closed", [False, True])
def test_moving_anchors_gives_similarity_transform(closed):
    rng = np.random.default_rng(7)
    pts = blob(40, rng, closed=closed)
    tree = build_shape_tree(pts, closed=closed)
    moved = similarity(pts, 1.1, 2.5, (4.0, -3.0))
    i0, i1 = tree.anchor_indices
    rec = reconstruct(tree, anchors=moved[[i0, i1]])
    assert np.abs(rec - moved).max() <= 1e-9


def test_deform_scale_zero_is_identity_and_noise_grows():
    rng = np.random.default_rng(3)
    pts = blob(64, rng)
    tree = build_shape_tree(pts, closed=True)
    np.testing.assert_allclose(deform(tree, 0.0, rng=1), pts, atol=1e-9)
    dev = []
    for scale in (0.02, 0.1):
        d = [np.abs(deform(tree, scale, rng=seed) - pts).mean() for seed in range(20)]
        dev.append(np.mean(d))
    assert dev[1] > 2 * dev[0]
    # per-depth scales: noise only at the deepest level moves only that level's midpoints
    depth_scale = np.zeros(tree.max_depth + 1)
    depth_scale[-1] = 0.2
    moved = np.abs(deform(tree, depth_scale, rng=0) - pts).max(axis=1) > 1e-12
    deepest = tree.mid[tree.depth == tree.max_depth] % len(pts)
    assert set(np.flatnonzero(moved)) == set(deepest.tolist())


def test_deform_is_reproducible_with_seed():
    tree = build_shape_tree(blob(30, np.random.default_rng(0)), closed=True)
    np.testing.assert_array_equal(deform(tree, 0.1, rng=42), deform(tree, 0.1, rng=42))


def test_errors_name_the_problem():
    with pytest.raises(ShapeTreeError, match="split"):
        build_shape_tree(blob(10, np.random.default_rng(0)), closed=True, split="thirds")
    with pytest.raises(CurveError):
        build_shape_tree(np.array([[0.0, 0.0], [1.0, 1.0]]), closed=False)
    with pytest.raises(CurveError, match="NaN"):
        build_shape_tree(np.array([[0.0, 0.0], [1.0, np.nan], [2, 0]]), closed=False)
    tree = build_shape_tree(blob(10, np.random.default_rng(0)), closed=True)
    with pytest.raises(ShapeTreeError, match="anchors"):
        reconstruct(tree, anchors=np.zeros((3, 2)))
    with pytest.raises(ShapeTreeError, match="distinct"):
        reconstruct(tree, anchors=np.zeros((2, 2)))
    with pytest.raises(ShapeTreeError, match="scale"):
        deform(tree, -1.0)
