"""All-pairs distance matrices: parallel, with a resumable on-disk block cache.

The directed cost ``C[i, j] = ψ(A_i, B_j)`` (curve ``i``'s shape-tree deformed onto curve
``j``) is computed in *row blocks* (a few models against every target). Each finished
block is written atomically (temporary file, ``fsync``, ``os.replace``) with a header that
carries the cache key, the block's rows and a SHA-256 of its payload, so a run that is
killed resumes where it stopped and a damaged block is detected and recomputed.

The kernel of :mod:`shapetree.matching` releases the GIL, so the blocks run in threads.
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
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from shapetree._errors import ShapeTreeError
from shapetree.curves import as_curve, resample, smooth
from shapetree.matching import MatchParams, match_cost, prepare_model, prepare_target
from shapetree.matching._batch import ModelStack

__all__ = [
    "ENGINE_VERSION",
    "PRECISIONS",
    "SYMMETRIZE",
    "DistanceParams",
    "combine",
    "directed_costs",
    "distance_matrix",
    "mirror_curve",
]

#: Bump when the meaning of a cached block changes (kernel, cost definition, layout).
ENGINE_VERSION = 3
_MAGIC = b"SHAPETREE-DMBLOCK\n"
_HDR = struct.Struct("<Q")

#: Table precisions of the engine (``DistanceParams.precision``).
PRECISIONS = {"float32": np.float32, "float64": np.float64}

#: Accepted ``symmetrize`` values (``None`` is the same as ``"none"``).
SYMMETRIZE = ("min", "mean", "max", "none", "reverse")


def mirror_curve(points: ArrayLike) -> np.ndarray:
    """Mirror a closed curve left-right, keeping its orientation.

    Parameters
    ----------
    points : array_like, shape (n, 2)

    Returns
    -------
    ndarray, shape (n, 2)
        ``x`` negated and the point order reversed, so a counter-clockwise curve stays
        counter-clockwise (matching assumes both curves have the same orientation).
    """
    p = np.asarray(points, dtype=np.float64)
    return np.ascontiguousarray((p * np.array([-1.0, 1.0]))[::-1])


@dataclass(frozen=True)
class DistanceParams:
    """Every parameter that changes a directed cost (the cache key is made of these).

    Attributes
    ----------
    n_points : int or None
        Curves are resampled to this many points, evenly in arc length (``None``: as given).
    weight : float
        λ factor of the model's nodes (only matters relative to ``occlusion``).
    occlusion : float or None
        Replacement factor κ (:class:`shapetree.matching.MatchParams`).
    n_trees : int
        Shape-trees per model (rotated start points), best taken.
    split : str
        Midpoint rule of the shape-trees.
    mirror : bool
        Also deform the mirrored model and keep, per pair, the cheaper of the two.
    band : float or None
        Pruned matching (:class:`shapetree.matching.MatchParams`): a model subcurve may
        only stretch by at most this factor; ``None`` is exact matching.
    length_power : float
        λ grows as the relative subcurve length to this power
        (:func:`shapetree.matching.prepare_model`; the paper: 1).
    smooth : float or None
        Gaussian smoothing of each curve before resampling, as a fraction of its length
        (:func:`shapetree.curves.smooth`); ``None``: none.
    phases : int
        Target phases (not in the paper). With ``P > 1`` every target is also resampled
        starting ``p / P`` of a sample spacing further along (``p = 1 .. P - 1``) and the
        cheapest of the ``P`` matchings is kept: the model's points may then land between
        the target's first sampling, as on a ``P`` times finer target, but without the
        base-case cost that a finer target's extra points would carry. Needs
        ``n_points``.
    target_factor : int
        Targets are resampled to ``target_factor * n_points`` points (models keep
        ``n_points``); not in the paper, which samples both curves alike. Needs
        ``n_points``.
    segment_weight : float
        Factor on the base case "model segment vs a target subcurve"
        (:class:`shapetree.matching.MatchParams`; the paper: 1). With ``target_factor``
        2 and ``segment_weight`` 0 the model's points land anywhere along the target and
        only the model's own triangles are compared.
    precision : {"float32", "float64"}
        Precision of the dynamic-programming tables. ``float32`` (default) runs the kernel
        about twice as fast; costs then differ from float64 by about 1e-6 relative, far
        below the gaps that rank shapes.
    """

    n_points: int | None = 50
    weight: float = 1.0
    occlusion: float | None = None
    n_trees: int = 1
    split: str = "half"
    mirror: bool = False
    band: float | None = None
    length_power: float = 1.0
    smooth: float | None = None
    phases: int = 1
    target_factor: int = 1
    segment_weight: float = 1.0
    precision: str = "float32"

    def __post_init__(self) -> None:
        if self.n_points is not None and int(self.n_points) < 4:
            raise ShapeTreeError(f"n_points must be at least 4, got {self.n_points}")
        if int(self.n_trees) < 1:
            raise ShapeTreeError(f"n_trees must be at least 1, got {self.n_trees}")
        # validates κ, band and segment_weight
        MatchParams(occlusion=self.occlusion, band=self.band, segment_weight=self.segment_weight)
        if not (np.isfinite(self.weight) and self.weight > 0):
            raise ShapeTreeError(f"weight must be a positive number, got {self.weight}")
        if not (np.isfinite(self.length_power) and self.length_power >= 0):
            raise ShapeTreeError(f"length_power must be >= 0, got {self.length_power}")
        if self.smooth is not None and not (np.isfinite(self.smooth) and 0 <= self.smooth < 0.5):
            raise ShapeTreeError(f"smooth must be in [0, 0.5), got {self.smooth}")
        ph = self.phases
        if isinstance(ph, bool) or not isinstance(ph, int | np.integer) or ph < 1:
            raise ShapeTreeError(f"phases must be an integer >= 1, got {self.phases!r}")
        if self.phases > 1 and self.n_points is None:
            raise ShapeTreeError("phases > 1 resamples the targets: it needs n_points")
        tf = self.target_factor
        if isinstance(tf, bool) or not isinstance(tf, int | np.integer) or tf < 1:
            raise ShapeTreeError(f"target_factor must be an integer >= 1, got {tf!r}")
        if tf > 1 and self.n_points is None:
            raise ShapeTreeError("target_factor > 1 resamples the targets: it needs n_points")
        if self.precision not in PRECISIONS:
            raise ShapeTreeError(
                f"precision must be one of {tuple(PRECISIONS)}, got {self.precision!r}"
            )

    @property
    def dtype(self) -> np.dtype:
        """NumPy dtype of the kernel's tables."""
        return np.dtype(PRECISIONS[self.precision])

    @property
    def target_points(self) -> int | None:
        """Points per target curve (``n_points * target_factor``)."""
        return None if self.n_points is None else int(self.n_points) * int(self.target_factor)

    @property
    def n_pass(self) -> int:
        """1, or 2 with ``mirror`` (plain model, mirrored model)."""
        return 2 if self.mirror else 1


