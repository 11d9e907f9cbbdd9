"""Per-query summaries of a long exhaustive Swedish-leaf run, kept in the repository.

The full 1125 x 1125 matrix of the no-time-limit choice takes about 5 h of both cores:
more than one session, and the engine's block cache (``~/.cache/shapetree``) does not
outlive the machine it was written on. What the paper's protocol needs from a query's
row is small: in each of the seeded splits, its nearest training leaf (or that it is a
training leaf there). Those, with the query's 9 nearest leaves (for the worst-queries
grid), are written to a JSON file in ``benchmarks/results/`` after every block of rows,
so a run resumes from the committed file on any machine.

The file is tied to the engine's cache key of the whole problem (code fingerprint,
options, the sampled curves in the run's order): a file made by other code, other options
or another order is not read.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from shapetree._atomic import atomic_write_bytes
from shapetree.matching import MatchConfig

#: Nearest leaves kept per query (the worst-queries grid shows 9).
N_NEAREST = 9


def split_nn(
    rows: np.ndarray, queries: np.ndarray, labels: np.ndarray, splits: list[np.ndarray]
) -> np.ndarray:
    """Each query's nearest training item in every split, ``-1`` where it trains.

    Parameters
    ----------
    rows : ndarray, shape (r, n)
        Query ``queries[i]``'s costs to every item (set order).
    queries : ndarray of int, shape (r,)
    labels : ndarray, shape (n,)
    splits : list of ndarray of bool, shape (n,)
        Training masks (:func:`shapetree.retrieval._protocols.split_masks`).

    Returns
    -------
    ndarray of int, shape (r, len(splits))
        The first of the nearest, as ``numpy.argmin`` over the training items in set
        order (the tie rule of ``nn_accuracy_splits``).
    """
    nn = np.full((len(queries), len(splits)), -1, dtype=np.int64)
    for s, train in enumerate(splits):
        tr = np.flatnonzero(train)
        te = np.flatnonzero(~train[queries])
        if te.size:
            nn[te, s] = tr[np.argmin(rows[np.ix_(te, tr)], axis=1)]
    return nn


def nearest_others(rows: np.ndarray, queries: np.ndarray, k: int = N_NEAREST) -> np.ndarray:
    """The ``k`` nearest items of each query, itself left out (stable order)."""
    d = np.array(rows, dtype=float)
    d[np.arange(len(queries)), queries] = np.inf
    return np.argsort(d, axis=1, kind="stable")[:, :k]


class RowStore:
    """The per-query summaries of one run: ``nn`` (splits) and ``top`` (nearest) by query.

    Parameters
    ----------
    path : Path
        The JSON file (read if it exists and belongs to ``key``; written by :meth:`save`).
    key : str
        The engine's cache key of the whole problem.
    meta : dict
        Stored beside the rows (configuration, order, protocol), for the reader.
    """

    def __init__(self, path: Path, key: str, meta: dict[str, Any]) -> None:
        self.path, self.key, self.meta = Path(path), key, meta
        self.rows: dict[int, dict[str, list[int]]] = {}
        self.blocks: set[tuple[int, int]] = set()
        if self.path.exists():
            data = json.loads(self.path.read_text())
            if data.get("key") == key:
                self.rows = {int(q): v for q, v in data["rows"].items()}
                self.blocks = {(int(a), int(b)) for a, b in data["blocks"]}
            else:
                print(
                    f"{self.path.name}: made by other code, options or order "
                    f"(key {str(data.get('key'))[:12]}, now {key[:12]}): starting afresh",
                    flush=True,
                )

    def add(self, r0: int, r1: int, queries: np.ndarray, nn: np.ndarray, top: np.ndarray) -> None:
        """Record block ``[r0, r1)`` (the run's order) and write the file atomically."""
        for q, a, b in zip(queries.tolist(), nn.tolist(), top.tolist(), strict=True):
            self.rows[int(q)] = {"nn": a, "top": b}
        self.blocks.add((r0, r1))
        self.save()

    def save(self) -> None:
        data = dict(
            self.meta,
            key=self.key,
            blocks=sorted(self.blocks),
            n_rows=len(self.rows),
            rows={str(q): self.rows[q] for q in sorted(self.rows)},
        )
        text = json.dumps(data, separators=(",", ":"))
        # one query per line keeps the file's diffs readable
        text = text.replace('},"', '},\n"')
        atomic_write_bytes(self.path, (text + "\n").encode(), fsync=True)

    def prefix(self, order: np.ndarray) -> int:
        """How many leading items of ``order`` have their row recorded."""
        for i, q in enumerate(order.tolist()):
            if q not in self.rows:
                return i
        return len(order)

    def nn(self, queries: np.ndarray) -> np.ndarray:
        return np.array([self.rows[int(q)]["nn"] for q in queries], dtype=np.int64)

    def top(self, queries: np.ndarray) -> np.ndarray:
        return np.array([self.rows[int(q)]["top"] for q in queries], dtype=np.int64)


def fill(
    store: RowStore,
    curves: list[np.ndarray],
    cfg: MatchConfig,
    cache: Path,
    perm: np.ndarray,
    labels: np.ndarray,
    splits: list[np.ndarray],
    *,
    upto: int,
    block: int,
    workers: int = 2,
) -> None:
    """Record the rows of the first ``upto`` curves (in the run's order ``perm``; ``curves``
    is the set in that order) that ``store`` lacks. They are computed by
    :func:`shapetree.retrieval.directed_costs`, ``workers`` blocks of ``block`` rows at a
    time (cached in ``cache`` under that call's key, so a run killed on this machine
    re-reads them); each block is written to the store's file as soon as its chunk is
    done. The outer bar counts rows, the inner one the chunk's pairs."""
    from tqdm.auto import tqdm

    from shapetree.retrieval import directed_costs

    n = len(curves)
    inv = np.argsort(perm)
    starts = [
        r0
        for r0 in range(0, upto, block)
        if not all(int(q) in store.rows for q in perm[r0 : min(n, r0 + block)])
    ]
    chunks: list[list[int]] = []  # up to ``workers`` adjacent blocks, computed together
    for r0 in starts:
        if chunks and len(chunks[-1]) < workers and chunks[-1][-1] + block == r0:
            chunks[-1].append(r0)
        else:
            chunks.append([r0])
    if not starts:
        return
    todo = sum(min(n, r0 + block) - r0 for r0 in starts)
    with tqdm(total=todo, desc="rows to the store", unit="row", smoothing=0.1) as bar:
        for chunk in chunks:
            c0, c1 = chunk[0], min(n, chunk[-1] + block)
            arr = directed_costs(
                curves[c0:c1],
                curves,
                cfg,
                workers=workers,
                cache_dir=cache,
                block=block,
                desc=f"rows {c0}-{c1}",
            )
            rows = arr.min(axis=0)[:, inv]
            for r0 in chunk:
                r1 = min(n, r0 + block)
                part, queries = rows[r0 - c0 : r1 - c0], perm[r0:r1]
                nn = split_nn(part, queries, labels, splits)
                store.add(r0, r1, queries, nn, nearest_others(part, queries))
            bar.update(c1 - c0)
