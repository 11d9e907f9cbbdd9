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
or another order is not read as it is. It may be *adopted* (:func:`adopt`) when the current
code, recomputing a spread sample of its rows, gives every one of them identically (a
change that leaves the costs alone, such as input validation or a faster curve check,
changes the fingerprint but not a row); the file then records the check.
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
        #: The file's content when it was made under another key (see :func:`adopt`).
        self.foreign: dict[str, Any] | None = None
        if self.path.exists():
            data = json.loads(self.path.read_text())
            if data.get("key") == key:
                self.rows, self.blocks = _rows(data), _blocks(data)
                if "adopted" in data:  # kept when the file is written again
                    self.meta = dict(self.meta, adopted=data["adopted"])
            else:
                self.foreign = data
                print(
                    f"{self.path.name}: made by other code, options or order "
                    f"(key {str(data.get('key'))[:12]}, now {key[:12]})",
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

    def adopt_foreign(self, check: dict[str, Any]) -> None:
        """Take the foreign file's rows as this key's, recording ``check`` (what was
        recomputed and found identical) after the file's earlier adoptions."""
        assert self.foreign is not None
        self.rows, self.blocks = _rows(self.foreign), _blocks(self.foreign)
        earlier = list(self.foreign.get("adopted", []))
        self.meta = dict(self.meta, adopted=[*earlier, check])
        self.foreign = None
        self.save()

    def nn(self, queries: np.ndarray) -> np.ndarray:
        return np.array([self.rows[int(q)]["nn"] for q in queries], dtype=np.int64)

    def top(self, queries: np.ndarray) -> np.ndarray:
        return np.array([self.rows[int(q)]["top"] for q in queries], dtype=np.int64)


def _rows(data: dict[str, Any]) -> dict[int, dict[str, list[int]]]:
    return {int(q): v for q, v in data["rows"].items()}


def _blocks(data: dict[str, Any]) -> set[tuple[int, int]]:
    return {(int(a), int(b)) for a, b in data["blocks"]}


def _summaries(
    curves: list[np.ndarray],
    cfg: MatchConfig,
    positions: np.ndarray,
    perm: np.ndarray,
    labels: np.ndarray,
    splits: list[np.ndarray],
    **engine: Any,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The queries ``perm[positions]`` and their ``nn`` and ``top`` summaries, computed by
    :func:`shapetree.retrieval.directed_costs` (``curves``: the set in the order ``perm``)."""
    from shapetree.retrieval import directed_costs

    arr = directed_costs([curves[p] for p in positions.tolist()], curves, cfg, **engine)
    rows = arr.min(axis=0)[:, np.argsort(perm)]
    queries = perm[positions]
    return queries, split_nn(rows, queries, labels, splits), nearest_others(rows, queries)


def adopt(
    store: RowStore,
    curves: list[np.ndarray],
    cfg: MatchConfig,
    perm: np.ndarray,
    labels: np.ndarray,
    splits: list[np.ndarray],
    *,
    check: int,
    workers: int = 2,
) -> bool:
    """Adopt the rows of a file made under another key if the current code reproduces them.

    ``check`` recorded queries, spread evenly over the run's recorded prefix (its first and
    last row included), are recomputed with the current code and options; if every one's
    ``nn`` (each split's nearest training leaf) and ``top`` (its 9 nearest leaves, in order)
    equal the file's, the file's rows become the store's, under the current key, and the
    file records the check (``adopted``: the old key, the queries checked, the date).
    Otherwise nothing is adopted and the run starts afresh (the file is overwritten by
    the first new block). Returns whether the rows were adopted; ``False`` at once when
    the file was made under the current key or does not exist.

    A sample cannot prove that no other row changed; it is meant for changes that leave
    every cost alone by design (validation, speed), where one changed cost would show in
    most rows' nearest leaves.
    """
    import datetime

    if store.foreign is None:
        return False
    old = _rows(store.foreign)
    done = 0
    for q in perm.tolist():
        if q not in old:
            break
        done += 1
    if done == 0:
        return False
    positions = np.unique(np.linspace(0, done - 1, min(check, done)).round().astype(np.int64))
    print(f"recomputing {positions.size} of the file's {done} rows to compare", flush=True)
    queries, nn, top = _summaries(
        curves, cfg, positions, perm, labels, splits, workers=workers, desc="rows to compare"
    )
    differ = [
        int(q)
        for q, a, b in zip(queries.tolist(), nn.tolist(), top.tolist(), strict=True)
        if old[int(q)] != {"nn": a, "top": b}
    ]
    if differ:
        print(
            f"{len(differ)} of {queries.size} recomputed rows differ (queries {differ[:10]}): "
            "not adopted, starting afresh",
            flush=True,
        )
        return False
    store.adopt_foreign(
        {
            "from_key": store.foreign.get("key"),
            "checked_queries": queries.tolist(),
            "identical": int(queries.size),
            "date": datetime.date.today().isoformat(),
        }
    )
    print(f"all {queries.size} recomputed rows identical: the file's {done} rows adopted")
    return True


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

    n = len(curves)
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
            queries, nn, top = _summaries(
                curves,
                cfg,
                np.arange(c0, c1),
                perm,
                labels,
                splits,
                workers=workers,
                cache_dir=cache,
                block=block,
                desc=f"rows {c0}-{c1}",
            )
            for r0 in chunk:
                r1 = min(n, r0 + block)
                part = slice(r0 - c0, r1 - c0)
                store.add(r0, r1, queries[part], nn[part], top[part])
            bar.update(c1 - c0)
