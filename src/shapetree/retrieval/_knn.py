"""Exact k-nearest-neighbour search with a lower bound of the shape-tree cost.

:func:`knn` returns, for every query, exactly the ``k`` database shapes (and distances)
that the exhaustive :func:`shapetree.retrieval.search` returns, but skips most full
matchings: it first computes a cheap lower bound ``B[q, x] <= D[q, x]`` of every pair
(:mod:`shapetree.matching._bound`), then computes full costs best-first, in increasing
order of the bound, and stops for a query as soon as its next bound exceeds its ``k``-th
best full cost.

Exactness. The exhaustive ranking sorts ``D[q]`` stably (ties by index). Let ``τ`` be the
``k``-th smallest full cost computed so far for query ``q``. A database shape ``x`` whose
bound is ``B[q, x] > τ`` has ``D[q, x] >= B[q, x] > τ``: at least ``k`` computed shapes
rank before it whatever their indices, so it is not among the ``k`` nearest. Candidates are
taken in increasing bound order, so once the next bound exceeds ``τ`` every remaining one
does (``τ`` only decreases as costs are added). Shapes with a bound equal to ``τ`` are
computed (a tie may rank them first). The ``k`` nearest of the computed shapes, ranked by
``(distance, index)``, are then the exhaustive ``k`` nearest.

The full costs are computed by the same kernel calls as :func:`~shapetree.retrieval.
directed_costs` (:class:`~shapetree.matching._batch.ModelStack`, one row per model and
pass, the minimum over target phases and passes), so they are bitwise the numbers
``search`` ranks. The work runs in rounds: each round takes, for every unfinished query,
its next candidates whose bound is ``<= τ`` (``k`` in the first round, then by default
all of them), and computes them grouped by the shape that is prepared as the target (one
target preparation for all the queries that need it).

The height-function fusion (``height_weight = w > 0``, ``D = ψ^(1 - w) h^w``) is searched
the same way: ``h`` is computed exactly for every pair of a block (the engine's numbers,
:class:`~shapetree.matching._height.HeightRows`, in the engine's direction), and the bound
of ``D`` is ``B^(1 - w) h^w``, which is ``<= D`` because ``ψ^(1 - w)`` does not decrease
with ψ. Only the shape-tree matchings are skipped, so the fusion prunes as much as its ψ
bound allows while ``h`` costs what it costs in the full matrix.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from shapetree._errors import ShapeTreeError
from shapetree.matching import MatchConfig, prepare_target
from shapetree.matching._api import fuse_height, kernel_params, model_passes
from shapetree.matching._batch import ModelStack
from shapetree.matching._bound import BoundStack
from shapetree.matching._height import HeightParams, HeightRows
from shapetree.retrieval._engine import (
    _block_path,
    _cache_key,
    _check_scheduler,
    _prep_heights,
    _prep_models,
    _prep_targets,
    _resolve,
    _source,
    read_block,
    write_block,
)

__all__ = ["knn", "lower_bounds"]

#: The bound's kept levels when not given (``"auto"``), ``(keep_from, keep_top)``: under a
#: band the roots are dropped (the top levels hold most of the work; dropping two halves
#: the tightness, benchmarks/bench_knn.py); without a band every node costs the same and
#: the four top levels are kept.
AUTO_KEEP = {"band": (1, 0), "no band": (None, 4)}


def _keep(cfg: MatchConfig, keep_from: int | None | str, keep_top: int | str):
    """``(keep_from, keep_top)`` checked, ``"auto"`` resolved by :data:`AUTO_KEEP`."""
    auto = AUTO_KEEP["band" if cfg.band is not None else "no band"]
    kf = auto[0] if keep_from == "auto" else keep_from
    kt = auto[1] if keep_top == "auto" else keep_top
    if kf is not None:
        kf = _check_int("keep_from", kf, 0)
    return kf, _check_int("keep_top", kt, 0)


def _models(curves: list[np.ndarray], cfg: MatchConfig) -> list[list]:
    """Per curve its prepared models, one per pass (plain, mirrored)."""
    return [model_passes(a, cfg) for a in curves]


def _target(b: np.ndarray, cfg: MatchConfig):
    return prepare_target(b, closed=True, length_power=cfg.length_power, dtype=cfg.dtype)


def _check_sizes(models: list[list], targets: list[list[np.ndarray]]) -> int:
    sizes = {ms[0].points.shape[0] for ms in models}
    tsizes = {b.shape[0] for bs in targets for b in bs}
    if len(sizes) != 1 or len(tsizes) != 1:
        raise ShapeTreeError(
            "knn needs every curve resampled to one number of points (set n_points in the "
            "configuration)"
        )
    return next(iter(tsizes))


class _Direction:
    """One direction of matching: ``models[i]`` (rows) deformed onto ``targets[j]``."""

    def __init__(
        self,
        models: list[list],
        targets: list[list[np.ndarray]],
        cfg: MatchConfig,
        keep_from: int | None,
        keep_top: int,
    ) -> None:
        self.models, self.targets, self.cfg = models, targets, cfg
        self.m = _check_sizes(models, targets)
        self.params = kernel_params(cfg)
        self.n_pass = cfg.n_pass
        self.keep_from, self.keep_top = keep_from, keep_top
        self._bound_stacks: dict[tuple[int, ...], BoundStack] = {}
        self._lock = threading.Lock()

    def _flat(self, rows: Sequence[int]) -> list:
        # pass-major, as the engine stacks them: [plain rows..., mirrored rows...]
        return [self.models[i][p] for p in range(self.n_pass) for i in rows]

    def bound_stack(self, rows: Sequence[int]) -> BoundStack:
        """A new bound stack of the models ``rows`` (one per block of queries)."""
        return BoundStack(
            self._flat(rows),
            self.m,
            self.params,
            self.cfg.dtype,
            keep_from=self.keep_from,
            keep_top=self.keep_top,
        )

    def shared_stack(self, rows: Sequence[int]) -> BoundStack:
        """The bound stack of ``rows``, built once and shared by every block (the
        database's models when the database is deformed onto the queries)."""
        key = tuple(rows)
        with self._lock:
            stack = self._bound_stacks.get(key)
            if stack is None:
                stack = self._bound_stacks[key] = self.bound_stack(rows)
        return stack

    def bounds_for_target(self, j: int, rows: Sequence[int], stack: BoundStack) -> np.ndarray:
        """Lower bounds of ``cost(rows, j)`` (``stack``: the bound stack of ``rows``)."""
        best = np.full(len(rows), np.inf)
        for b in self.targets[j]:
            c = stack.bounds(_target(b, self.cfg)).reshape(self.n_pass, len(rows)).min(axis=0)
            np.minimum(best, c, out=best)
        return best

    def costs_for_target(self, j: int, rows: Sequence[int]) -> np.ndarray:
        """Full directed costs of ``rows`` onto target ``j`` (the engine's numbers)."""
        stack = ModelStack(self._flat(rows), self.m, self.params, self.cfg.dtype)
        out = np.full((self.n_pass, len(rows)), np.inf)
        for b in self.targets[j]:
            c = stack.costs(_target(b, self.cfg)).reshape(self.n_pass, len(rows))
            np.minimum(out, c, out=out)
        return out.min(axis=0)


def _run(jobs: list[Callable[[], Any]], workers: int) -> list[Any]:
    if workers <= 1 or len(jobs) <= 1:
        return [f() for f in jobs]
    with ThreadPoolExecutor(max_workers=workers) as ex:
        return list(ex.map(lambda f: f(), jobs))


def _chunks(items: Sequence[int], n: int) -> list[list[int]]:
    n = max(1, min(n, len(items)))
    return [list(items[i::n]) for i in range(n)]


def _each(items: Sequence[int], fn: Callable[[int], None], workers: int) -> None:
    """``fn(i)`` for every item, the items split into ``workers`` interleaved chunks that run
    side by side (``fn`` writes its own part of an output; the kernels release the GIL)."""

    def chunk(js: list[int]) -> Callable[[], None]:
        def run() -> None:
            for j in js:
                fn(j)

        return run

    _run([chunk(js) for js in _chunks(items, workers)], workers)


def _combine(fwd: np.ndarray | None, bwd: np.ndarray | None, sym: str) -> np.ndarray:
    if sym == "none":
        assert fwd is not None
        return fwd
    if sym == "reverse":
        assert bwd is not None
        return bwd
    assert fwd is not None and bwd is not None
    if sym == "min":
        return np.minimum(fwd, bwd)
    if sym == "mean":
        return 0.5 * (fwd + bwd)
    return np.maximum(fwd, bwd)


Curves = tuple[list[np.ndarray], list[list[np.ndarray]]]
#: Height descriptors (plain, mirrored) of the queries and of the database.
Heights = tuple[list, list]


def _prepared(
    queries: Sequence[ArrayLike], database: Sequence[ArrayLike], cfg: MatchConfig
) -> tuple[Curves | None, Curves | None, Heights | None]:
    """The sampled curves of each direction the configuration needs, ``(fwd, bwd,
    heights)``: ``fwd = (query models, database targets)`` unless ``symmetrize="reverse"``,
    ``bwd = (database models, query targets)`` unless ``symmetrize="none"``, ``heights =
    (query descriptors, database descriptors)`` when ``height_weight > 0``."""
    fwd = bwd = heights = None
    if cfg.symmetrize != "reverse":
        fwd = (_prep_models(queries, cfg, "query"), _prep_targets(database, cfg, "database curve"))
    if cfg.symmetrize != "none":
        bwd = (_prep_models(database, cfg, "database curve"), _prep_targets(queries, cfg, "query"))
    if cfg.height_weight > 0:
        hq = _prep_heights(queries, cfg, "query")
        hd = _prep_heights(database, cfg, "database curve")
        assert hq is not None and hd is not None
        heights = (hq, hd)
    return fwd, bwd, heights


def _pairs_key(
    fwd: Curves | None,
    bwd: Curves | None,
    cfg: MatchConfig,
    spec: str,
    heights: Heights | None = None,
) -> str:
    """Cache key: the engine's key of each direction's sampled curves, the height
    descriptors (with the fusion) and ``spec``."""
    import hashlib

    h = hashlib.sha256(spec.encode())
    for curves in (fwd, bwd):
        if curves is not None:
            h.update(_cache_key(curves[0], curves[1], cfg).encode())
    for group in heights or ():
        for plain, mirrored in group:
            h.update(np.ascontiguousarray(plain).tobytes())
            h.update(np.ascontiguousarray(mirrored).tobytes())
    return h.hexdigest()


class _Pairs:
    """Bounds and full costs of query x database pairs under one configuration.

    Built from the sampled curves of :func:`_prepared`; :meth:`bounds` and :meth:`costs`
    work on any subset of the queries (a block of rows), so blocks can run in threads,
    or as tasks on a Dask cluster (a ``_Pairs`` of the block's queries alone), and be
    cached apart.
    """

    def __init__(
        self,
        fwd: Curves | None,
        bwd: Curves | None,
        cfg: MatchConfig,
        keep_from: int | None,
        keep_top: int,
        heights: Heights | None = None,
    ) -> None:
        self.cfg = cfg
        self.sym = cfg.symmetrize
        self.w = cfg.height_weight
        self.heights = heights
        self._height_db: HeightRows | None = None
        self._lock = threading.Lock()
        self.fwd = self.bwd = None
        if fwd is not None:
            self.nq, self.nd = len(fwd[0]), len(fwd[1])
            self.fwd = _Direction(_models(fwd[0], cfg), fwd[1], cfg, keep_from, keep_top)
        if bwd is not None:
            self.nq, self.nd = len(bwd[1]), len(bwd[0])
            self.bwd = _Direction(_models(bwd[0], cfg), bwd[1], cfg, keep_from, keep_top)

    def bounds(self, rows: Sequence[int], workers: int = 1) -> np.ndarray:
        """``B[q, x] <= D[q, x]`` for the queries ``rows``, shape (len(rows), n_database)."""
        rows = list(rows)
        fwd = bwd = None
        if self.fwd is not None:
            fwd = np.empty((len(rows), self.nd))
            fstack = self.fwd.bound_stack(rows)

            def column(j: int) -> None:
                fwd[:, j] = self.fwd.bounds_for_target(j, rows, fstack)

            _each(range(self.nd), column, workers)
        if self.bwd is not None:
            bwd = np.empty((len(rows), self.nd))
            every = list(range(self.nd))
            bstack = self.bwd.shared_stack(every)

            def row(i: int) -> None:
                bwd[i] = self.bwd.bounds_for_target(rows[i], every, bstack)

            _each(range(len(rows)), row, workers)
        return np.maximum(_combine(fwd, bwd, self.sym), 0.0)

    def fused_bounds(
        self, rows: Sequence[int], h: np.ndarray | None, workers: int = 1
    ) -> np.ndarray:
        """:meth:`bounds`, fused with the exact ``h`` of :meth:`height_rows` when given."""
        b = self.bounds(rows, workers)
        return b if h is None else fuse_height(b, h, self.w)

    def height_rows(self, rows: Sequence[int], workers: int = 1) -> np.ndarray | None:
        """``h[q, x]`` for the queries ``rows`` (``None`` without the fusion), shape
        (len(rows), n_database): the engine's numbers, in its direction (the queries'
        descriptors stacked against each database outline; under ``symmetrize="reverse"``
        the database's against each query, as ``distance_matrix`` computes them)."""
        if self.heights is None:
            return None
        rows = list(rows)
        hq, hd = self.heights
        hp = HeightParams.of(self.cfg.height_points, self.cfg.height_complexity)
        out = np.empty((len(rows), self.nd))
        if self.sym != "reverse":
            stack = HeightRows([hq[r] for r in rows], hp)

            def column(j: int) -> None:
                out[:, j] = stack.against(hd[j])

            _each(range(self.nd), column, workers)
            return out
        with self._lock:
            if self._height_db is None:
                self._height_db = HeightRows(hd, hp)
            db = self._height_db

        def row(i: int) -> None:
            out[i] = db.against(hq[rows[i]])

        _each(range(len(rows)), row, workers)
        return out

    def costs(self, pairs: list[tuple[int, int]], workers: int = 1) -> np.ndarray:
        """Full distances of ``(q, x)`` pairs, equal to ``search``'s (``>= 0``)."""
        fwd = bwd = None
        if self.fwd is not None:
            fwd = self._direction_costs(self.fwd, [(x, q) for q, x in pairs], workers)
        if self.bwd is not None:
            bwd = self._direction_costs(self.bwd, [(q, x) for q, x in pairs], workers)
        return np.maximum(_combine(fwd, bwd, self.sym), 0.0)

    def _direction_costs(
        self, d: _Direction, by_target: list[tuple[int, int]], workers: int
    ) -> np.ndarray:
        # group the pairs by the curve that is the target (one preparation for its group)
        groups: dict[int, list[int]] = {}
        for i, (j, _row) in enumerate(by_target):
            groups.setdefault(j, []).append(i)
        out = np.empty(len(by_target))

        def target(j: int) -> None:
            idx = groups[j]
            out[idx] = d.costs_for_target(j, [by_target[i][1] for i in idx])

        _each(sorted(groups), target, workers)
        return out


def _check_int(name: str, v: Any, lo: int) -> int:
    if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < lo:
        raise ShapeTreeError(f"{name} must be an integer >= {lo}, got {v!r}")
    return int(v)


def lower_bounds(
    queries: Sequence[ArrayLike],
    database: Sequence[ArrayLike],
    config: MatchConfig | str | None = None,
    *,
    keep_from: int | None | str = "auto",
    keep_top: int | str = "auto",
    workers: int = 2,
    **options: Any,
) -> np.ndarray:
    """Lower bounds of the distances :func:`~shapetree.retrieval.distance_matrix` gives.

    Parameters
    ----------
    queries, database : sequence of array_like
        Closed curves (rows, columns).
    config : MatchConfig, str or None
        Needs ``n_points`` (one size for every curve); every ``symmetrize`` is supported.
        With ``height_weight = w > 0`` the bound is ``B_ψ^(1 - w) h^w`` with ``h`` exact.
    keep_from, keep_top : int, None or "auto"
        Nodes of the model's shape-tree of depth ``>= keep_from`` (``None``: none by this
        rule) or ``< keep_top`` are matched exactly, the others dropped
        (:mod:`shapetree.matching._bound`); ``"auto"``: :data:`AUTO_KEEP`.
    workers : int
    **options
        :class:`~shapetree.matching.MatchConfig` fields changed on top of ``config``.

    Returns
    -------
    ndarray, shape (len(queries), len(database))
        ``B[q, x] <= distance_matrix(queries, database, config)[q, x]``.
    """
    queries, database = _source(queries), _source(database)
    cfg = _resolve(config, options, queries, database)
    workers = _check_int("workers", workers, 1)
    if len(queries) == 0 or len(database) == 0:
        raise ShapeTreeError("lower_bounds needs at least one query and one database curve")
    fwd, bwd, heights = _prepared(queries, database, cfg)
    pairs = _Pairs(fwd, bwd, cfg, *_keep(cfg, keep_from, keep_top), heights)
    rows = range(len(queries))
    return pairs.fused_bounds(rows, pairs.height_rows(rows, workers), workers)


def _knn_rows(
    pairs: _Pairs, rows: list[int], k: int, step: int, workers: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, float]]:
    """The exact ``k`` nearest of the queries ``rows``: bounds, then best-first rounds of
    full matchings (module docstring). Returns indices, distances, the full matchings per
    query and the timings."""
    t0 = time.perf_counter()
    nq, nd = len(rows), pairs.nd
    h = pairs.height_rows(rows, workers)
    t_height = time.perf_counter() - t0
    bound = pairs.fused_bounds(rows, h, workers)
    t_bound = time.perf_counter() - t0 - t_height
    order = np.argsort(bound, axis=1, kind="stable")
    dist = np.full((nq, nd), np.inf)
    done = np.zeros((nq, nd), dtype=bool)
    ptr = np.zeros(nq, dtype=np.int64)
    count = np.zeros(nq, dtype=np.int64)
    open_q = np.ones(nq, dtype=bool)
    rounds = 0
    t_full = 0.0
    while True:
        todo: list[tuple[int, int]] = []
        for q in np.flatnonzero(open_q):
            # τ: the k-th smallest full cost computed so far (inf before k are known)
            tau = np.partition(dist[q], k - 1)[k - 1] if count[q] >= k else np.inf
            # k first; then (batch=None) every candidate whose bound is <= τ in one round:
            # two rounds in all, each target prepared at most twice; with a batch, at
            # least `batch` more and as many as the query has computed (doubling)
            take = k if rounds == 0 else max(step, int(count[q]))
            got = 0
            while ptr[q] < nd and got < take:
                x = int(order[q, ptr[q]])
                if bound[q, x] > tau:
                    break  # every later candidate has a bound >= this one: all pruned
                todo.append((int(q), x))
                ptr[q] += 1
                got += 1
            if got == 0:
                open_q[q] = False
        if not todo:
            break
        rounds += 1
        t1 = time.perf_counter()
        c = pairs.costs([(rows[q], x) for q, x in todo], workers)
        if h is not None:
            qs, xs = np.array(todo).T
            c = fuse_height(c, h[qs, xs], pairs.w)
        t_full += time.perf_counter() - t1
        for (q, x), v in zip(todo, c):
            dist[q, x] = v
            done[q, x] = True
            count[q] += 1
    idx = np.empty((nq, k), dtype=np.int64)
    out = np.empty((nq, k))
    cols = np.arange(nd)
    for q in range(nq):
        comp = cols[done[q]]
        # rank the computed shapes by (distance, index), as a stable argsort of D[q]
        rank = comp[np.lexsort((comp, dist[q, comp]))][:k]
        idx[q] = rank
        out[q] = dist[q, rank]
    timing = {
        "bound_seconds": t_bound,
        "height_seconds": t_height,
        "full_seconds": t_full,
        "rounds": rounds,
    }
    return idx, out, done.sum(axis=1), timing


