"""The engine's row blocks, and the pruned search's blocks of queries, as tasks on a
``dask.distributed`` cluster.

:func:`shapetree.retrieval.directed_costs`, :func:`~shapetree.retrieval.distance_matrix`
and :func:`~shapetree.retrieval.knn` take ``scheduler=``:

* ``None``: threads in this process (the default, unchanged);
* a :class:`distributed.Client` (used as it is, never closed here) or a
  ``distributed`` cluster object (a client is opened on it for the call);
* an address string, ``"tcp://host:8786"`` (or any ``scheme://...`` that ``distributed``
  speaks, or ``"host:port"``), connected to within :data:`CONNECT_TIMEOUT` seconds;
* ``"local:N"``: a ``distributed.LocalCluster`` of ``N`` worker processes with one thread
  each, on 127.0.0.1 without dashboard, started for the call and closed after it;
* a :class:`DaskScheduler` (what :func:`open_scheduler` yields): one connection or local
  cluster shared by several calls (``distance_matrix`` with a query set uses one for both
  directions).

Design (why it is exact, and safe to kill):

* Each row block is one task running the same :func:`shapetree.retrieval._engine._compute_block`
  on the same rows as the threaded engine, so the matrix is *bitwise* the threaded one.
  Likewise each block of queries of :func:`~shapetree.retrieval.knn` is one task running
  :func:`shapetree.retrieval._knn.knn_block` on the block's sampled curves, the same
  bounds and full matchings as a thread computes for those rows (:func:`run_tasks` is
  the one submission loop of both).
* The prepared targets are scattered once to every worker (``broadcast=True``), not sent
  with each task; each task carries only its own rows' model curves.
* Tasks are pure functions of their arguments, with a deterministic key derived from the
  cache key; a worker that dies mid-task has its task rescheduled by the scheduler (up to
  its ``allowed-failures``), and a task that raises is retried :data:`TASK_RETRIES` times.
  Should every copy of the scattered targets be lost with their workers, the remaining
  blocks are resubmitted with a fresh scatter (at most :data:`TASK_RETRIES` times).
* This (client) process writes each finished block into the checksummed block cache as it
  arrives (:func:`shapetree.retrieval._engine.write_block`), so workers need no shared
  file system, a killed client resumes from its cache, and cached blocks are never
  submitted.
* Every task checks that its worker runs the client's code
  (:func:`shapetree._cache.code_fingerprint`): a worker with another shapetree version is
  refused rather than mixed in.
* Progress: workers report finished pairs of a running block (at most every
  :data:`PROGRESS_INTERVAL` seconds, as ``distributed`` events) and the client's tqdm bar
  counts them, with the number of workers shown beside it.

This module imports ``distributed`` only when a scheduler is used, so ``import shapetree``
never imports dask.
"""

from __future__ import annotations

import re
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from shapetree._errors import ShapeTreeError

__all__ = [
    "CONNECT_TIMEOUT",
    "CONNECT_TRIES",
    "DaskScheduler",
    "PROGRESS_INTERVAL",
    "TASK_RETRIES",
    "check_scheduler",
    "local_cluster",
    "open_scheduler",
    "run_blocks",
    "run_tasks",
]

#: Seconds allowed to reach a scheduler given by address (and to start a local cluster).
CONNECT_TIMEOUT: float = 20.0
#: Retries of a task that raised (worker deaths are counted by the scheduler's own
#: ``distributed.scheduler.allowed-failures``); also the number of resubmissions after the
#: scattered targets were lost.
TASK_RETRIES: int = 3
#: Seconds between two progress reports of a running block.
PROGRESS_INTERVAL: float = 0.5

_INSTALL = (
    'scheduler= needs dask.distributed, which is not installed: pip install "shapetree[dask]"'
)
_LOCAL = re.compile(r"local:(.*)", re.IGNORECASE | re.DOTALL)
_URL = re.compile(r"[a-z][a-z0-9+.-]*://\S+", re.IGNORECASE)
_HOSTPORT = re.compile(r"[A-Za-z0-9_.-]+:\d{1,5}")
SCHEDULER_FORMS = (
    "None (threads), a distributed.Client, a scheduler address such as "
    "'tcp://host:8786', or 'local:N' (a local cluster of N worker processes)"
)


def _distributed() -> Any:
    """The ``distributed`` module, or a :class:`ShapeTreeError` saying how to install it."""
    try:
        import distributed
    except ImportError as exc:
        raise ShapeTreeError(_INSTALL) from exc
    return distributed