def _prep_curves(
    curves: Sequence[ArrayLike],
    n_points: int | None,
    what: str,
    sigma: float | None = None,
    phases: int = 1,
) -> list[list[np.ndarray]]:
    """Validated, smoothed and resampled curves: ``out[i][p]`` is curve ``i`` at phase
    ``p / phases`` (``out[i][0]`` starts at the curve's first point)."""
    out = []
    for i, c in enumerate(curves):
        a = as_curve(c, closed=True, name=f"{what} {i}")
        if sigma:
            n_keep = a.shape[0]
            a = smooth(a, float(sigma), closed=True)  # dense, evenly spaced
            if n_points is None:
                a = resample(a, n_keep, closed=True)
        versions = []
        for ph in range(phases):
            b = a
            if n_points is not None and (ph or sigma or a.shape[0] != n_points):
                b = resample(a, int(n_points), closed=True, phase=ph / phases)
            versions.append(np.ascontiguousarray(b, dtype=np.float64))
        out.append(versions)
    return out


def _cache_key(models: list[np.ndarray], targets: list[np.ndarray], p: DistanceParams) -> str:
    h = hashlib.sha256()
    h.update(f"shapetree-dm v{ENGINE_VERSION}\n".encode())
    spec = asdict(p)
    if spec["band"] is None:  # keys of exact runs predate the band option
        del spec["band"]
    if spec["length_power"] == 1.0:  # and keys of the paper's λ predate length_power
        del spec["length_power"]
    if not spec["smooth"]:  # and keys without smoothing predate it
        del spec["smooth"]
    for k, v in (("phases", 1), ("target_factor", 1), ("segment_weight", 1.0)):
        if spec[k] == v:  # keys of the paper's sampling and base case predate these
            del spec[k]
    h.update(json.dumps(spec, sort_keys=True).encode())
    for group in (models, targets):
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
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    with open(tmp, "wb") as f:
        f.write(_MAGIC + _HDR.pack(len(hb)) + hb + payload)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


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
    p: DistanceParams,
    tick=None,
) -> np.ndarray:
    """Directed costs of ``models`` (rows) against every target (given at each of its
    phases, the cheapest phase kept): shape (n_pass, r, m)."""
    mp = MatchParams(occlusion=p.occlusion, band=p.band, segment_weight=p.segment_weight)
    kw = dict(
        closed=True,
        n_trees=p.n_trees,
        split=p.split,
        weight=p.weight,
        length_power=p.length_power,
    )
    passes = [[prepare_model(a, **kw) for a in models]]
    if p.mirror:
        passes.append([prepare_model(mirror_curve(a), **kw) for a in models])
    out = np.empty((len(passes), len(models), len(targets)))
    flat = [mod for ms in passes for mod in ms]
    sizes = {a.shape[0] for a in models}
    tsizes = {b.shape[0] for bs in targets for b in bs}
    # equal sizes (the usual case, n_points set): one kernel call per target for the block
    batched = len(sizes) == len(tsizes) == 1
    stack = ModelStack(flat, next(iter(tsizes)), mp, p.dtype) if batched else None
    for j, versions in enumerate(targets):
        out[:, :, j] = np.inf
        for b in versions:
            t = prepare_target(b, closed=True, length_power=p.length_power, dtype=p.dtype)
            if stack is not None:
                c = stack.costs(t).reshape(len(passes), len(models))
            else:
                c = np.array([[match_cost(m, t, mp) for m in ms] for ms in passes])
            np.minimum(out[:, :, j], c, out=out[:, :, j])
        if tick is not None:
            tick(len(models))
    return out


