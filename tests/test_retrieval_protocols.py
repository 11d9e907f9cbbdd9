"""Retrieval protocols on hand-made matrices with known answers."""

from __future__ import annotations

import numpy as np
import pytest

from shapetree import ShapeTreeError
from shapetree.retrieval import (
    bullseye,
    bullseye_per_class,
    combine,
    kimia_ranks,
    nn_accuracy_splits,
    ranked_neighbours,
)
from shapetree.retrieval._protocols import bullseye_per_query


def _block_matrix(labels: np.ndarray, noise: float = 0.0, seed: int = 0) -> np.ndarray:
    """Distances 0..1 within a class, 10.. across classes."""
    rng = np.random.default_rng(seed)
    n = labels.size
    d = rng.uniform(0.1, 1.0, (n, n)) + 10.0 * (labels[:, None] != labels[None, :])
    d += noise * rng.standard_normal((n, n))
    np.fill_diagonal(d, 0.0)
    return d


def test_bullseye_perfect_and_half() -> None:
    lab = np.repeat(np.array(["a", "b", "c"]), 4)
    d = _block_matrix(lab)
    assert bullseye(d, lab, k=8) == 100.0
    assert bullseye(d, lab, k=4) == 100.0
    # k=2: 2 hits out of min(2, 4) per query
    assert bullseye(d, lab, k=2) == 100.0
    # worst case: every other class closer than own class (except self)
    d2 = 10.0 - _block_matrix(lab) + 0.0
    np.fill_diagonal(d2, 0.0)
    # each query: self + 3 others; k=4 -> self(hit) + 3 foreign = 1/4
    assert bullseye(d2, lab, k=4) == pytest.approx(25.0)
    assert bullseye_per_query(d2, lab, k=4).tolist() == [1] * 12


def test_bullseye_known_counts() -> None:
    lab = np.array(["a", "a", "b", "b"])
    d = np.array(
        [
            [0, 3, 1, 5],  # a: neighbours b(2), a(1) -> k=2 -> self + b -> 1 hit
            [3, 0, 5, 5],  # a: self + (0 at 3 vs b 5) -> 2
            [1, 5, 0, 2],  # b: self + a(0) -> 1
            [5, 5, 2, 0],  # b: self + b -> 2
        ],
        dtype=float,
    )
    assert bullseye_per_query(d, lab, k=2).tolist() == [1, 2, 1, 2]
    assert bullseye(d, lab, k=2) == pytest.approx(100 * 6 / 8)
    assert bullseye_per_class(d, lab, k=2) == {"a": 75.0, "b": 75.0}


def test_self_ranks_first_even_with_ties() -> None:
    d = np.zeros((3, 3))
    assert ranked_neighbours(d)[:, 0].tolist() == [0, 1, 2]
    assert ranked_neighbours(d, exclude_self=True).tolist() == [[1, 2], [0, 2], [0, 1]]


def test_kimia_ranks_known() -> None:
    lab = np.array(["a", "a", "a", "b", "b", "b"])
    d = _block_matrix(lab)
    assert kimia_ranks(d, lab, n_ranks=3).tolist() == [6, 6, 0]
    # make item 0's nearest other a "b"
    d[0, 3] = 0.01
    r = kimia_ranks(d, lab, n_ranks=3)
    assert r[0] == 5 and r[1] == 6 and r[2] == 1
    # default length is 10, ints
    lab99 = np.repeat(np.arange(9), 11).astype(str)
    r10 = kimia_ranks(_block_matrix(lab99), lab99)
    assert r10.tolist() == [99] * 10 and r10.dtype.kind == "i"


def test_nn_accuracy_splits() -> None:
    lab = np.repeat(np.array(["x", "y", "z"]), 30)
    mean, std = nn_accuracy_splits(_block_matrix(lab), lab, n_train=10, n_splits=5, seed=1)
    assert (mean, std) == (100.0, 0.0)
    # a random matrix is at chance level, and splits are reproducible per seed
    d = np.random.default_rng(3).uniform(size=(90, 90))
    m1, s1, a1 = nn_accuracy_splits(d, lab, n_train=10, n_splits=20, seed=7, return_splits=True)
    m2, s2 = nn_accuracy_splits(d, lab, n_train=10, n_splits=20, seed=7)
    assert (m1, s1) == (m2, s2) and a1.shape == (20,)
    assert 20 < m1 < 47
    # one test item per class deliberately confused: 3 of 60 tests wrong (when it is a test)
    with pytest.raises(ShapeTreeError):
        nn_accuracy_splits(d, lab, n_train=30)


def test_combine() -> None:
    c = np.array([[[0.0, 1.0], [3.0, 0.0]], [[0.0, 2.0], [0.5, 0.0]]])
    assert combine(c, "none").tolist() == [[0, 1], [0.5, 0]]
    assert combine(c, None).tolist() == [[0, 1], [0.5, 0]]
    assert combine(c, "min").tolist() == [[0, 0.5], [0.5, 0]]
    assert combine(c, "mean").tolist() == [[0, 0.75], [0.75, 0]]
    assert combine(c, "max").tolist() == [[0, 1], [1, 0]]
    assert combine(c, "reverse").tolist() == [[0, 0.5], [1, 0]]
    with pytest.raises(ShapeTreeError):
        combine(c, "median")


def test_bad_inputs() -> None:
    with pytest.raises(ShapeTreeError):
        bullseye(np.zeros((3, 2)), ["a", "b", "c"])
    with pytest.raises(ShapeTreeError):
        kimia_ranks(np.zeros((3, 3)), ["a", "b"])
    with pytest.raises(ShapeTreeError):
        bullseye(np.full((2, 2), np.nan), ["a", "b"])