#: Tries of a client's handshake (see :func:`_connect`).
CONNECT_TRIES: int = 3


def _connect(d: Any, target: Any, timeout: str) -> Any:
    """``distributed.Client(target)``, tried again when the handshake meets a broadcast.

    The scheduler sends a new client ``stream-start`` in a batch that lasts 2 ms; a message to
    all clients sent in that window (another client's ``cancel`` of keys the scheduler has
    already forgotten, for one) joins the batch, and ``Client._ensure_connected`` fails on its
    ``assert len(msg) == 1``. That is distributed's race, not a broken scheduler, so the
    connection is made again, at most :data:`CONNECT_TRIES` times in all.
    """
    for _ in range(CONNECT_TRIES):
        try:
            return d.Client(target, timeout=timeout, set_as_default=False)
        except AssertionError as exc:
            last = exc
    raise ShapeTreeError(
        f"the Dask handshake with {target!r} failed {CONNECT_TRIES} times (a message to all "
        f"clients arrived with it each time): {last!r}"
    ) from last


class DaskScheduler:
    """A Dask client for the engine, opened on first use and closed by :meth:`close`.

    Built by :func:`check_scheduler` from a ``scheduler=`` value (validated there); pass
    it as ``scheduler=`` to several engine calls to share one cluster between them.

    Parameters
    ----------
    address : str, optional
        Scheduler address to connect to.
    n_local : int, optional
        Worker processes of a ``LocalCluster`` to start.
    client : distributed.Client, optional
        An existing client, used and left open.
    cluster : distributed cluster, optional
        An existing cluster, on which a client is opened (and closed by :meth:`close`).
    """

    def __init__(
        self,
        *,
        address: str | None = None,
        n_local: int | None = None,
        client: Any = None,
        cluster: Any = None,
    ) -> None:
        self.address, self.n_local = address, n_local
        self._client, self._cluster = client, cluster
        self._owns_client = client is None
        self._owns_cluster = False
        self._lock = threading.Lock()

    def __repr__(self) -> str:
        return f"DaskScheduler({self.describe()})"

    def describe(self) -> str:
        """Where the blocks run: ``"local:N"``, the address, or the client's scheduler."""
        if self.n_local is not None:
            return f"local:{self.n_local}"
        if self.address is not None:
            return self.address
        c = self._client if self._client is not None else self._cluster
        return str(getattr(c, "scheduler_address", None) or type(c).__name__)

    def client(self) -> Any:
        """The ``distributed.Client``, connecting (or starting the local cluster) on the
        first call.

        Returns
        -------
        distributed.Client

        Raises
        ------
        ShapeTreeError
            The address cannot be reached (or the local cluster not started) within
            :data:`CONNECT_TIMEOUT` seconds.
        """
        with self._lock:
            if self._client is not None:
                return self._client
            d = _distributed()
            timeout = f"{float(CONNECT_TIMEOUT)}s"
            try:
                if self.n_local is not None:
                    self._cluster = local_cluster(self.n_local)
                    self._owns_cluster = True
                target = self._cluster if self._cluster is not None else self.address
                self._client = _connect(d, target, timeout)
            except (OSError, TimeoutError) as exc:
                self._close_cluster()
                what = (
                    f"cannot start a local Dask cluster of {self.n_local} workers"
                    if self.n_local is not None
                    else f"cannot reach the Dask scheduler at {self.describe()!r}"
                )
                raise ShapeTreeError(
                    f"{what} within {float(CONNECT_TIMEOUT):g} s ({type(exc).__name__}: {exc})"
                ) from exc
            return self._client

    def n_threads(self) -> int:
        """Worker threads of the cluster now (at least 1); connects if needed."""
        info = self.client().scheduler_info()
        return max(1, sum(int(w.get("nthreads", 1)) for w in info.get("workers", {}).values()))

    def n_workers(self) -> int:
        """Workers of the cluster now (as the client last heard)."""
        if self._client is None:
            return 0
        return len(self._client.scheduler_info().get("workers", {}))

    def _close_cluster(self) -> None:
        if self._owns_cluster and self._cluster is not None:
            self._cluster.close()
            self._cluster, self._owns_cluster = None, False

    def close(self) -> None:
        """Close what this object opened (a client given by the caller stays open)."""
        with self._lock:
            if self._owns_client and self._client is not None:
                self._client.close()
                self._client = None
            self._close_cluster()

    def __enter__(self) -> DaskScheduler:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def local_cluster(n_workers: int) -> Any:
    """The cluster of ``scheduler="local:N"``: ``N`` worker processes of one thread each.

    Parameters
    ----------
    n_workers : int
        Worker processes (each restarted by its nanny if it dies).

    Returns
    -------
    distributed.LocalCluster
        On 127.0.0.1, without dashboard (the scheduler's plain HTTP endpoints on a free
        port, not 8787), silent below warnings; close it with ``.close()``.
    """
    d = _distributed()
    return d.LocalCluster(
        n_workers=int(n_workers),
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
        scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
    )