def _block_result(
    pairs: _Pairs, rows: list[int], k: int, step: int, workers: int
) -> tuple[np.ndarray, dict[str, float]]:
    """The block array of the queries ``rows`` (distances, indices exact in float64,
    full matchings per query in ``[2, :, 0]``) and its timings."""
    bi, bd, bf, bt = _knn_rows(pairs, rows, k, step, workers)
    arr = np.zeros((3, len(rows), k))
    arr[0], arr[1], arr[2, :, 0] = bd, bi, bf
    return arr, bt


def knn_block(
    block: tuple[list | None, list | None, list | None],
    shared: tuple[list | None, list | None, list | None],
    cfg: MatchConfig,
    keep_from: int | None,
    keep_top: int,
    k: int,
    step: int,
) -> tuple[np.ndarray, dict[str, float]]:
    """One block of queries of :func:`knn`, from sampled curves alone (a Dask task).

    ``block = (query models, query targets, query height descriptors)`` of the block's
    queries and ``shared = (database targets, database models, database height
    descriptors)``, each ``None`` where the configuration does not need it
    (:func:`_prepared`). Returns what a thread computes for the same rows: the block array
    and its timings."""
    (qm, qt, qh), (dt, dm, dh) = block, shared
    fwd = (qm, dt) if qm is not None else None
    bwd = (dm, qt) if qt is not None else None
    heights = (qh, dh) if qh is not None else None
    pairs = _Pairs(fwd, bwd, cfg, keep_from, keep_top, heights)
    return _block_result(pairs, list(range(pairs.nq)), k, step, 1)


