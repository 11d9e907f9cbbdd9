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
or another order is not read. Within a session, blocks the engine has already cached
under that key are read instead of recomputed.
"""

from __future__ import annotations

import json
import threading
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
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
        self._lock = threading.Lock()

    def add(self, r0: int, r1: int, queries: np.ndarray, nn: np.ndarray, top: np.ndarray) -> None:
        """Record block ``[r0, r1)`` (the run's order) and write the file atomically."""
        with self._lock:
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
    is the set in that order) that ``store`` lacks, block by block: read from the
    engine's cache under the whole problem's key when there, else computed (``workers``
    blocks at a time) and cached there too. Each finished block is written to the
    store's file at once."""
    from tqdm.auto import tqdm

    from shapetree.retrieval._engine import (
        _block_path,
        _compute_block,
        _prep_models,
        _prep_targets,
        read_block,
        write_block,
    )

    n = len(curves)
    ms = _prep_models(curves, cfg, "model curve")
    tv = _prep_targets(curves, cfg, "target curve")
    folder = Path(cache) / store.key[:32]
    folder.mkdir(parents=True, exist_ok=True)
    inv = np.argsort(perm)

    def meta(r0: int, r1: int) -> dict:
        return {"key": store.key, "rows": [r0, r1], "shape": [cfg.n_pass, r1 - r0, n]}

    def record(r0: int, r1: int, arr: np.ndarray) -> None:
        rows = arr.min(axis=0)[:, inv]
        queries = perm[r0:r1]
        store.add(
            r0, r1, queries, split_nn(rows, queries, labels, splits), nearest_others(rows, queries)
        )

    todo = []
    for r0 in range(0, upto, block):
        r1 = min(n, r0 + block)
        if all(int(q) in store.rows for q in perm[r0:r1]):
            continue
        arr = read_block(_block_path(folder, r0, r1), meta(r0, r1))
        if arr is None:
            todo.append((r0, r1))
        else:
            record(r0, r1, arr)
    if not todo:
        return
    total = sum(r1 - r0 for r0, r1 in todo) * n
    bar = tqdm(total=total, desc="matching (rows to the store)", unit="pair", smoothing=0.05)
    lock = threading.Lock()

    def tick(k: int) -> None:
        with lock:
            bar.update(k)

    def job(r0: int, r1: int) -> None:
        arr = _compute_block(ms[r0:r1], tv, cfg, tick)
        write_block(_block_path(folder, r0, r1), arr, meta(r0, r1))
        record(r0, r1, arr)

    try:
        with ThreadPoolExecutor(max_workers=workers) as ex:
            pending = {ex.submit(job, r0, r1) for r0, r1 in todo}
            try:
                while pending:
                    finished, pending = wait(pending, return_when=FIRST_COMPLETED)
                    for f in finished:
                        f.result()
            except BaseException:
                for f in pending:
                    f.cancel()
                raise
    finally:
        bar.close()