def check_scheduler(scheduler: Any) -> tuple[DaskScheduler | None, bool]:
    """Validate a ``scheduler=`` value (without connecting yet).

    Parameters
    ----------
    scheduler : None, str, distributed.Client, distributed cluster or DaskScheduler
        See the module docstring.

    Returns
    -------
    scheduler : DaskScheduler or None
        ``None`` for threads.
    owned : bool
        Whether the caller must :meth:`~DaskScheduler.close` it (it was made here).

    Raises
    ------
    ShapeTreeError
        A malformed string, a value of another type, or ``distributed`` not installed.
    """
    if scheduler is None:
        return None, False
    if isinstance(scheduler, DaskScheduler):
        return scheduler, False
    if isinstance(scheduler, str):
        s = scheduler.strip()
        local = _LOCAL.fullmatch(s)
        if local is not None:
            n = local.group(1).strip()
            if not n.isdigit() or int(n) < 1:
                raise ShapeTreeError(
                    f"scheduler {scheduler!r}: 'local:N' needs a whole number of worker "
                    f"processes N >= 1, e.g. 'local:2'"
                )
            _distributed()
            return DaskScheduler(n_local=int(n)), True
        if _URL.fullmatch(s) or _HOSTPORT.fullmatch(s):
            _distributed()
            return DaskScheduler(address=s), True
        raise ShapeTreeError(
            f"scheduler {scheduler!r} is not a Dask scheduler address ('tcp://host:8786' or "
            f"'host:8786') nor 'local:N'; scheduler must be {SCHEDULER_FORMS}"
        )
    if type(scheduler).__module__.split(".")[0] == "distributed":
        d = _distributed()
        if isinstance(scheduler, d.Client):
            if scheduler.asynchronous:
                raise ShapeTreeError(
                    "scheduler: an asynchronous distributed.Client is not supported"
                )
            if scheduler.status not in ("running", "connecting", "newly-created"):
                raise ShapeTreeError(f"scheduler: the distributed.Client is {scheduler.status}")
            return DaskScheduler(client=scheduler), False
        if hasattr(scheduler, "scheduler_address"):
            return DaskScheduler(cluster=scheduler), True
    raise ShapeTreeError(f"scheduler must be {SCHEDULER_FORMS}; got {scheduler!r}")


@contextmanager
def open_scheduler(scheduler: Any) -> Iterator[DaskScheduler | None]:
    """Validate ``scheduler`` once and share it between several engine calls.

    Parameters
    ----------
    scheduler : None, str, distributed.Client, distributed cluster or DaskScheduler
        As the engine's ``scheduler=`` (see the module docstring).

    Yields
    ------
    DaskScheduler or None
        Pass it as ``scheduler=``; a local cluster started for it (or a client opened for
        it) is closed when the ``with`` block ends.

    Examples
    --------
    >>> with open_scheduler(None) as sched:
    ...     print(sched)
    None
    """
    sched, owned = check_scheduler(scheduler)
    try:
        yield sched
    finally:
        if owned and sched is not None:
            sched.close()


# ---------------------------------------------------------------- worker side


def _progress_tick(topic: str | None, rows: tuple[int, int]) -> Callable[[int], None] | None:
    """A throttled reporter of a running block's finished pairs, as a ``distributed``
    event of ``topic`` (``None`` outside a worker or without a topic)."""
    if topic is None:
        return None
    try:
        from distributed import get_worker

        worker = get_worker()
    except (ImportError, ValueError):
        return None
    state = {"pairs": 0, "last": time.monotonic()}

    def tick(k: int) -> None:
        state["pairs"] += int(k)
        now = time.monotonic()
        if now - state["last"] >= PROGRESS_INTERVAL:
            state["last"] = now
            worker.log_event(topic, {"rows": list(rows), "pairs": state["pairs"]})

    return tick


