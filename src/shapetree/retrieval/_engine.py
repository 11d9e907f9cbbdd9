"""All-pairs distance matrices: parallel, with a resumable on-disk block cache.

The directed cost ``C[i, j] = ψ(A_i, B_j)`` (curve ``i``'s shape-tree deformed onto curve
``j``) is computed in *row blocks* (a few models against every target). Each finished
block is written atomically (:func:`shapetree._atomic.atomic_write_bytes`) with a header that
carries the cache key, the block's rows and a SHA-256 of its payload, so a run that is
killed resumes where it stopped and a damaged block is detected and recomputed. The cache
key includes :func:`shapetree._cache.code_fingerprint` (package version and the source of
every module that changes a cost), so an upgrade never silently reuses stale distances.

The kernel of :mod:`shapetree.matching` releases the GIL, so the blocks run in threads; with
``scheduler=`` they run as tasks on a ``dask.distributed`` cluster instead
(:mod:`shapetree.retrieval._dask`, imported only then), bitwise the same, with the blocks
written to the same cache by this process as they arrive.
"""

from __future__ import annotations

import hashlib
import json
import os
import struct
import threading
import time
import warnings
from collections.abc import Sequence
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from shapetree._atomic import atomic_write_bytes
from shapetree._errors import ShapeTreeError
from shapetree.matching import MatchConfig, match_cost, prepare_target
from shapetree.matching._api import kernel_params, model_curve, model_passes, target_curves
from shapetree.matching._batch import ModelStack
from shapetree.matching._config import SYMMETRIZE, resolve_config
from shapetree.retrieval._index import ShapeIndex

__all__ = [
    "combine",
    "directed_costs",
    "distance_matrix",
    "search",
]

_MAGIC = b"SHAPETREE-DMBLOCK\n"
_HDR = struct.Struct("<Q")


def _prep_models(curves: Sequence[ArrayLike], config: MatchConfig, what: str) -> list[np.ndarray]:
    if isinstance(curves, ShapeIndex):
        curves.check_config(config)
        return curves.models
    return [model_curve(c, config, closed=True, name=f"{what} {i}") for i, c in enumerate(curves)]


def _prep_targets(
    curves: Sequence[ArrayLike], config: MatchConfig, what: str
) -> list[list[np.ndarray]]:
    if isinstance(curves, ShapeIndex):
        curves.check_config(config)
        return curves.targets
    return [target_curves(c, config, closed=True, name=f"{what} {i}") for i, c in enumerate(curves)]


def _prep_heights(curves: Any, config: MatchConfig, what: str) -> list | None:
    """The height descriptors (plain, mirrored) of every curve when ``height_weight > 0``
    (from a :class:`ShapeIndex`'s stored outlines), else ``None``."""
    if config.height_weight == 0:
        return None
    from shapetree.matching._api import height_outline
    from shapetree.matching._height import HeightParams, height_descriptors

    hp = HeightParams.of(config.height_points, config.height_complexity)
    outlines = curves.outlines if isinstance(curves, ShapeIndex) else curves
    return [
        height_descriptors(height_outline(c, config, name=f"{what} {i}"), hp)
        for i, c in enumerate(outlines)
    ]


def n_layers(config: MatchConfig) -> int:
    """Layers of a block of :func:`directed_costs`: one per pass (plain, mirrored), and a
    last one of height-function distances when ``height_weight > 0``."""
    return config.n_pass + (config.height_weight > 0)


def _source(curves: Any) -> Any:
    """A database file name (str or path-like) is read as a :class:`ShapeIndex`."""
    if isinstance(curves, str | os.PathLike):
        return ShapeIndex.load(curves)
    return curves


