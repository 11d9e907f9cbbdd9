"""TPG diffusion re-ranking: closed-form oracle, properties, and a case it must fix."""

from __future__ import annotations

import numpy as np
import pytest

from shapetree import ShapeTreeError
from shapetree.retrieval import bullseye, tpg_rerank
from shapetree.retrieval._rerank import knn_affinity


def _points_on_chains(
    n_chains: int = 3, per: int = 12, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Classes that are long thin chains: far ends of a chain are farther apart than
    neighbouring chains, so pairwise distances mix classes and context separates them."""
    rng = np.random.default_rng(seed)
    pts, lab = [], []
    for c in range(n_chains):
        t = np.linspace(0.0, 6.0, per)
        pts.append(
            np.stack([t, np.full(per, 1.2 * c)], axis=1) + 0.05 * rng.standard_normal((per, 2))
        )
        lab += [c] * per
    p = np.concatenate(pts)
    return np.linalg.norm(p[:, None] - p[None], axis=-1), np.array(lab)


def test_knn_affinity_rows() -> None:
    d, _ = _points_on_chains()
    p = knn_affinity(d, k=5, k_sigma=4)
    assert np.allclose(p.sum(axis=1), 1.0)
    assert ((p > 0).sum(axis=1) == 5).all()
    # the item itself is always among its own neighbours
    assert (np.diag(p) > 0).all()


def test_fixed_point_equals_closed_form() -> None:
    """Q = sum_t P^t (P^T)^t solves vec(Q) = (I - P kron P)^-1 vec(I)."""
    rng = np.random.default_rng(1)
    x = rng.uniform(size=(7, 2))
    d = np.linalg.norm(x[:, None] - x[None], axis=-1)
    alpha, k = 0.7, 3
    p = alpha * knn_affinity(d, k=k, k_sigma=3)
    n = len(d)
    q = np.linalg.solve(np.eye(n * n) - np.kron(p, p), np.eye(n).ravel()).reshape(n, n)
    q = 0.5 * (q + q.T)
    got = tpg_rerank(d, k=k, alpha=alpha, k_sigma=3, tol=1e-14)
    assert np.allclose(got, q.max() - q, atol=1e-10)


def test_rerank_is_symmetric_and_self_nearest() -> None:
    d, _ = _points_on_chains()
    r = tpg_rerank(d, k=5)
    assert r.shape == d.shape
    assert np.allclose(r, r.T)
    assert (r >= 0).all()
    assert (np.argmin(r, axis=1) == np.arange(len(r))).all()


def test_rerank_follows_the_chains() -> None:
    d, lab = _points_on_chains()
    before = bullseye(d, lab, k=12)
    after = bullseye(tpg_rerank(d, k=4, k_sigma=3), lab, k=12)
    assert before < 80.0
    assert after > before + 10.0


@pytest.mark.parametrize(
    ("bad", "msg"),
    [
        (np.zeros((3, 4)), "square"),
        (np.array([[0.0, np.nan, 1], [1, 0, 1], [1, 1, 0]]), "NaN"),
        (np.array([[0.0, -1.0, 1], [1, 0, 1], [1, 1, 0]]), "negative"),
        (np.zeros((2, 2)), "at least 3"),
    ],
)
def test_bad_inputs(bad: np.ndarray, msg: str) -> None:
    with pytest.raises(ShapeTreeError, match=msg):
        tpg_rerank(bad)


def test_bad_parameters() -> None:
    d, _ = _points_on_chains()
    with pytest.raises(ShapeTreeError, match="alpha"):
        tpg_rerank(d, alpha=1.0)
    with pytest.raises(ShapeTreeError, match="k must"):
        tpg_rerank(d, k=0)


def test_defaults_adapt_to_small_sets() -> None:
    d, _ = _points_on_chains(n_chains=2, per=3)  # 6 items < the default 10 neighbours
    r = tpg_rerank(d)
    assert r.shape == (6, 6) and np.isfinite(r).all()
    with pytest.raises(ShapeTreeError, match="k_sigma"):
        tpg_rerank(d, k_sigma=6)