def directed_costs(
    models: Sequence[ArrayLike],
    targets: Sequence[ArrayLike] | None = None,
    *,
    n_points: int | None = 50,
    weight: float = 1.0,
    occlusion: float | None = None,
    n_trees: int = 1,
    split: str = "half",
    mirror: bool = False,
    band: float | None = None,
    length_power: float = 1.0,
    smooth: float | None = None,
    phases: int = 1,
    target_factor: int = 1,
    segment_weight: float = 1.0,
    precision: str = "float32",
    workers: int = 2,
    cache_dir: str | os.PathLike[str] | None = None,
    block: int | None = None,
    progress: bool = True,
    desc: str = "matching",
    stats: dict | None = None,
) -> np.ndarray:
    """Directed costs ``ψ(model_i, target_j)``, one layer per pass (plain, mirrored).

    Parameters
    ----------
    models : sequence of array_like, each shape (n_i, 2)
        Closed curves whose shape-trees are deformed (rows).
    targets : sequence of array_like, optional
        Closed curves deformed onto (columns); default ``models``.
    n_points, weight, occlusion, n_trees, split, mirror, band, length_power, smooth, phases,
    target_factor, segment_weight, precision
        See :class:`DistanceParams`.
    workers : int
        Threads (the matching kernel releases the GIL).
    cache_dir : path-like, optional
        Folder for finished row blocks; a sub-folder named by the cache key (a SHA-256 of
        the resampled curves and every parameter above) is used.
    block : int, optional
        Rows per block (the unit of work, of caching and of resumption); default
        ``ceil(n_models / (4 workers))``, at most 32. Each target is prepared once per
        block, so larger blocks spend less time on that.
    progress : bool
        Show a tqdm progress bar with ETA.
    desc : str
        Progress-bar label.
    stats : dict, optional
        Filled with ``pairs``, ``pairs_computed``, ``blocks``, ``blocks_cached``,
        ``seconds`` and ``key``.

    Returns
    -------
    ndarray, shape (n_pass, n_models, n_targets)
        ``[0]`` plain costs; ``[1]`` costs of the mirrored models (when ``mirror``).
    """
    p = DistanceParams(
        n_points,
        weight,
        occlusion,
        int(n_trees),
        split,
        bool(mirror),
        band,
        float(length_power),
        None if not smooth else float(smooth),
        phases,
        target_factor,
        float(segment_weight),
        precision,
    )
    ph, tp = int(p.phases), p.target_points
    if targets is None and ph == 1 and tp == p.n_points:
        tv = _prep_curves(models, p.n_points, "curve", p.smooth)
        ms = [v[0] for v in tv]
    else:
        ms = [v[0] for v in _prep_curves(models, p.n_points, "model curve", p.smooth)]
        tv = _prep_curves(models if targets is None else targets, tp, "target curve", p.smooth, ph)
    ts = [v[0] for v in tv]
    n, m = len(ms), len(ts)
    if block is None:
        block = min(32, -(-n // (4 * max(1, int(workers)))))
    block = max(1, int(block))
    out = np.empty((p.n_pass, n, m))
    ranges = [(r0, min(n, r0 + block)) for r0 in range(0, n, block)]
    folder = None
    key = _cache_key(ms, ts, p)
    if cache_dir is not None:
        folder = Path(cache_dir) / key[:32]
        folder.mkdir(parents=True, exist_ok=True)
        info = folder / "params.json"
        if not info.exists():
            spec = dict(asdict(p), key=key, n_models=n, n_targets=m, version=ENGINE_VERSION)
            tmp = info.with_name(f".params.{os.getpid()}.tmp")
            tmp.write_text(json.dumps(spec, indent=1))
            os.replace(tmp, info)

    def meta(r0: int, r1: int) -> dict:
        return {"key": key, "rows": [r0, r1], "shape": [p.n_pass, r1 - r0, m]}

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
        arr = _compute_block(ms[r0:r1], tv, p, tick)
        if folder is not None:
            write_block(_block_path(folder, r0, r1), arr, meta(r0, r1))
        return r0, r1, arr

    try:
        if int(workers) <= 1 or len(todo) <= 1:
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
        )
    return out


def combine(costs: np.ndarray, symmetrize: str | None = "min") -> np.ndarray:
    """Turn directed costs into a distance matrix.

    Parameters
    ----------
    costs : ndarray, shape (n_pass, n, n)
        From :func:`directed_costs` of a set against itself; passes are reduced by ``min``.
    symmetrize : {"min", "mean", "max", "none", "reverse"} or None
        ``D = min(C, C.T)`` / ``(C + C.T) / 2`` / ``max``; ``"none"`` keeps
        ``D[i, j] = ψ(i, j)`` (query ``i`` deformed onto ``j``); ``"reverse"`` uses
        ``D[i, j] = ψ(j, i)``.

    Returns
    -------
    ndarray, shape (n, n)
    """
    c = np.asarray(costs)
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
    *,
    n_points: int | None = 50,
    weight: float = 1.0,
    occlusion: float | None = None,
    n_trees: int = 1,
    split: str = "half",
    mirror: bool = False,
    band: float | None = None,
    length_power: float = 1.0,
    smooth: float | None = None,
    phases: int = 1,
    target_factor: int = 1,
    segment_weight: float = 1.0,
    precision: str = "float32",
    symmetrize: str | None = "min",
    workers: int = 2,
    cache_dir: str | os.PathLike[str] | None = None,
    progress: bool = True,
    block: int | None = None,
) -> np.ndarray:
    """Shape-tree distances between closed curves (all pairs, or queries × database).

    Parameters
    ----------
    curves : sequence of array_like, each shape (n_i, 2)
        Closed, counter-clockwise curves (the queries; rows of the result).
    targets : sequence of array_like, optional
        A database (columns of the result); default ``curves`` (square matrix).
    n_points : int or None
        Resample every curve to this many points first (``None``: as given).
    weight : float
        λ factor; only changes rankings relative to ``occlusion``.
    occlusion : float or None
        Replacement factor κ (bounds each subtree's cost by ``κ λ (|A'| + |B'|)``).
    n_trees : int
        Shape-trees per model (rotated start points), best taken.
    split : {"half", "best"}
        Midpoint rule of the shape-trees.
    mirror : bool
        Mirror invariance: also deform the mirrored curve, keep the cheaper cost.
    band : float or None
        Pruned (banded) matching: maximum stretch factor of a subcurve; ``None``: exact.
    length_power : float
        λ grows as the relative subcurve length to this power (the paper: 1).
    smooth : float or None
        Gaussian smoothing of every curve before resampling, as a fraction of its length
        (:func:`shapetree.curves.smooth`); e.g. 0.005 removes pixel staircases.
    phases : int
        Also match each target resampled at ``phases - 1`` offsets of a fraction of a
        sample spacing, keeping the cheapest (see :class:`DistanceParams`; not in the
        paper; needs ``n_points``).
    target_factor : int
        Targets are resampled to ``target_factor * n_points`` points (not in the paper).
    segment_weight : float
        Factor on the base case "model segment vs target subcurve" (paper: 1).
    precision : {"float32", "float64"}
        Precision of the kernel's tables (see :class:`DistanceParams`).
    symmetrize : {"min", "mean", "max", "none", "reverse"} or None
        How the two directions ψ(i, j) and ψ(j, i) are combined (see :func:`combine`);
        ``"none"`` uses ψ(query, database) only (for a rectangular matrix that halves the
        work; a square one needs every ordered pair anyway).
    workers : int
        Threads (the kernel releases the GIL).
    cache_dir : path-like, optional
        Resumable cache of finished row blocks (see :func:`directed_costs`).
    progress : bool
        tqdm progress bar with ETA.
    block : int, optional
        Rows per cached block (see :func:`directed_costs`).

    Returns
    -------
    ndarray, shape (len(curves), len(targets))
        ``D[i, j]``: distance of database item ``j`` to query ``i`` (smaller is closer).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 2 * np.pi, 30, endpoint=False)
    >>> circle, ellipse = np.c_[np.cos(t), np.sin(t)], np.c_[2 * np.cos(t), np.sin(t)]
    >>> D = distance_matrix([circle, ellipse], n_points=20, progress=False, workers=1)
    >>> D.shape, bool(D[0, 0] < 1e-12), bool(np.allclose(D, D.T))
    ((2, 2), True, True)
    """
    s = "none" if symmetrize is None else str(symmetrize)
    if s not in SYMMETRIZE:
        raise ShapeTreeError(f"symmetrize must be one of {SYMMETRIZE} or None, got {symmetrize!r}")
    kw = dict(
        n_points=n_points,
        weight=weight,
        occlusion=occlusion,
        n_trees=n_trees,
        split=split,
        mirror=mirror,
        band=band,
        length_power=length_power,
        smooth=smooth,
        phases=phases,
        target_factor=target_factor,
        segment_weight=segment_weight,
        precision=precision,
        workers=workers,
        cache_dir=cache_dir,
        progress=progress,
        block=block,
    )
    if targets is None:
        return combine(directed_costs(curves, None, **kw), s)
    fwd = directed_costs(curves, targets, desc="queries->database", **kw).min(axis=0)
    if s == "none":
        return fwd
    bwd = directed_costs(targets, curves, desc="database->queries", **kw).min(axis=0).T
    if s == "reverse":
        return bwd.copy()
    if s == "min":
        return np.minimum(fwd, bwd)
    if s == "mean":
        return 0.5 * (fwd + bwd)
    return np.maximum(fwd, bwd)