def _resolve(config: MatchConfig | str | None, options: dict, *sources: Any) -> MatchConfig:
    """The configuration of an engine call; with a :class:`ShapeIndex` among ``sources``,
    ``config=None`` means the index's own (``options`` change it), and any other is
    refused (:meth:`ShapeIndex.check_config`)."""
    index = next((s for s in sources if isinstance(s, ShapeIndex)), None)
    if index is None:
        return resolve_config(config, **options)
    cfg = resolve_config(index.config if config is None else config, **options)
    for s in sources:
        if isinstance(s, ShapeIndex):
            s.check_config(cfg)
    return cfg


def _cache_key(
    models: list[np.ndarray], targets: list[list[np.ndarray]], config: MatchConfig
) -> str:
    """SHA-256 of the code a cost depends on (package version and the ``"matching"`` scope
    of :func:`shapetree._cache.code_fingerprint`, so that an edit of the detection code
    does not invalidate a distance cache), every option that changes a directed cost, and
    the sampled curves."""
    from shapetree._cache import code_fingerprint

    h = hashlib.sha256()
    h.update(f"shapetree-dm {code_fingerprint('matching')}\n".encode())
    spec = config.as_dict()
    del spec["symmetrize"]  # blocks hold directed costs; symmetrizing happens afterwards
    h.update(json.dumps(spec, sort_keys=True).encode())
    for group in (models, [v for vs in targets for v in vs]):
        h.update(struct.pack("<Q", len(group)))
        for c in group:
            h.update(struct.pack("<QQ", *c.shape))
            h.update(c.tobytes())
    return h.hexdigest()


# ---------------------------------------------------------------- block files


def _block_path(folder: Path, r0: int, r1: int) -> Path:
    return folder / f"rows_{r0:06d}_{r1:06d}.blk"


def write_block(path: Path, arr: np.ndarray, meta: dict) -> None:
    """Atomically write one cost block with its self-checking header.

    Parameters
    ----------
    path : Path
    arr : ndarray, shape (n_pass, rows, cols)
    meta : dict
        Key, row range and shape, stored in the JSON header with the payload's SHA-256.
    """
    arr = np.ascontiguousarray(arr, dtype="<f8")
    payload = arr.tobytes()
    header = dict(meta, shape=list(arr.shape), sha256=hashlib.sha256(payload).hexdigest())
    hb = json.dumps(header, sort_keys=True).encode()
    atomic_write_bytes(path, _MAGIC + _HDR.pack(len(hb)) + hb + payload, fsync=True)


def read_block(path: Path, meta: dict) -> np.ndarray | None:
    """Read a cost block; ``None`` when missing, truncated, foreign or corrupted.

    Parameters
    ----------
    path : Path
    meta : dict
        Expected header entries (key, rows, shape); any difference rejects the block.

    Returns
    -------
    ndarray, shape (n_pass, rows, cols), or None
    """
    try:
        data = path.read_bytes()
    except OSError:
        return None
    try:
        if not data.startswith(_MAGIC):
            raise ValueError("bad magic")
        off = len(_MAGIC)
        (hl,) = _HDR.unpack_from(data, off)
        off += _HDR.size
        header = json.loads(data[off : off + hl].decode())
        payload = data[off + hl :]
        for k, v in meta.items():
            if header.get(k) != v:
                raise ValueError(f"header {k}={header.get(k)!r}, expected {v!r}")
        if hashlib.sha256(payload).hexdigest() != header["sha256"]:
            raise ValueError("checksum mismatch")
        shape = tuple(header["shape"])
        arr = np.frombuffer(payload, dtype="<f8")
        if arr.size != int(np.prod(shape)):
            raise ValueError("payload size")
        return arr.reshape(shape).astype(np.float64)
    except (ValueError, KeyError, struct.error, UnicodeDecodeError) as exc:
        warnings.warn(f"cache block {path} is damaged ({exc}); recomputing it", stacklevel=2)
        return None


# ---------------------------------------------------------------- computation


