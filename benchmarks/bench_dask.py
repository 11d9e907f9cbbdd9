"""Threaded engine against a Dask ``LocalCluster`` on the same work: the cluster's overhead.

Prints a table and writes ``benchmarks/results/bench_dask.json``. Measured in this one run,
on the same curves (seeded MPEG-7 shapes from ``$SHAPETREE_DATA``, or the demo shapes when
the set is not there) and the same configuration (the ``mpeg7`` preset by default):

* ``threads``: ``distance_matrix(curves, config, workers=N)`` (after a warm-up call, so no
  JIT compilation is timed);
* ``dask end to end``: ``distance_matrix(curves, config, scheduler="local:N")`` as a user
  calls it: starting the cluster, loading the kernels in each worker process, scattering
  the targets, the blocks, closing the cluster;
* ``dask warm``: the same blocks on an already started and warmed-up
  ``LocalCluster(n_workers=N, threads_per_worker=1)`` (what a long-lived cluster costs per
  call: scatter, task scheduling, results sent back), and the cluster start-up alone.

The three are interleaved ``--repeat`` times and the fastest of each is kept (the machine
may be shared).

Both block sizes are the engine's default for ``N`` workers (the same blocks), and the
matrices are checked bitwise equal. The overhead is reported as ratios to the threaded
time measured in the same run.

Run::

    python benchmarks/bench_dask.py                 # 100 MPEG-7 shapes, mpeg7 preset, N = 2
    python benchmarks/bench_dask.py --shapes 200 --workers 2 --preset general

``benchmarks/bench_scale.py`` calls :func:`measure` directly.
"""

from __future__ import annotations

import argparse
import sys
import time
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, machine, write_json  # noqa: E402

from shapetree.matching import MatchConfig  # noqa: E402
from shapetree.retrieval import distance_matrix  # noqa: E402


def shapes(n: int, seed: int = 0, dataset: str = "mpeg7") -> tuple[list[np.ndarray], str]:
    """``n`` seeded shapes of ``dataset`` (all of its classes mixed), or of the demo shapes
    (repeated, slightly jittered) when the data set is not available.

    Returns
    -------
    curves : list of ndarray, each shape (k, 2)
    source : str
        Where they came from.
    """
    from shapetree import DatasetError

    rng = np.random.default_rng(seed)
    try:
        from shapetree.datasets import load

        curves = load(dataset, n_points=None, progress=False).curves
        idx = np.sort(rng.choice(len(curves), min(n, len(curves)), replace=False))
        return [curves[i] for i in idx], f"{dataset} (seed {seed})"
    except DatasetError:
        from shapetree.demo import demo_shapes

        demo = list(demo_shapes().values())
        out = []
        for i in range(n):
            c = np.asarray(demo[i % len(demo)], dtype=float)
            out.append(c + rng.normal(0, 1e-3 * np.ptp(c), c.shape))
        return out, f"demo shapes, jittered (seed {seed}; {dataset} not found)"


