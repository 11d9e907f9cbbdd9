"""``knn`` (pruned by the lower bound) returns exactly what exhaustive ``search`` returns.

Indices and distances must be equal arrays (the same kernel calls, the same ties by
index) for every query, under presets with mirror, phases, several trees, band,
occlusion, no band, and the symmetrized distances; on Kimia-99 at small sizes so that it
stays fast, with exact ties, and with bounds that prune (a database of copies of a few
shapes).
"""

from __future__ import annotations

import zlib

import numpy as np
import pytest
from _shapes import blob

from shapetree._errors import ShapeTreeError
from shapetree.retrieval import search
from shapetree.retrieval._knn import knn


def _seed(*key: object) -> int:
    return zlib.crc32(repr(key).encode())


@pytest.fixture(scope="module")
def kimia():
    from shapetree.datasets import load

    return load("kimia99", n_points=None, progress=False).curves


def _exhaustive(queries, database, preset, k, **options):
    rows = [search(q, database, preset, k=k, progress=False, **options) for q in queries]
    return np.array([r[0] for r in rows]), np.array([r[1] for r in rows])


@pytest.mark.parametrize(
    ("preset", "options", "k"),
    [
        ("kimia99", {"n_points": 20}, 10),
        ("mpeg7", {"n_points": 16}, 5),
        ("paper", {"n_points": 20, "keep_top": 3, "keep_from": None}, 10),
        ("general", {"n_points": 16, "keep_from": 1}, 1),
        ("kimia99", {"n_points": 16, "symmetrize": "min"}, 8),
        ("mpeg7", {"n_points": 16, "symmetrize": "mean", "phases": 1}, 4),
        ("paper", {"n_points": 16, "symmetrize": "max"}, 6),
        ("general", {"n_points": 16, "symmetrize": "reverse"}, 6),
        ("kimia99", {"n_points": 16, "tree_combine": "mean"}, 8),
        # the height-function fusion: h exact, the bound B^(1 - w) h^w (every direction)
        ("fused", {"n_points": 16, "height_points": 24, "n_trees": 1}, 6),
        ("fused", {"n_points": 16, "height_points": 16, "symmetrize": "min"}, 5),
        ("fused", {"n_points": 16, "height_points": 20, "symmetrize": "reverse"}, 4),
        ("general", {"n_points": 16, "height_weight": 1.0, "height_points": 16}, 5),
        ("paper", {"n_points": 16, "height_weight": 0.3, "symmetrize": "mean"}, 3),
    ],
)
def test_knn_equals_exhaustive_search_on_kimia99(kimia, preset, options, k):
    rng = np.random.default_rng(_seed("knn", preset, sorted(options.items()), k))
    queries = [kimia[i] for i in rng.choice(len(kimia), 5, replace=False)]
    keep = {key: options.pop(key) for key in ("keep_top", "keep_from") if key in options}
    stats: dict = {}
    idx, dist = knn(queries, kimia, preset, k=k, stats=stats, **keep, **options)
    ref_idx, ref_dist = _exhaustive(queries, kimia, preset, k, **options)
    np.testing.assert_array_equal(idx, ref_idx)
    np.testing.assert_array_equal(dist, ref_dist)
    assert stats["pairs"] == len(queries) * len(kimia)
    assert 0.0 <= stats["skipped"] < 1.0
    assert stats["full"] >= len(queries) * k
    assert len(stats["full_per_query"]) == len(queries)


def test_knn_prunes_and_keeps_ties_by_index():
    """Copies of three shapes: exact ties (ranked by index) and bounds that prune."""
    rng = np.random.default_rng(_seed("knn-ties"))
    shapes = [blob(40, rng, wobble=0.3) for _ in range(3)]
    database = [shapes[i % 3] for i in range(30)]
    queries = [shapes[0], shapes[2]]
    stats: dict = {}
    idx, dist = knn(queries, database, "paper", n_points=16, k=4, stats=stats, workers=1)
    ref_idx, ref_dist = _exhaustive(queries, database, "paper", 4, n_points=16)
    np.testing.assert_array_equal(idx, ref_idx)
    np.testing.assert_array_equal(dist, ref_dist)
    assert list(idx[0]) == [0, 3, 6, 9]  # equal distances: by index
    assert stats["skipped"] > 0.3  # the other shapes' bounds exceed the copies' ~0 cost
    # strict best-first in small rounds: the same answer
    idx2, dist2 = knn(queries, database, "paper", n_points=16, k=4, batch=1, workers=2)
    np.testing.assert_array_equal(idx2, ref_idx)
    np.testing.assert_array_equal(dist2, ref_dist)


