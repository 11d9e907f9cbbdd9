"""Retrieval and classification protocols of the paper's §5.1 (Tables 1–3)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from shapetree._errors import ShapeTreeError

__all__ = [
    "bullseye",
    "bullseye_per_class",
    "bullseye_per_query",
    "kimia_ranks",
    "nn_accuracy_splits",
    "ranked_neighbours",
]


def _check(D: ArrayLike, labels: ArrayLike, square: bool = True) -> tuple[np.ndarray, np.ndarray]:
    d = np.asarray(D, dtype=np.float64)
    lab = np.asarray(labels)
    if d.ndim != 2 or (square and d.shape[0] != d.shape[1]):
        raise ShapeTreeError(f"distance matrix must be square 2-D, got shape {d.shape}")
    if lab.shape != (d.shape[0],):
        raise ShapeTreeError(f"need one label per row: {lab.shape} labels for {d.shape} matrix")
    if np.isnan(d).any():
        raise ShapeTreeError("distance matrix contains NaN")
    return d, lab


def ranked_neighbours(D: ArrayLike, *, exclude_self: bool = False) -> np.ndarray:
    """Database indices of each query sorted by increasing distance (ties by index).

    Parameters
    ----------
    D : array_like, shape (n, n)
        ``D[q, j]``: distance of item ``j`` to query ``q``.
    exclude_self : bool
        Drop the query itself from its own ranking.

    Returns
    -------
    ndarray of int, shape (n, n) or (n, n - 1)
    """
    d = np.asarray(D, dtype=np.float64)
    if exclude_self:
        d = d.copy()
        np.fill_diagonal(d, np.inf)
        return np.argsort(d, axis=1, kind="stable")[:, :-1]
    # the query ranks first among items at its own distance (normally 0)
    d = d.copy()
    np.fill_diagonal(d, -np.inf)
    return np.argsort(d, axis=1, kind="stable")


def bullseye_per_query(D: ArrayLike, labels: ArrayLike, k: int = 40) -> np.ndarray:
    """Same-class hits among each query's ``k`` nearest items (the query included).

    Parameters
    ----------
    D : array_like, shape (n, n)
    labels : array_like, shape (n,)
    k : int

    Returns
    -------
    ndarray of int, shape (n,)
    """
    d, lab = _check(D, labels)
    order = ranked_neighbours(d)[:, :k]
    return (lab[order] == lab[:, None]).sum(axis=1)


def bullseye(D: ArrayLike, labels: ArrayLike, k: int = 40) -> float:
    """Bull's-eye score (MPEG-7 protocol), in percent.

    For each query, the same-class items among its ``k`` nearest (itself included) are
    counted; the total is divided by the best possible total, ``Σ_q min(k, |class(q)|)``
    (``1400 · 20`` for MPEG-7).

    Parameters
    ----------
    D : array_like, shape (n, n)
        ``D[q, j]``: distance of item ``j`` to query ``q``.
    labels : array_like, shape (n,)
    k : int
        Neighbourhood size (40 = twice the class size for MPEG-7).

    Returns
    -------
    float
        Percentage in ``[0, 100]``.

    Examples
    --------
    >>> D = [[0, 1, 5, 5], [1, 0, 5, 5], [5, 5, 0, 1], [5, 5, 1, 0]]
    >>> bullseye(D, ["a", "a", "b", "b"], k=2)
    100.0
    """
    d, lab = _check(D, labels)
    hits = bullseye_per_query(d, lab, k)
    _, inv, counts = np.unique(lab, return_inverse=True, return_counts=True)
    best = np.minimum(k, counts[inv])
    return float(100.0 * hits.sum() / best.sum())


def bullseye_per_class(D: ArrayLike, labels: ArrayLike, k: int = 40) -> dict[str, float]:
    """Bull's-eye score of each class's queries, in percent.

    Parameters
    ----------
    D : array_like, shape (n, n)
    labels : array_like, shape (n,)
    k : int

    Returns
    -------
    dict
        ``{class: percentage}`` in sorted class order.
    """
    d, lab = _check(D, labels)
    hits = bullseye_per_query(d, lab, k)
    out = {}
    for c in sorted(set(lab.tolist())):
        sel = lab == c
        out[str(c)] = float(100.0 * hits[sel].sum() / (sel.sum() * min(k, sel.sum())))
    return out


def kimia_ranks(D: ArrayLike, labels: ArrayLike, n_ranks: int = 10) -> np.ndarray:
    """Kimia-99 protocol: same-class counts at ranks 1..10 (the query excluded).

    Parameters
    ----------
    D : array_like, shape (n, n)
    labels : array_like, shape (n,)
    n_ranks : int

    Returns
    -------
    ndarray of int, shape (n_ranks,)
        Entry ``r``: number of queries whose ``(r+1)``-th nearest other shape is in the
        query's class (at most ``n``; 99 for Kimia-99).

    Examples
    --------
    >>> D = [[0, 1, 2], [1, 0, 3], [2, 3, 0]]
    >>> kimia_ranks(D, ["a", "a", "b"], n_ranks=2).tolist()
    [2, 0]
    """
    d, lab = _check(D, labels)
    order = ranked_neighbours(d, exclude_self=True)[:, :n_ranks]
    return (lab[order] == lab[:, None]).sum(axis=0).astype(int)


def split_masks(labels: ArrayLike, n_train: int, n_splits: int, seed: int) -> list[np.ndarray]:
    """The training sets of the Swedish-leaf splits (:func:`nn_accuracy_splits`).

    Parameters
    ----------
    labels : array_like, shape (n,)
    n_train, n_splits, seed : int

    Returns
    -------
    list of ndarray of bool, each shape (n,)
        ``True`` for the training items of each split, ``n_train`` per class, drawn by
        ``numpy.random.default_rng(seed)``.
    """
    lab = np.asarray(labels)
    rng = np.random.default_rng(seed)
    classes = sorted(set(lab.tolist()))
    out = []
    for _ in range(n_splits):
        train = np.zeros(lab.shape[0], dtype=bool)
        for c in classes:
            idx = np.flatnonzero(lab == c)
            if idx.size <= n_train:
                raise ShapeTreeError(f"class {c!r} has {idx.size} items, needs > {n_train}")
            train[rng.choice(idx, n_train, replace=False)] = True
        out.append(train)
    return out


def nn_accuracy_splits(
    D: ArrayLike,
    labels: ArrayLike,
    n_train: int = 25,
    n_splits: int = 10,
    seed: int = 0,
    *,
    return_splits: bool = False,
) -> tuple[float, float] | tuple[float, float, np.ndarray]:
    """Swedish-leaf protocol: 1-NN accuracy over random per-class train/test splits.

    Each split draws ``n_train`` training items per class (``numpy.random.default_rng``
    seeded with ``seed``); every other item is classified by its nearest training item
    (row = test query, column = training item).

    Parameters
    ----------
    D : array_like, shape (n, n)
    labels : array_like, shape (n,)
    n_train : int
        Training items per class.
    n_splits : int
    seed : int
    return_splits : bool
        Also return each split's accuracy.

    Returns
    -------
    mean, std : float
        Percentages (``std`` is the population standard deviation over the splits).
    accuracies : ndarray, shape (n_splits,)
        Only with ``return_splits``.
    """
    d, lab = _check(D, labels)
    accs = np.empty(n_splits)
    for s, train in enumerate(split_masks(lab, n_train, n_splits, seed)):
        tr, te = np.flatnonzero(train), np.flatnonzero(~train)
        nn = tr[np.argmin(d[np.ix_(te, tr)], axis=1)]
        accs[s] = 100.0 * np.mean(lab[nn] == lab[te])
    mean, std = float(accs.mean()), float(accs.std())
    return (mean, std, accs) if return_splits else (mean, std)