def _compute_block(
    models: list[np.ndarray],
    targets: list[list[np.ndarray]],
    config: MatchConfig,
    tick=None,
    heights: tuple[list, list] | None = None,
) -> np.ndarray:
    """Directed costs of ``models`` (rows) against every target (given at each of its
    phases, the cheapest phase kept): shape (n_pass, r, m); with ``heights`` (the rows'
    and the targets' height descriptors) a last layer of height-function distances,
    shape (n_pass + 1, r, m), computed target by target with the costs (so ``tick``
    counts a pair once both are done)."""
    mp = kernel_params(config)
    per_model = [model_passes(a, config) for a in models]
    passes = [[pm[p] for pm in per_model] for p in range(config.n_pass)]
    n_pass = len(passes)
    out = np.empty((n_pass + (heights is not None), len(models), len(targets)))
    flat = [mod for ms in passes for mod in ms]
    sizes = {a.shape[0] for a in models}
    tsizes = {b.shape[0] for bs in targets for b in bs}
    # equal sizes (the usual case, n_points set): one kernel call per target for the block
    batched = len(sizes) == len(tsizes) == 1
    stack = ModelStack(flat, next(iter(tsizes)), mp, config.dtype) if batched else None
    if heights is not None:
        from shapetree.matching._height import HeightParams, HeightRows

        hp = HeightParams.of(config.height_points, config.height_complexity)
        hrows = HeightRows(heights[0], hp)
    for j, versions in enumerate(targets):
        out[:n_pass, :, j] = np.inf
        for b in versions:
            t = prepare_target(b, closed=True, length_power=config.length_power, dtype=config.dtype)
            if stack is not None:
                c = stack.costs(t).reshape(n_pass, len(models))
            else:
                c = np.array([[match_cost(m, t, mp) for m in ms] for ms in passes])
            np.minimum(out[:n_pass, :, j], c, out=out[:n_pass, :, j])
        if heights is not None:
            out[n_pass, :, j] = hrows.against(heights[1][j])
        if tick is not None:
            tick(len(models))
    return out


def directed_costs(
    models: Sequence[ArrayLike],
    targets: Sequence[ArrayLike] | None = None,
    config: MatchConfig | str | None = None,
    *,
    workers: int = 2,
    cache_dir: str | os.PathLike[str] | None = None,
    block: int | None = None,
    progress: bool = True,
    desc: str = "matching",
    stats: dict | None = None,
    scheduler: Any = None,
    **options: Any,
) -> np.ndarray:
    """Directed costs ``ψ(model_i, target_j)``, one layer per pass (plain, mirrored).

    Parameters
    ----------
    models : sequence of array_like, each shape (n_i, 2), or ShapeIndex
        Closed curves whose shape-trees are deformed (rows), or a prepared database
        (:class:`shapetree.retrieval.ShapeIndex` or its file name: its stored samples
        are used).
    targets : sequence of array_like or ShapeIndex, optional
        Closed curves deformed onto (columns); default ``models``.
    config : MatchConfig, str or None
        Matcher configuration or preset name (default: the ``general`` preset, or the
        configuration of a ``ShapeIndex`` given; another one than the index's is refused);
        ``symmetrize`` is not used here (see :func:`combine`).
    workers : int
        Threads (the matching kernel releases the GIL); not used with ``scheduler``.
    cache_dir : path-like, optional
        Folder for finished row blocks; a sub-folder named by the cache key (a SHA-256 of
        the package version and kernel sources, the configuration and the sampled curves)
        is used, so a stale block can never be reused after an upgrade.
    block : int, optional
        Rows per block (the unit of work, of caching and of resumption); default
        ``ceil(n_models / (4 workers))``, at most 32, where ``workers`` is the cluster's
        worker threads with ``scheduler``. Each target is prepared once per block, so
        larger blocks spend less time on that. A cache is resumed block by block, so pass
        the same ``block`` (or the same worker count) to resume a run.
    progress : bool
        Show a tqdm progress bar with ETA.
    desc : str
        Progress-bar label.
    stats : dict, optional
        Filled with ``pairs``, ``pairs_computed``, ``blocks``, ``blocks_cached``,
        ``seconds``, ``key`` and ``engine`` (``"threads"`` or ``"dask"``).
    scheduler : None, str, distributed.Client or DaskScheduler
        Where the blocks run. ``None``: ``workers`` threads here. A
        ``distributed.Client`` (left open), a scheduler address (``"tcp://host:8786"``,
        connected to), or ``"local:N"`` (a ``LocalCluster`` of ``N`` one-thread worker
        processes, started for the call and closed after it): the blocks run as Dask
        tasks (``pip install "shapetree[dask]"``), the result bitwise the threaded one;
        this process writes each finished block to ``cache_dir`` as it arrives, so
        workers need no shared file system and an interrupted run resumes. The cluster is
        connected to (or started) only when a block has to be computed. See
        :mod:`shapetree.retrieval._dask`.
    **options
        :class:`shapetree.matching.MatchConfig` fields changed on top of ``config``.

    Returns
    -------
    ndarray, shape (layers, n_models, n_targets)
        ``[0]`` plain costs; ``[1]`` costs of the mirrored models (when ``mirror``); with
        ``height_weight > 0`` a last layer of height-function distances
        (:func:`n_layers`; :func:`combine` fuses them).
    """
    sched, owned = _check_scheduler(scheduler)
    try:
        return _directed_costs(
            models,
            targets,
            config,
            options,
            sched,
            workers=workers,
            cache_dir=cache_dir,
            block=block,
            progress=progress,
            desc=desc,
            stats=stats,
        )
    finally:
        if owned:
            sched.close()