def test_knn_k_larger_than_database_and_one_query(kimia):
    db = kimia[:7]
    idx, dist = knn([kimia[20]], db, "general", n_points=12, k=50)
    ref_idx, ref_dist = search(kimia[20], db, "general", n_points=12)
    np.testing.assert_array_equal(idx[0], ref_idx)
    np.testing.assert_array_equal(dist[0], ref_dist)
    assert idx.shape == (1, 7)


def test_knn_refuses_bad_arguments(kimia):
    db = kimia[:5]
    for bad in (0, -1, 2.5, True):
        with pytest.raises(ShapeTreeError, match="k must"):
            knn([kimia[0]], db, n_points=12, k=bad)
    with pytest.raises(ShapeTreeError, match="workers"):
        knn([kimia[0]], db, n_points=12, workers=0)
    with pytest.raises(ShapeTreeError, match="at least one"):
        knn([], db, n_points=12)
    with pytest.raises(ShapeTreeError, match="at least one"):
        knn([kimia[0]], [], n_points=12)
    with pytest.raises(ShapeTreeError, match="n_points"):
        knn([kimia[0]], db, n_points=None, phases=1, target_factor=1)


def test_knn_blocks_and_cache_resume(kimia, tmp_path):
    """Blocks of queries give the same answer as one block; a second run reads every block
    from the cache; a damaged block is recomputed."""
    queries, db = kimia[:9], kimia[:30]
    ref_idx, ref_dist = knn(queries, db, "kimia99", n_points=14, k=5, workers=1, block=9)
    stats: dict = {}
    idx, dist = knn(
        queries, db, "kimia99", n_points=14, k=5, block=2, cache_dir=tmp_path, stats=stats
    )
    np.testing.assert_array_equal(idx, ref_idx)
    np.testing.assert_array_equal(dist, ref_dist)
    assert stats["blocks"] == 5 and stats["blocks_cached"] == 0
    full = stats["full"]
    again: dict = {}
    idx2, dist2 = knn(
        queries, db, "kimia99", n_points=14, k=5, block=2, cache_dir=tmp_path, stats=again
    )
    np.testing.assert_array_equal(idx2, ref_idx)
    np.testing.assert_array_equal(dist2, ref_dist)
    assert again["blocks_cached"] == 5 and again["full"] == full
    blocks = sorted(tmp_path.glob("knn-*/*.blk"))
    assert len(blocks) == 5
    blocks[1].write_bytes(blocks[1].read_bytes()[:-8] + b"\x01" * 8)
    with pytest.warns(UserWarning, match="damaged"):
        idx3, _ = knn(queries, db, "kimia99", n_points=14, k=5, block=2, cache_dir=tmp_path)
    np.testing.assert_array_equal(idx3, ref_idx)
    # another k is another cache entry, never a mix
    idx4, _ = knn(queries, db, "kimia99", n_points=14, k=3, block=2, cache_dir=tmp_path)
    np.testing.assert_array_equal(idx4, ref_idx[:, :3])
    assert len(list(tmp_path.glob("knn-*"))) == 2


@pytest.mark.parametrize(
    ("name", "params"),
    [
        ("kimia99", {"n_points": 14}),
        ("mpeg7", {"n_points": 14, "per_class": 8, "k": 8}),
        ("swedish_leaf", {"n_points": 14, "per_class": 28, "n_splits": 4}),
    ],
)
def test_evaluate_with_neighbours_equals_exhaustive(name, params):
    """The protocol's score from each shape's K nearest (pruned search) is the exhaustive
    one; for Swedish leaf a small K forces some rows to be completed in full."""
    from shapetree.datasets import load
    from shapetree.retrieval import evaluate

    classes = sorted(set(load(name, n_points=None, progress=False).labels))
    params = dict(params, classes=",".join(classes[:3] if name == "kimia99" else classes[:4]))
    kw = dict(progress=False, verbose=False, workers=2, **params)
    full = evaluate(name, name, **kw)
    need = {"kimia99": 11, "mpeg7": params.get("k", 40) + 1, "swedish_leaf": 2}[name]
    pruned = evaluate(name, name, neighbours=need, **kw)
    for key in ("ranks", "bullseye", "bullseye_per_class", "accuracy_splits"):
        if key in full:
            assert pruned[key] == full[key], key
    nb = pruned["neighbours"]
    assert nb["k"] == need and 0 <= nb["skipped"] < 1
    assert pruned["pairs_computed"] == nb["full_matchings"] <= full["pairs_computed"]
    if name == "swedish_leaf":
        assert nb["rows_completed"] > 0  # K=2: some test shapes had no training neighbour
    with pytest.raises(ShapeTreeError, match=f"needs each shape's {need} nearest"):
        evaluate(name, name, neighbours=need - 1, **kw)
    with pytest.raises(ShapeTreeError, match="rerank"):
        evaluate(name, name, neighbours=need, rerank="tpg", **kw)