def measure(
    curves: list[np.ndarray],
    config: MatchConfig | str = "mpeg7",
    workers: int = 2,
    repeat: int = 2,
) -> dict[str, Any]:
    """Time the threaded engine and a ``LocalCluster`` of ``workers`` processes on ``curves``.

    The ways are interleaved ``repeat`` times (threads, warm cluster, end to end) and the
    fastest time of each is kept, so a burst of load from other processes on the machine
    does not land on one way only.

    Parameters
    ----------
    curves : list of ndarray, each shape (k, 2)
        Closed curves; their all-pairs matrix is computed each way.
    config : MatchConfig or str
        Matcher configuration or preset name.
    workers : int
        Threads of the threaded run, worker processes (one thread each) of the cluster.
    repeat : int
        Rounds of the three ways.

    Returns
    -------
    dict
        Fastest seconds of each way (``threads_seconds``, ``dask_end_to_end_seconds``,
        ``dask_warm_seconds``; every round in ``rounds``), ``cluster_start_seconds``, the
        ratios to the threaded time (``end_to_end_over_threads``, ``warm_over_threads``),
        ``pairs``, ``pairs_per_second`` of each way and ``bitwise_equal`` (must be true).
    """
    import distributed

    from shapetree.retrieval._dask import local_cluster

    cfg = MatchConfig.preset(config) if isinstance(config, str) else config
    n = len(curves)
    kw: dict[str, Any] = dict(config=cfg, progress=False, workers=workers)
    distance_matrix(curves[:2], **kw)  # JIT warm-up of this process

    t0 = time.perf_counter()
    cluster = local_cluster(workers)
    client = distributed.Client(cluster, set_as_default=False)
    t_start = time.perf_counter() - t0
    rounds: dict[str, list[float]] = {"threads": [], "dask_warm": [], "dask_end_to_end": []}
    equal = True
    try:
        # load the kernels in every worker process (as the end-to-end run has to)
        client.run(partial(distance_matrix, curves[:2], config=cfg, progress=False, workers=1))
        for _ in range(max(1, int(repeat))):
            t0 = time.perf_counter()
            d_threads = distance_matrix(curves, **kw)
            rounds["threads"].append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            d_warm = distance_matrix(curves, scheduler=client, **kw)
            rounds["dask_warm"].append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            d_e2e = distance_matrix(curves, scheduler=f"local:{workers}", **kw)
            rounds["dask_end_to_end"].append(time.perf_counter() - t0)
            equal &= bool(np.array_equal(d_threads, d_warm) and np.array_equal(d_threads, d_e2e))
    finally:
        client.close()
        cluster.close()
    best = {k: min(v) for k, v in rounds.items()}
    pairs = n * n
    return dict(
        shapes=n,
        pairs=pairs,
        workers=workers,
        repeat=len(rounds["threads"]),
        config=cfg.as_dict(),
        threads_seconds=best["threads"],
        dask_end_to_end_seconds=best["dask_end_to_end"],
        dask_warm_seconds=best["dask_warm"],
        cluster_start_seconds=t_start,
        end_to_end_over_threads=best["dask_end_to_end"] / best["threads"],
        warm_over_threads=best["dask_warm"] / best["threads"],
        pairs_per_second={k: pairs / v for k, v in best.items()},
        rounds=rounds,
        bitwise_equal=equal,
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset", default="mpeg7")
    ap.add_argument("--preset", default="mpeg7")
    ap.add_argument("--shapes", type=int, default=100)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--repeat", type=int, default=2, help="interleaved rounds (fastest kept)")
    ap.add_argument("--json", type=Path, default=RESULTS / "bench_dask.json")
    args = ap.parse_args(argv)

    curves, source = shapes(args.shapes, args.seed, args.dataset)
    print(
        f"{len(curves)} shapes from {source} ({len(curves) ** 2} pairs), preset {args.preset}, "
        f"{args.workers} threads vs LocalCluster of {args.workers} processes",
        flush=True,
    )
    r = measure(curves, args.preset, args.workers, args.repeat)
    print()
    print(f"{'way':<38}{'seconds':>9}{'pairs/s':>10}{'/ threads':>11}")
    rows = [
        (f"threads (workers={args.workers})", r["threads_seconds"]),
        (f"dask local:{args.workers}, end to end", r["dask_end_to_end_seconds"]),
        ("dask, started and warm cluster", r["dask_warm_seconds"]),
    ]
    for name, sec in rows:
        print(f"{name:<38}{sec:>9.2f}{r['pairs'] / sec:>10.0f}{sec / r['threads_seconds']:>11.2f}")
    print(f"{'cluster start (alone)':<38}{r['cluster_start_seconds']:>9.2f}")
    print("every round:", {k: [round(x, 2) for x in v] for k, v in r["rounds"].items()})
    print(f"bitwise equal: {r['bitwise_equal']}")
    out = dict(
        command=" ".join(["python", "benchmarks/bench_dask.py", *(argv or sys.argv[1:])]),
        source=source,
        preset=args.preset,
        seed=args.seed,
        **r,
        machine=machine(),
    )
    write_json(args.json, out)
    print(f"wrote {args.json}")
    return 0 if r["bitwise_equal"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
