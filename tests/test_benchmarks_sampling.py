"""The query-sample estimators of ``benchmarks/eval_beyond.py`` against the full protocols.

The held-out MPEG-7 and Swedish-leaf figures of the README that are marked as estimates
come from these functions; with every item a query they must give the full protocol's
numbers exactly (the oracle is :mod:`shapetree.retrieval`'s own protocol code).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from shapetree.retrieval import nn_accuracy_splits
from shapetree.retrieval._protocols import bullseye_per_query

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
eval_beyond = pytest.importorskip("eval_beyond")
row_store = pytest.importorskip("_row_store")


def _labels(n_classes: int, per_class: int) -> np.ndarray:
    return np.repeat([f"c{i}" for i in range(n_classes)], per_class)


def test_class_stratified_order_puts_the_sample_first() -> None:
    labels = _labels(4, 75)
    perm, ends = eval_beyond.class_stratified_order(labels, 8)
    assert sorted(perm.tolist()) == list(range(300))
    assert ends[0] == 4 * 10  # positions 0, 8, ..., 72 of each class
    assert ends[1] == 4 * 19  # then 4, 12, ..., 68
    assert ends[-1] == 300 and len(ends) == 8
    first = perm[: ends[0]]
    assert np.all(first % 75 % 8 == 0)
    for e in ends:  # every prefix ending at a group end is stratified
        counts = np.unique(labels[perm[:e]], return_counts=True)[1]
        assert counts.size == 4 and np.all(counts == e // 4)


def test_swedish_sample_with_every_item_is_the_protocol() -> None:
    rng = np.random.default_rng(3)
    labels = _labels(3, 40)
    D = rng.random((120, 120)) + 0.03 * (labels[:, None] != labels[None, :])
    mean, _ = nn_accuracy_splits(D, labels)
    rec, share = eval_beyond.swedish_sample_accuracy(D, np.arange(120), labels)
    assert rec["accuracy_mean"] == pytest.approx(mean, abs=0.005)
    assert 60.0 < mean < 100.0  # neither trivial nor chance
    assert share.shape == (120,) and np.all((share >= 0) & (share <= 1))


def test_swedish_sample_uses_only_the_sampled_rows() -> None:
    rng = np.random.default_rng(4)
    labels = _labels(3, 40)
    D = rng.random((120, 120))
    queries = np.arange(0, 120, 4)
    rec, _ = eval_beyond.swedish_sample_accuracy(D[queries], queries, labels)
    D2 = D.copy()
    others = np.setdiff1d(np.arange(120), queries)
    D2[others] = rng.random((others.size, 120))  # rows of non-sampled items do not matter
    rec2, _ = eval_beyond.swedish_sample_accuracy(D2[queries], queries, labels)
    assert rec == rec2


def test_mpeg7_sample_hits_are_the_bullseye_hits() -> None:
    rng = np.random.default_rng(5)
    labels = _labels(5, 20)
    D = rng.random((100, 100)) + 0.3 * (labels[:, None] != labels[None, :])
    np.fill_diagonal(D, 0.0)
    np.testing.assert_array_equal(
        eval_beyond._sample_hits(D, labels), bullseye_per_query(D, labels, k=40)
    )


def test_paired_reference_arithmetic() -> None:
    mine = np.array([1.0, 1.0, 0.0, 1.0])
    ref = np.array([1.0, 0.0, 0.0, 0.0])
    rec = eval_beyond._paired_reference(75.0, mine, ref, 25.0, "ref", 30.0)
    assert rec["paired_gain"] == 50.0
    assert rec["paired_estimate"] == 80.0
    assert rec["sample_minus_full"] == -5.0
    # standard error of the per-query differences (0, 1, 0, 1): std 0.577 / 2
    assert rec["paired_gain_stderr"] == pytest.approx(
        100 * np.std([0, 1, 0, 1], ddof=1) / 2, abs=0.01
    )


def test_swedish_nn_accuracy_with_every_item_is_the_protocol_mean_and_std() -> None:
    rng = np.random.default_rng(6)
    labels = _labels(3, 40)
    D = rng.random((120, 120)) + 0.02 * (labels[:, None] != labels[None, :])
    mean, std, accs = nn_accuracy_splits(D, labels, return_splits=True)
    queries = np.arange(120)
    nn = row_store.split_nn(D, queries, labels, eval_beyond.swedish_splits(labels))
    rec, _ = eval_beyond.swedish_nn_accuracy(nn, queries, labels)
    assert rec["accuracy_mean"] == pytest.approx(mean, abs=0.005)
    assert rec["accuracy_std_splits"] == pytest.approx(std, abs=0.005)
    np.testing.assert_allclose(rec["accuracy_splits"], accs, atol=0.005)
    # each query is a training leaf in the splits where nn says -1, and only there
    for s, train in enumerate(eval_beyond.swedish_splits(labels)):
        np.testing.assert_array_equal(nn[:, s] < 0, train)


def test_nearest_others_leaves_the_query_out() -> None:
    rows = np.array([[0.0, 3.0, 1.0, 2.0], [5.0, 0.0, 5.0, 1.0]])
    top = row_store.nearest_others(rows, np.array([0, 1]), k=2)
    np.testing.assert_array_equal(top, [[2, 3], [3, 0]])


def test_row_store_round_trip_and_foreign_key(tmp_path: Path) -> None:
    path = tmp_path / "rows.json"
    store = row_store.RowStore(path, "k1", {"what": "test"})
    store.add(0, 2, np.array([5, 3]), np.array([[1, -1], [0, 2]]), np.array([[1], [0]]))
    again = row_store.RowStore(path, "k1", {})
    assert again.rows == store.rows and again.blocks == {(0, 2)}
    assert again.prefix(np.array([5, 3, 4])) == 2 and again.prefix(np.array([4, 5])) == 0
    np.testing.assert_array_equal(again.nn(np.array([3])), [[0, 2]])
    other = row_store.RowStore(path, "k2", {})  # other code or options: not read
    assert other.rows == {} and other.prefix(np.array([5])) == 0


def test_row_store_fill_matches_the_engine(tmp_path: Path) -> None:
    from shapetree.matching import MatchConfig
    from shapetree.retrieval import directed_costs

    t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    rng = np.random.default_rng(7)
    curves = [
        np.c_[(1 + a * np.cos(k * t)) * np.cos(t), (1 + a * np.cos(k * t)) * np.sin(t)]
        for k, a in zip([2, 2, 3, 3, 4, 4], rng.uniform(0.1, 0.3, 6), strict=True)
    ]
    labels = np.array(["b", "b", "c", "c", "d", "d"])
    cfg = MatchConfig(n_points=12, n_trees=1, mirror=False, phases=1, symmetrize="none")
    perm = np.array([0, 2, 4, 1, 3, 5])
    ordered = [curves[i] for i in perm]
    splits = [np.array([1, 0, 1, 0, 0, 1], bool), np.array([0, 1, 0, 1, 1, 0], bool)]
    from shapetree.retrieval._engine import _cache_key, _prep_models, _prep_targets

    key = _cache_key(_prep_models(ordered, cfg, "m"), _prep_targets(ordered, cfg, "t"), cfg)
    store = row_store.RowStore(tmp_path / "rows.json", key, {})
    row_store.fill(store, ordered, cfg, tmp_path / "cache", perm, labels, splits, upto=4, block=2)
    assert store.prefix(perm) == 4  # two blocks of two, the third not asked for
    C = directed_costs(curves, None, cfg, progress=False).min(axis=0)
    q = perm[:4]
    np.testing.assert_array_equal(store.nn(q), row_store.split_nn(C[q], q, labels, splits))
    np.testing.assert_array_equal(store.top(q), row_store.nearest_others(C[q], q))
    # resumed from the file alone (no engine cache): only the missing block is computed
    fresh = row_store.RowStore(tmp_path / "rows.json", key, {})
    row_store.fill(
        fresh, ordered, cfg, tmp_path / "other_cache", perm, labels, splits, upto=6, block=2
    )
    assert fresh.prefix(perm) == 6 and fresh.blocks == {(0, 2), (2, 4), (4, 6)}
    np.testing.assert_array_equal(fresh.nn(perm), row_store.split_nn(C[perm], perm, labels, splits))
    assert len(list((tmp_path / "other_cache").glob("*/*.blk"))) == 1  # rows 4-6 only


def test_row_store_adopts_a_foreign_file_only_when_rows_are_reproduced(tmp_path: Path) -> None:
    from shapetree.matching import MatchConfig

    t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    curves = [
        np.c_[(1 + a * np.cos(k * t)) * np.cos(t), (1 + a * np.cos(k * t)) * np.sin(t)]
        for k, a in [(2, 0.1), (2, 0.2), (3, 0.1), (3, 0.25), (4, 0.15), (4, 0.3)]
    ]
    labels = np.array(["b", "b", "c", "c", "d", "d"])
    cfg = MatchConfig(n_points=12, n_trees=1, mirror=False, phases=1, symmetrize="none")
    perm = np.array([0, 2, 4, 1, 3, 5])
    ordered = [curves[i] for i in perm]
    splits = [np.array([1, 0, 1, 0, 0, 1], bool), np.array([0, 1, 0, 1, 1, 0], bool)]
    path = tmp_path / "rows.json"
    old = row_store.RowStore(path, "old-code", {"what": "test"})
    row_store.fill(old, ordered, cfg, tmp_path / "c", perm, labels, splits, upto=6, block=2)
    rows = dict(old.rows)

    new = row_store.RowStore(path, "new-code", {"what": "test"})
    assert new.rows == {} and new.foreign is not None
    assert row_store.adopt(new, ordered, cfg, perm, labels, splits, check=3, workers=1)
    assert new.rows == rows and new.blocks == {(0, 2), (2, 4), (4, 6)}
    (record,) = new.meta["adopted"]
    assert record["from_key"] == "old-code" and record["identical"] == 3
    assert record["checked_queries"] == [0, 4, 5]  # first, middle and last of the order
    again = row_store.RowStore(path, "new-code", {"what": "test"})  # read back as its own
    assert again.rows == rows and again.meta["adopted"] == [record]
    assert not row_store.adopt(again, ordered, cfg, perm, labels, splits, check=3, workers=1)

    # one row that the current code does not reproduce: nothing is adopted
    store = row_store.RowStore(path, "newer", {})
    store.foreign["rows"]["4"] = {"nn": rows[4]["nn"], "top": rows[4]["top"][::-1]}
    assert not row_store.adopt(store, ordered, cfg, perm, labels, splits, check=6, workers=1)
    assert store.rows == {} and store.foreign is not None