def knn(
    queries: Sequence[ArrayLike],
    database: Sequence[ArrayLike],
    config: MatchConfig | str | None = None,
    *,
    k: int = 10,
    workers: int = 2,
    progress: bool = False,
    stats: dict | None = None,
    keep_from: int | None | str = "auto",
    keep_top: int | str = "auto",
    batch: int | None = None,
    cache_dir: str | os.PathLike[str] | None = None,
    block: int | None = None,
    scheduler: Any = None,
    **options: Any,
) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` nearest database shapes of every query, exactly as exhaustive search.

    Parameters
    ----------
    queries : sequence of array_like, ShapeIndex or path-like
        Closed curves (arrays, OpenCV contours or shapely polygons), or a prepared
        database (:class:`~shapetree.retrieval.ShapeIndex` or its file name).
    database : sequence of array_like, ShapeIndex or path-like
        Closed curves, or a prepared database.
    config : MatchConfig, str or None
        Matcher configuration or preset name (default: the ``general`` preset, or the
        configuration of a ``ShapeIndex`` given); it needs ``n_points`` (every curve
        resampled to one size). Every ``symmetrize`` is supported (``"none"``: ``D[q, x]
        = ψ(q onto x)``; the others bound both directions), and so is the height-function
        fusion (``height_weight > 0``, e.g. the ``fused`` preset; module docstring).
    k : int
        Neighbours per query (at most the database size).
    workers : int
        Threads (the kernels release the GIL): blocks of queries run side by side; not
        used with ``scheduler``.
    progress : bool
        tqdm progress bar over the queries, with ETA.
    stats : dict, optional
        Filled with ``pairs``, ``full`` (full matchings computed), ``skipped`` (their
        complement, as a fraction), ``rounds`` (the most of any block), ``bound_seconds``,
        ``height_seconds`` (the exact height-function distances of the fusion, 0 without)
        and ``full_seconds`` (summed over blocks), ``seconds`` (wall), ``blocks``,
        ``blocks_cached`` and, per query, ``full_per_query``.
    keep_from, keep_top : int, None or "auto"
        Which levels of the shape-tree the bound matches exactly (:func:`lower_bounds`);
        ``"auto"``: under a band all but the roots, without one the four top levels
        (:data:`AUTO_KEEP`). They change the speed, never the result.
    batch : int, optional
        The first round computes each query's ``k`` candidates of smallest bound; by
        default the second computes every candidate whose bound is ``<= τ`` (two rounds,
        each database shape prepared as a target at most twice per block). With
        ``batch``, later rounds take at least ``batch`` and as many as the query has
        computed (closer to strict best-first order, more rounds).
    cache_dir : path-like, optional
        Folder for finished blocks of queries (checksummed, written atomically, in a
        sub-folder named by a SHA-256 of the code, the configuration, ``k`` and the
        sampled curves): a killed run resumes where it stopped.
    block : int, optional
        Queries per block (the unit of work, caching and resumption); default: the
        queries split into a multiple of ``workers`` blocks of equal size, at most 32 each
        (with ``scheduler``: at least eight blocks, at most 32 queries each).
    scheduler : None, str, distributed.Client or DaskScheduler
        ``None``: threads in this process. Otherwise each block of queries is one task on
        a ``dask.distributed`` cluster (a ``distributed.Client``, left open; a scheduler
        address ``"tcp://host:8786"``; ``"local:N"``, a local cluster of N processes
        started and closed for the call; or :func:`~shapetree.retrieval.open_scheduler`'s
        value), as for :func:`~shapetree.retrieval.distance_matrix`: the database's
        sampled curves are scattered once to every worker, this process writes the block
        cache, and the result is bitwise the threaded one.
    **options
        :class:`~shapetree.matching.MatchConfig` fields changed on top of ``config``.

    Returns
    -------
    indices : ndarray of int, shape (len(queries), k)
        Database indices, nearest first, ties by index: row ``q`` equals
        ``search(queries[q], database, config, k=k)[0]``.
    distances : ndarray, shape (len(queries), k)
        Their distances (``search``'s numbers, ``match(...).cost``).
    """
    t_start = time.perf_counter()
    queries, database = _source(queries), _source(database)
    cfg = _resolve(config, options, queries, database)
    workers = _check_int("workers", workers, 1)
    k = _check_int("k", k, 1)
    keep_from, keep_top = _keep(cfg, keep_from, keep_top)
    nq, nd = len(queries), len(database)
    if nq == 0 or nd == 0:
        raise ShapeTreeError(f"knn needs at least one query and one database curve, got {nq}, {nd}")
    k = min(k, nd)
    step = nd if batch is None else _check_int("batch", batch, 1)
    sched, owned = _check_scheduler(scheduler)
    if block is None and sched is not None:
        # at least eight blocks, at most 32 queries each, so that a few workers share
        # them evenly (the cluster's size is not known before it is reached)
        block = max(1, min(32, -(-nq // 8)))
    elif block is None:
        # a multiple of `workers` blocks of equal size, at most 32 queries each, so that
        # no thread is left alone with the last block
        n_blocks = workers * -(-nq // (workers * 32))
        block = -(-nq // n_blocks)
    else:
        block = _check_int("block", block, 1)
    ranges = [(r0, min(nq, r0 + block)) for r0 in range(0, nq, block)]
    idx = np.empty((nq, k), dtype=np.int64)
    dist = np.empty((nq, k))
    full = np.zeros(nq, dtype=np.int64)
    timing = {"bound_seconds": 0.0, "height_seconds": 0.0, "full_seconds": 0.0, "rounds": 0}
    fwd, bwd, heights = _prepared(queries, database, cfg)
    key = _pairs_key(fwd, bwd, cfg, f"shapetree-knn k={k}", heights)
    folder = None
    if cache_dir is not None:
        folder = Path(cache_dir) / f"knn-{key[:32]}"
        folder.mkdir(parents=True, exist_ok=True)

    def meta(r0: int, r1: int) -> dict:
        return {"key": key, "rows": [r0, r1], "shape": [3, r1 - r0, k]}

    def store(r0: int, r1: int, arr: np.ndarray) -> None:
        dist[r0:r1], idx[r0:r1], full[r0:r1] = arr[0], arr[1].astype(np.int64), arr[2, :, 0]

    todo = []
    for r0, r1 in ranges:
        arr = read_block(_block_path(folder, r0, r1), meta(r0, r1)) if folder else None
        if arr is None:
            todo.append((r0, r1))
        else:
            store(r0, r1, arr)
    bar = None
    if progress and todo:
        from tqdm.auto import tqdm

        done_rows = nq - sum(r1 - r0 for r0, r1 in todo)
        bar = tqdm(total=nq, initial=done_rows, desc="nearest neighbours", unit="query")
    lock = threading.Lock()

    def finish(r0: int, r1: int, arr: np.ndarray, bt: dict[str, float]) -> None:
        if folder is not None:
            write_block(_block_path(folder, r0, r1), arr, meta(r0, r1))
        with lock:
            store(r0, r1, arr)
            for name in ("bound_seconds", "height_seconds", "full_seconds"):
                timing[name] += bt[name]
            timing["rounds"] = max(timing["rounds"], bt["rounds"])

    try:
        if sched is not None and todo:
            from shapetree.retrieval._dask import _knn_task, run_tasks

            qm = fwd[0] if fwd is not None else None
            qt = bwd[1] if bwd is not None else None
            qh = heights[0] if heights is not None else None
            shared = (
                fwd[1] if fwd is not None else None,
                bwd[0] if bwd is not None else None,
                heights[1] if heights is not None else None,
            )
            search = (cfg, keep_from, keep_top, k, step)

            def task_args(r0: int, r1: int, sh: Any) -> tuple:
                qm_b = qm[r0:r1] if qm is not None else None
                qt_b = qt[r0:r1] if qt is not None else None
                qh_b = qh[r0:r1] if qh is not None else None
                return (qm_b, qt_b, qh_b), sh, search

            run_tasks(
                sched,
                _knn_task,
                shared,
                task_args,
                todo,
                name=f"shapetree-knn-{key[:24]}",
                on_result=lambda r0, r1, res: finish(r0, r1, *res),
                units=lambda r0, r1: r1 - r0,
                bar=bar,
            )
        elif todo:
            pairs = _Pairs(fwd, bwd, cfg, keep_from, keep_top, heights)
            inner = workers if len(todo) <= 1 else 1

            def job(r0: int, r1: int) -> None:
                arr, bt = _block_result(pairs, list(range(r0, r1)), k, step, inner)
                finish(r0, r1, arr, bt)
                if bar is not None:
                    with lock:
                        bar.update(r1 - r0)

            _run([lambda r=r: job(*r) for r in todo], 1 if inner > 1 else workers)
    finally:
        if bar is not None:
            bar.close()
        if owned and sched is not None:
            sched.close()
    if stats is not None:
        n_full = int(full.sum())
        stats.update(
            pairs=nq * nd,
            full=n_full,
            skipped=1.0 - n_full / (nq * nd),
            seconds=time.perf_counter() - t_start,
            full_per_query=full.tolist(),
            blocks=len(ranges),
            blocks_cached=len(ranges) - len(todo),
            engine="dask" if sched is not None else "threads",
            **timing,
        )
    return idx, dist