def _check_code(fingerprint: str) -> None:
    """Refuse to run on a worker whose shapetree code is not the client's (the
    ``"matching"`` scope of the code fingerprint: the code that decides a distance block
    or a neighbour list, what the client caches under that fingerprint)."""
    import shapetree
    from shapetree._cache import code_fingerprint

    mine = code_fingerprint("matching")
    if mine != fingerprint:
        raise ShapeTreeError(
            f"Dask worker runs other shapetree code (version {shapetree.__version__}, code "
            f"fingerprint {mine[:12]}) than the client (fingerprint {fingerprint[:12]}): "
            f"install the same shapetree on every worker"
        )


def _block_task(
    models: list[np.ndarray],
    shared: tuple[list[list[np.ndarray]], list | None],
    config: Any,
    row_heights: list | None,
    fingerprint: str,
    rows: tuple[int, int],
    topic: str | None,
) -> np.ndarray:
    """One row block on a worker: ``_compute_block(models, targets, config, heights)``,
    after checking that the worker runs the client's code. ``shared``: the targets and
    their height descriptors (scattered once); ``row_heights``: the block's models'.
    Pure (same arguments, same array)."""
    from shapetree.retrieval._engine import _compute_block

    _check_code(fingerprint)
    targets, col_heights = shared
    heights = None if row_heights is None else (row_heights, col_heights)
    return _compute_block(models, targets, config, _progress_tick(topic, rows), heights)


def _knn_task(
    block: tuple[Any, Any],
    shared: tuple[Any, Any],
    search: tuple[Any, ...],
    fingerprint: str,
    rows: tuple[int, int],
    topic: str | None,
) -> tuple[np.ndarray, dict[str, float]]:
    """One block of queries of the pruned search on a worker
    (:func:`shapetree.retrieval._knn.knn_block`), after the same code check. ``block``:
    the block's prepared query curves (as models, as targets); ``shared``: the database's
    (scattered once); ``search``: ``(config, keep_from, keep_top, k, step)``."""
    from shapetree.retrieval._knn import knn_block

    _check_code(fingerprint)
    return knn_block(block, shared, *search)


# ---------------------------------------------------------------- client side


def run_blocks(
    scheduler: DaskScheduler,
    models: list[np.ndarray],
    targets: list[list[np.ndarray]],
    config: Any,
    todo: list[tuple[int, int]],
    *,
    key: str,
    on_block: Callable[[int, int, np.ndarray], None],
    bar: Any = None,
    heights: tuple[list, list] | None = None,
) -> None:
    """Compute row blocks on the cluster, handing each to ``on_block`` as it finishes.

    Parameters
    ----------
    scheduler : DaskScheduler
    models : list of ndarray, each shape (n, 2)
        Every model curve (rows); a task gets ``models[r0:r1]``.
    targets : list of list of ndarray
        Every target, at each of its phases (scattered once to every worker).
    config : MatchConfig
    todo : list of (int, int)
        Row ranges ``[r0, r1)`` to compute.
    key : str
        The engine's cache key (names the tasks, so equal work has equal keys).
    on_block : callable
        ``on_block(r0, r1, arr)`` with ``arr`` of shape (layers, r1 - r0, len(targets))
        (:func:`shapetree.retrieval._engine.n_layers`),
        called in this thread in order of completion.
    bar : tqdm, optional
        Progress bar counting pairs; running blocks' reports and finished blocks move it.
    heights : (list, list), optional
        The height descriptors of the models and the targets (``height_weight > 0``);
        the targets' are scattered with the targets.

    Raises
    ------
    ShapeTreeError
        A task failed (its error, a worker mismatch, or workers killed by it too often).
    """
    m = len(targets)
    rows_h, cols_h = heights if heights is not None else (None, None)
    run_tasks(
        scheduler,
        _block_task,
        (targets, cols_h),
        lambda r0, r1, shared: (
            models[r0:r1],
            shared,
            config,
            None if rows_h is None else rows_h[r0:r1],
        ),
        todo,
        name=f"shapetree-block-{key[:24]}",
        on_result=on_block,
        units=lambda r0, r1: (r1 - r0) * m,
        bar=bar,
        reports=True,
    )