def _check_scheduler(scheduler: Any) -> tuple[Any, bool]:
    """``(DaskScheduler or None, owned)``: the ``scheduler=`` value validated (the Dask
    module is imported only when one is given)."""
    if scheduler is None:
        return None, False
    from shapetree.retrieval._dask import check_scheduler

    return check_scheduler(scheduler)


def _directed_costs(
    models: Any,
    targets: Any,
    config: MatchConfig | str | None,
    options: dict,
    sched: Any,
    *,
    workers: int,
    cache_dir: str | os.PathLike[str] | None,
    block: int | None,
    progress: bool,
    desc: str,
    stats: dict | None,
) -> np.ndarray:
    """:func:`directed_costs` with ``scheduler`` already validated (``sched``: a
    :class:`~shapetree.retrieval._dask.DaskScheduler` or ``None`` for threads)."""
    models, targets = _source(models), _source(targets)
    cfg = _resolve(config, options, models, targets)
    if not isinstance(workers, int | np.integer) or isinstance(workers, bool) or workers < 1:
        raise ShapeTreeError(f"workers must be an integer >= 1, got {workers!r}")
    if block is not None and (
        isinstance(block, bool) or not isinstance(block, int | np.integer) or block < 1
    ):
        raise ShapeTreeError(f"block must be an integer >= 1 or None, got {block!r}")
    ms = _prep_models(models, cfg, "model curve")
    tv = _prep_targets(models if targets is None else targets, cfg, "target curve")
    hr = _prep_heights(models, cfg, "model curve")
    hc = hr if targets is None else _prep_heights(targets, cfg, "target curve")
    n, m = len(ms), len(tv)
    if n == 0 or m == 0:
        raise ShapeTreeError(f"need at least one model and one target, got {n} and {m}")
    if block is None:
        threads = int(workers) if sched is None else sched.n_threads()
        block = min(32, -(-n // (4 * threads)))
    block = int(block)
    layers = n_layers(cfg)
    out = np.empty((layers, n, m))
    ranges = [(r0, min(n, r0 + block)) for r0 in range(0, n, block)]
    folder = None
    key = _cache_key(ms, tv, cfg)
    if cache_dir is not None:
        folder = Path(cache_dir) / key[:32]
        folder.mkdir(parents=True, exist_ok=True)
        info = folder / "params.json"
        if not info.exists():
            spec = dict(cfg.as_dict(), key=key, n_models=n, n_targets=m)
            atomic_write_bytes(info, json.dumps(spec, indent=1).encode(), fsync=False)

    def meta(r0: int, r1: int) -> dict:
        return {"key": key, "rows": [r0, r1], "shape": [layers, r1 - r0, m]}

    todo = []
    for r0, r1 in ranges:
        arr = read_block(_block_path(folder, r0, r1), meta(r0, r1)) if folder else None
        if arr is None:
            todo.append((r0, r1))
        else:
            out[:, r0:r1] = arr
    done_pairs = (n - sum(r1 - r0 for r0, r1 in todo)) * m
    t_start = time.perf_counter()

    bar = None
    if progress and todo:
        from tqdm.auto import tqdm

        bar = tqdm(
            total=n * m, initial=done_pairs, desc=desc, unit="pair", smoothing=0.05, leave=True
        )
    lock = threading.Lock()

    def tick(k: int) -> None:
        if bar is not None:
            with lock:
                bar.update(k)

    def job(r0: int, r1: int) -> tuple[int, int, np.ndarray]:
        heights = None if hr is None else (hr[r0:r1], hc)
        arr = _compute_block(ms[r0:r1], tv, cfg, tick, heights)
        if folder is not None:
            write_block(_block_path(folder, r0, r1), arr, meta(r0, r1))
        return r0, r1, arr

    def store(r0: int, r1: int, arr: np.ndarray) -> None:
        if folder is not None:
            write_block(_block_path(folder, r0, r1), arr, meta(r0, r1))
        out[:, r0:r1] = arr

    try:
        if sched is not None and todo:
            from shapetree.retrieval._dask import run_blocks

            run_blocks(
                sched,
                ms,
                tv,
                cfg,
                todo,
                key=key,
                on_block=store,
                bar=bar,
                heights=None if hr is None else (hr, hc),
            )
        elif int(workers) <= 1 or len(todo) <= 1:
            for r0, r1 in todo:
                _, _, arr = job(r0, r1)
                out[:, r0:r1] = arr
        else:
            with ThreadPoolExecutor(max_workers=int(workers)) as ex:
                pending = {ex.submit(job, r0, r1) for r0, r1 in todo}
                try:
                    while pending:
                        finished, pending = wait(pending, return_when=FIRST_COMPLETED)
                        for f in finished:
                            r0, r1, arr = f.result()
                            out[:, r0:r1] = arr
                except BaseException:
                    for f in pending:
                        f.cancel()
                    raise
    finally:
        if bar is not None:
            bar.close()
    if stats is not None:
        stats.update(
            pairs=n * m,
            pairs_computed=n * m - done_pairs,
            blocks=len(ranges),
            blocks_cached=len(ranges) - len(todo),
            seconds=time.perf_counter() - t_start,
            key=key,
            engine="threads" if sched is None else "dask",
        )
    return out


def combine(
    costs: np.ndarray, symmetrize: str | None = "min", height_weight: float = 0.0
) -> np.ndarray:
    """Turn directed costs into a distance matrix.

    Parameters
    ----------
    costs : ndarray, shape (layers, n, n)
        From :func:`directed_costs` of a set against itself; passes are reduced by ``min``.
    symmetrize : {"none", "min", "mean", "max", "reverse"} or None
        ``D = min(C, C.T)`` / ``(C + C.T) / 2`` / ``max``; ``"none"`` keeps
        ``D[i, j] = ψ(i, j)`` (query ``i`` deformed onto ``j``); ``"reverse"`` uses
        ``D[i, j] = ψ(j, i)``.
    height_weight : float
        The configuration's ``height_weight``: when positive, the last layer of ``costs``
        holds the height-function distances ``h`` and ``D = ψ^(1 - w) h^w``.

    Returns
    -------
    ndarray, shape (n, n)
    """
    c = np.asarray(costs)
    if height_weight:
        if c.ndim != 3 or c.shape[0] < 2:
            raise ShapeTreeError(
                "height_weight > 0 needs the costs of directed_costs under that "
                f"configuration (passes, then a layer of height distances), got {c.shape}"
            )
        from shapetree.matching._api import fuse_height

        return fuse_height(combine(c[:-1], symmetrize), c[-1], height_weight)
    if c.ndim == 3:
        c = c.min(axis=0)
    s = "none" if symmetrize is None else str(symmetrize)
    if s == "none":
        return c.copy()
    if c.shape[0] != c.shape[1]:
        raise ShapeTreeError(f"symmetrize={s!r} needs a square matrix, got {c.shape}")
    if s == "min":
        return np.minimum(c, c.T)
    if s == "mean":
        return 0.5 * (c + c.T)
    if s == "max":
        return np.maximum(c, c.T)
    if s == "reverse":
        return c.T.copy()
    raise ShapeTreeError(f"symmetrize must be one of {SYMMETRIZE} or None, got {symmetrize!r}")


def distance_matrix(
    curves: Sequence[ArrayLike],
    targets: Sequence[ArrayLike] | None = None,
    config: MatchConfig | str | None = None,
    *,
    workers: int = 2,
    cache_dir: str | os.PathLike[str] | None = None,
    progress: bool = True,
    block: int | None = None,
    scheduler: Any = None,
    **options: Any,
) -> np.ndarray:
    """Shape-tree distances between closed curves (all pairs, or queries × database).

    Parameters
    ----------
    curves : sequence of array_like, each shape (n_i, 2)
        Closed curves (the queries; rows of the result): ``(x, y)`` arrays, OpenCV
        contours or shapely polygons.
    targets : sequence of array_like or ShapeIndex, optional
        A database (columns of the result); default ``curves`` (square matrix). Either
        argument may be a prepared database, :class:`shapetree.retrieval.ShapeIndex` (or
        the name of its file).
    config : MatchConfig, str or None
        Matcher configuration or preset name (default: the ``general`` preset, or the
        configuration of a ``ShapeIndex`` given, the only one accepted with it). Its
        ``symmetrize`` says how ψ(i, j) and ψ(j, i) are combined (see :func:`combine`).
    workers : int
        Threads (the kernel releases the GIL).
    cache_dir : path-like, optional
        Resumable cache of finished row blocks (see :func:`directed_costs`).
    progress : bool
        tqdm progress bar with ETA.
    block : int, optional
        Rows per cached block (see :func:`directed_costs`).
    scheduler : None, str, distributed.Client or DaskScheduler
        ``None`` (threads), a ``distributed.Client``, a scheduler address
        (``"tcp://host:8786"``) or ``"local:N"``: where the blocks run (see
        :func:`directed_costs`); the result is bitwise the threaded one. One connection
        (or local cluster) serves both directions of a query set.
    **options
        :class:`shapetree.matching.MatchConfig` fields changed on top of ``config``.

    Returns
    -------
    ndarray, shape (len(curves), len(targets))
        ``D[i, j]``: distance of database item ``j`` to query ``i`` (smaller is closer);
        ``D[i, j]`` equals ``shapetree.matching.match(curves[i], targets[j], config).cost``.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 2 * np.pi, 30, endpoint=False)
    >>> circle, ellipse = np.c_[np.cos(t), np.sin(t)], np.c_[2 * np.cos(t), np.sin(t)]
    >>> D = distance_matrix([circle, ellipse], n_points=20, symmetrize="min",
    ...                     progress=False, workers=1)
    >>> D.shape, bool(D[0, 0] < 1e-6), bool(np.allclose(D, D.T))
    ((2, 2), True, True)
    """
    sched, owned = _check_scheduler(scheduler)
    try:
        return _distance_matrix(
            curves,
            targets,
            config,
            options,
            sched,
            workers=workers,
            cache_dir=cache_dir,
            progress=progress,
            block=block,
        )
    finally:
        if owned:
            sched.close()


def _distance_matrix(
    curves: Any,
    targets: Any,
    config: MatchConfig | str | None,
    options: dict,
    sched: Any,
    **kw: Any,
) -> np.ndarray:
    """:func:`distance_matrix` with ``scheduler`` already validated (``sched``), shared by
    both directions."""
    curves, targets = _source(curves), _source(targets)
    cfg = _resolve(config, options, curves, targets)
    s = cfg.symmetrize
    kw["scheduler"] = sched
    w = cfg.height_weight
    if targets is None:
        return combine(directed_costs(curves, None, cfg, **kw), s, w)
    h = None
    if s != "reverse":
        fwd = directed_costs(curves, targets, cfg, desc="queries->database", **kw)
        fwd, h = (fwd[:-1], fwd[-1]) if w else (fwd, None)
        fwd = fwd.min(axis=0)
    if s != "none":
        # h is symmetric: with the forward run's layer in hand, the backward run needs none
        bcfg = cfg if h is None else cfg.replace(height_weight=0.0)
        bwd = directed_costs(targets, curves, bcfg, desc="database->queries", **kw)
        if h is None and w:
            bwd, h = bwd[:-1], bwd[-1].T
        bwd = bwd.min(axis=0).T
    if s == "none":
        d = fwd
    elif s == "reverse":
        d = bwd.copy()
    elif s == "min":
        d = np.minimum(fwd, bwd)
    elif s == "mean":
        d = 0.5 * (fwd + bwd)
    else:
        d = np.maximum(fwd, bwd)
    if not w:
        return d
    from shapetree.matching._api import fuse_height

    return fuse_height(d, h, w)


def search(
    query: ArrayLike,
    database: Sequence[ArrayLike],
    config: MatchConfig | str | None = None,
    *,
    k: int | None = None,
    workers: int = 2,
    progress: bool = False,
    **options: Any,
) -> tuple[np.ndarray, np.ndarray]:
    """The database shapes nearest to a query, nearest first.

    Parameters
    ----------
    query : array_like, shape (n, 2)
        A closed curve (array, OpenCV contour or shapely polygon).
    database : sequence of array_like, ShapeIndex, or path-like
        Closed curves, or a prepared database (a :class:`ShapeIndex` or the name of its
        file, read with :meth:`ShapeIndex.load`).
    config : MatchConfig, str or None
        Matcher configuration or preset name (default: the ``general`` preset; with a
        ``ShapeIndex``, its configuration, and any other is refused).
    k : int, optional
        Return only the ``k`` nearest (default: all, ranked).
    workers : int
        Threads.
    progress : bool
        tqdm progress bar.
    **options
        :class:`shapetree.matching.MatchConfig` fields changed on top of ``config``.

    Returns
    -------
    indices : ndarray of int, shape (k,)
        Database indices, nearest first (ties by index).
    distances : ndarray, shape (k,)
        ``match(query, database[i], config).cost`` for each returned ``i``.
    """
    database = _source(database)
    if len(database) == 0:
        raise ShapeTreeError("search needs a non-empty database")
    if k is not None and (isinstance(k, bool) or not isinstance(k, int | np.integer) or k < 1):
        raise ShapeTreeError(f"k must be an integer >= 1 or None, got {k!r}")
    cfg = _resolve(config, options, database)
    d = distance_matrix([query], database, cfg, workers=workers, progress=progress)
    d = np.maximum(d[0], 0.0)  # a rounding error below zero is a perfect match
    order = np.argsort(d, kind="stable")[: k or len(d)]
    return order, d[order]