def run_tasks(
    scheduler: DaskScheduler,
    task: Callable[..., Any],
    shared: Any,
    task_args: Callable[[int, int, Any], tuple],
    todo: list[tuple[int, int]],
    *,
    name: str,
    on_result: Callable[[int, int, Any], None],
    units: Callable[[int, int], int],
    bar: Any = None,
    reports: bool = False,
) -> None:
    """Run one task per block of rows on the cluster, handing each result to
    ``on_result`` as it finishes (the engine's blocks and the pruned search's alike).

    Parameters
    ----------
    scheduler : DaskScheduler
    task : callable
        Runs on a worker as ``task(*task_args(r0, r1, shared), fingerprint, (r0, r1),
        topic)``; it checks the fingerprint (:func:`_check_code`) and is pure.
    shared : object
        Scattered once to every worker (``broadcast=True``); ``task_args`` receives its
        future.
    task_args : callable
        ``(r0, r1, shared) -> tuple``: the block's own arguments.
    todo : list of (int, int)
        Row ranges ``[r0, r1)``.
    name : str
        Prefix of the task keys (derived from a cache key, so equal work has equal keys).
    on_result : callable
        ``on_result(r0, r1, result)``, called in this thread in order of completion.
    units : callable
        ``(r0, r1) -> int``: what a finished block adds to ``bar``.
    bar : tqdm, optional
    reports : bool
        Whether running tasks report progress (``topic`` events of ``units``).

    Raises
    ------
    ShapeTreeError
        A task failed (its error, a worker mismatch, or workers killed by it too often).
    """
    d = _distributed()
    from shapetree._cache import code_fingerprint

    client = scheduler.client()
    fingerprint = code_fingerprint("matching")
    lock = threading.Lock()
    reported: dict[tuple[int, int], int] = {}
    finished: set[tuple[int, int]] = set()
    topic = f"shapetree-progress-{uuid.uuid4().hex}" if bar is not None and reports else None

    def on_event(event: Any) -> None:
        _, msg = event
        rows = tuple(msg["rows"])
        with lock:
            if rows in finished:
                return
            new = int(msg["pairs"]) - reported.get(rows, 0)
            if new > 0:  # a restarted task reports from 0 again: never counted twice
                reported[rows] = int(msg["pairs"])
                bar.update(new)

    def postfix() -> None:
        if bar is not None:
            bar.set_postfix_str(f"dask {scheduler.n_workers()} workers", refresh=False)

    if topic is not None:
        client.subscribe_topic(topic, on_event)
    remaining = list(todo)
    try:
        for attempt in range(TASK_RETRIES + 1):
            again = f"-again{attempt}" if attempt else ""  # never reuse a cancelled key
            [scattered] = client.scatter([shared], broadcast=True, hash=False)
            futures = {
                client.submit(
                    task,
                    *task_args(r0, r1, scattered),
                    fingerprint,
                    (r0, r1),
                    topic,
                    key=f"{name}-{r0:06d}-{r1:06d}{again}",
                    retries=TASK_RETRIES,
                ): (r0, r1)
                for r0, r1 in remaining
            }
            postfix()
            lost = False
            try:
                for fut in d.as_completed(list(futures), loop=client.loop):
                    r0, r1 = futures[fut]
                    try:
                        result = fut.result()
                    except d.client.FutureCancelledError:
                        lost = True  # its data went with the workers: resubmitted below
                        continue
                    except d.KilledWorker as exc:
                        raise ShapeTreeError(
                            f"the Dask task of rows {r0}:{r1} was running on workers that died "
                            f"too often ({exc}); see the workers' logs"
                        ) from exc
                    except ShapeTreeError:
                        raise
                    except Exception as exc:  # e.g. shapetree missing on a remote worker
                        raise ShapeTreeError(
                            f"the Dask task of rows {r0}:{r1} failed on a worker after "
                            f"{TASK_RETRIES} retries: {type(exc).__name__}: {exc}"
                        ) from exc
                    fut.release()
                    on_result(r0, r1, result)
                    remaining.remove((r0, r1))
                    with lock:
                        finished.add((r0, r1))
                        done = reported.pop((r0, r1), 0)
                        if bar is not None:
                            bar.update(units(r0, r1) - done)
                    postfix()
            finally:
                # Cancel only what is still pending and release the rest (an erred key kept
                # would answer the next submit of the same key): a cancel of released keys
                # makes the scheduler broadcast an empty "cancelled-keys" to every client,
                # and one that lands in a connecting client's first batch fails its
                # handshake (see _connect).
                pending = []
                for f in futures:
                    if f.done():
                        f.release()
                    else:
                        pending.append(f)
                if pending:
                    client.cancel(pending)
                scattered.release()
            if not lost or not remaining:
                break
        if remaining:
            raise ShapeTreeError(
                f"{len(remaining)} blocks could not be computed on the Dask cluster: their "
                f"inputs were lost with the workers {TASK_RETRIES + 1} times"
            )
    finally:
        if topic is not None:
            client.unsubscribe_topic(topic)
