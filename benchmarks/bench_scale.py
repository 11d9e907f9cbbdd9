"""Scaling, measured: matching rates per core, the lower bound's cost and pruning, threads
against a Dask ``LocalCluster``; and the projection to 10,000 and 100,000 shapes.

Prints tables and writes ``benchmarks/results/bench_scale.json`` (``docs/SCALING.md`` turns
it into costs). Everything is measured in this one run, on seeded MPEG-7 shapes
(``$SHAPETREE_DATA``):

* ``rates``: for each preset, the all-pairs matrix of ``--rate-shapes`` shapes on one
  thread, as CPU seconds per ordered pair (``time.process_time``, so a busy shared machine
  does not inflate it) and pairs per CPU-second; ``kernel runs`` is the number of
  dynamic programmes per pair (shape-trees x mirror passes x target phases).
* ``bound``: ``--queries`` queries against the whole set under ``--preset`` (default
  ``mpeg7``): the lower bound of every pair (``retrieval.lower_bounds``) and the full cost
  (``distance_matrix``), both on one thread in CPU seconds, their ratio, and the bound's
  tightness (bound / cost).
* ``pruning``: from those two matrices, what ``retrieval.knn`` computes in full for a
  database of ``N`` shapes and ``k`` neighbours, by replaying its two rounds exactly (the
  ``k`` smallest bounds, then every candidate whose bound is <= the k-th full cost found);
  for ``N`` below the set size, nested random subsets (averaged over ``--subsets``
  draws); for ``N`` above it (10,000 and 100,000), a *projection* that assumes a larger
  collection has the same distribution of distances as MPEG-7: the query's ``k``-th
  distance is read as the ``k / N`` quantile of its distances to the set (interpolated),
  and the computed fraction is the share of its bounds at or below it.
  ``--check-knn`` runs ``knn`` itself at ``N`` = the set size and checks that its count of
  full matchings equals the replay's.
* ``dask``: ``benchmarks/bench_dask.py``'s ``measure`` on ``--dask-shapes`` shapes: the
  threaded engine against ``local:2`` (end to end and on a warm cluster), interleaved,
  fastest of each, bitwise equal.
* ``projection``: CPU-hours and wall hours on ``W`` workers of the exhaustive matrix and of
  the pruned ``k``-NN graph for 10,000 and 100,000 shapes, from the rates above.

Run::

    python benchmarks/bench_scale.py                       # about 15 min on 2 busy cores
    python benchmarks/bench_scale.py --queries 8 --no-dask # quicker
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, machine, write_json  # noqa: E402

from shapetree.datasets import load  # noqa: E402
from shapetree.matching import PRESETS, MatchConfig  # noqa: E402
from shapetree.retrieval import distance_matrix  # noqa: E402
from shapetree.retrieval._knn import knn, lower_bounds  # noqa: E402

RATE_PRESETS = ("general", "paper", "kimia99", "mpeg7", "swedish_leaf")
SIZES = (175, 350, 700)  # and the whole database
PROJECT = (10_000, 100_000)
KS = (1, 10, 40)
#: The bound's ``keep_from`` values measured (1: the knn default; 2, 3: cheaper, looser).
KEEP_FROM = (1, 2, 3)
WORKERS = (1, 16, 64, 256)


def _cpu(fn) -> tuple[Any, float, float]:
    t0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.process_time() - c0, time.perf_counter() - t0


def kernel_runs(cfg: MatchConfig) -> int:
    """Dynamic programmes per ordered pair: shape-trees x passes x target phases."""
    return cfg.n_trees * cfg.n_pass * cfg.phases * cfg.target_factor


def kernel_work(curve: np.ndarray, cfg: MatchConfig) -> dict[str, int]:
    """Inner-loop iterations (one ``left + right + λ dif`` and a minimum each) and in-band
    table entries of one dynamic programme under ``cfg`` (its first shape-tree), counted
    from the bands the kernel uses: the size of the work a GPU thread block would do."""
    from shapetree.matching._api import model_curve, model_passes
    from shapetree.matching._match import _bands

    m = int(cfg.n_points)
    td = model_passes(model_curve(curve, cfg), cfg)[0].trees[0]
    lmin, lmax = _bands(td, m, cfg.band)
    n_nodes = td.tree.n_nodes
    iters = entries = 0
    for t in range(len(lmin)):
        rows = int(lmax[t] - lmin[t] + 1)
        entries += rows * m
        if t >= n_nodes:
            continue
        lt, rt = int(td.left_tab[t]), int(td.right_tab[t])
        for length in range(int(lmin[t]), int(lmax[t]) + 1):
            if length == 1:
                continue
            k0 = max(1, int(lmin[lt]), length - int(lmax[rt]))
            k1 = min(length - 1, int(lmax[lt]), length - int(lmin[rt]))
            iters += m * max(0, k1 - k0 + 1)
    return {"inner_iterations": iters, "table_entries": entries, "tables": len(lmin)}


def rates(curves: list[np.ndarray]) -> dict[str, Any]:
    out = {}
    for name in RATE_PRESETS:
        cfg = MatchConfig.preset(name)
        distance_matrix(curves[:2], None, cfg, progress=False, workers=1)  # JIT warm-up
        _, cpu, wall = _cpu(
            lambda cfg=cfg: distance_matrix(curves, None, cfg, progress=False, workers=1)
        )
        pairs = len(curves) ** 2
        out[name] = {
            "n_points": cfg.n_points,
            "kernel_runs": kernel_runs(cfg),
            "pairs": pairs,
            "cpu_seconds": cpu,
            "wall_seconds": wall,
            "cpu_ms_per_pair": 1e3 * cpu / pairs,
            "pairs_per_cpu_second": pairs / cpu,
            **(kernel_work(curves[0], cfg) if cfg.n_points else {}),
        }
        w = out[name]
        if "inner_iterations" in w:
            # inner iterations per CPU-second: how close the kernel runs to the machine
            w["inner_iterations_per_cpu_second"] = (
                w["inner_iterations"] * w["kernel_runs"] * pairs / cpu
            )
    return out


def replay(bound: np.ndarray, cost: np.ndarray, k: int) -> np.ndarray:
    """Full matchings per query that ``knn`` performs (its two default rounds)."""
    nq, n = cost.shape
    k = min(k, n)
    order = np.argsort(bound, axis=1, kind="stable")
    full = np.empty(nq, dtype=np.int64)
    for q in range(nq):
        first = order[q, :k]
        tau = np.sort(cost[q, first])[k - 1]
        rest = order[q, k:]
        full[q] = k + int(np.count_nonzero(bound[q, rest] <= tau))
    return full


def projected_fraction(bound: np.ndarray, cost: np.ndarray, k: int, n: int) -> float:
    """Computed fraction at ``n`` shapes if the distances keep MPEG-7's distribution."""
    fr = []
    for q in range(cost.shape[0]):
        tau = np.quantile(cost[q], min(1.0, k / n))
        fr.append(np.mean(bound[q] <= tau))
    return float(np.mean(fr))


def pruning(bound: np.ndarray, cost: np.ndarray, subsets: int, seed: int) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    n_all = cost.shape[1]
    rows: dict[str, Any] = {}
    for k in KS:
        per = {}
        for n in [*(s for s in SIZES if s < n_all), n_all]:
            fracs = []
            for _ in range(subsets if n < n_all else 1):
                if n < n_all:
                    pick = rng.choice(n_all, n, replace=False)
                    fracs.append(float(np.mean(replay(bound[:, pick], cost[:, pick], k) / n)))
                else:
                    fracs.append(float(np.mean(replay(bound, cost, k) / n)))
            per[str(n)] = {"computed": float(np.mean(fracs)), "measured": True}
        for n in PROJECT:
            per[str(n)] = {"computed": projected_fraction(bound, cost, k, n), "measured": False}
        rows[str(k)] = per
    return rows


def cascade(bounds: dict[int, np.ndarray], cost: np.ndarray, k: int, n: int) -> dict[str, float]:
    """Shares of pairs that reach each stage of the cascade keep_from 3 -> 1 -> full at
    ``n`` shapes (the query's k-th distance as the ``k / n`` quantile, as projected)."""
    s2, s3 = [], []
    for q in range(cost.shape[0]):
        tau = np.quantile(cost[q], min(1.0, k / n))
        cheap = bounds[3][q] <= tau
        s2.append(np.mean(cheap))
        s3.append(np.mean(cheap & (bounds[1][q] <= tau)))
    return {"second_bound": float(np.mean(s2)), "full": float(np.mean(s3))}


def projection(
    rate: dict[str, Any],
    bound_rec: dict[str, Any],
    prune: dict[str, Any],
    bounds: dict[int, np.ndarray],
    cost: np.ndarray,
    preset: str,
) -> dict[str, Any]:
    """CPU-hours and wall hours of exhaustive and pruned all-pairs at 10k and 100k: knn
    with its default bound (keep_from=1), and a cascade (keep_from=3, then 1, then full)."""
    s_pair = rate[preset]["cpu_ms_per_pair"] / 1e3
    r1 = bound_rec["1"]["bound_over_full"]
    r3 = bound_rec["3"]["bound_over_full"]
    out = {}
    for n in PROJECT:
        pairs = float(n) ** 2
        row = {"pairs": pairs, "exhaustive_cpu_hours": pairs * s_pair / 3600}
        for k in KS:
            f = prune[str(k)][str(n)]["computed"]
            row[f"knn{k}_computed_fraction"] = f
            row[f"knn{k}_cpu_hours"] = pairs * s_pair * (r1 + f) / 3600
            c = cascade(bounds, cost, k, n)
            row[f"cascade{k}_shares"] = c
            row[f"cascade{k}_cpu_hours"] = (
                pairs * s_pair * (r3 + c["second_bound"] * r1 + c["full"]) / 3600
            )
        row["wall_hours_on_workers"] = {
            str(w): {
                "exhaustive": row["exhaustive_cpu_hours"] / w,
                **{f"knn{k}": row[f"knn{k}_cpu_hours"] / w for k in KS},
                **{f"cascade{k}": row[f"cascade{k}_cpu_hours"] / w for k in KS},
            }
            for w in WORKERS
        }
        out[str(n)] = row
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="mpeg7", choices=sorted(PRESETS))
    ap.add_argument("--queries", type=int, default=16)
    ap.add_argument("--rate-shapes", type=int, default=12)
    ap.add_argument("--subsets", type=int, default=3)
    ap.add_argument("--dask-shapes", type=int, default=40)
    ap.add_argument("--no-dask", action="store_true")
    ap.add_argument("--check-knn", action="store_true")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--output", default=str(RESULTS / "bench_scale.json"))
    args = ap.parse_args(argv)
    t_all = time.perf_counter()
    ds = load("mpeg7", n_points=None, progress=False)
    rng = np.random.default_rng(args.seed)
    n_all = len(ds.curves)
    rate_ids = rng.choice(n_all, args.rate_shapes, replace=False)
    rate = rates([ds.curves[i] for i in rate_ids])
    print(
        f"{'preset':<13} {'points':>6} {'runs/pair':>9} {'CPU ms/pair':>11} "
        f"{'pairs/CPU-s':>11} {'iters/run':>10} {'Giter/CPU-s':>11}"
    )
    for name, r in rate.items():
        print(
            f"{name:<13} {r['n_points']!s:>6} {r['kernel_runs']:>9} "
            f"{r['cpu_ms_per_pair']:>11.2f} {r['pairs_per_cpu_second']:>11.0f} "
            f"{r.get('inner_iterations', 0):>10} "
            f"{r.get('inner_iterations_per_cpu_second', 0) / 1e9:>11.2f}"
        )

    cfg = MatchConfig.preset(args.preset)
    qids = np.sort(rng.choice(n_all, args.queries, replace=False))
    queries = [ds.curves[i] for i in qids]
    # new queries: the database is every other shape (a query never finds itself)
    database = [c for i, c in enumerate(ds.curves) if i not in set(qids.tolist())]
    n_db = len(database)
    cost, c_cpu, _ = _cpu(
        lambda: distance_matrix(queries, database, cfg, progress=False, workers=1)
    )
    cost = np.maximum(cost, 0.0)
    bounds, bound_rec = {}, {}
    pos = cost > 1e-9
    print(f"\nlower bounds ({args.preset}, {args.queries} queries x {n_db}, one thread)")
    print(f"{'keep_from':>9} {'CPU / full':>10} {'tightness':>9} {'above cost':>10}")
    for kf in KEEP_FROM:
        b, b_cpu, _ = _cpu(
            lambda kf=kf: lower_bounds(queries, database, cfg, workers=1, keep_from=kf)
        )
        bounds[kf] = b
        tight = b[pos] / cost[pos]
        bound_rec[str(kf)] = {
            "bound_cpu_seconds": b_cpu,
            "bound_over_full": b_cpu / c_cpu,
            "tightness_mean": float(tight.mean()),
            "tightness_quantiles": {
                str(q): float(np.quantile(tight, q)) for q in (0.05, 0.25, 0.5, 0.75, 0.95)
            },
            "bound_above_cost": int(np.count_nonzero(b > cost)),
        }
        r = bound_rec[str(kf)]
        print(
            f"{kf:>9} {r['bound_over_full']:>10.2f} {r['tightness_mean']:>9.3f} "
            f"{r['bound_above_cost']:>10}"
        )
    bound = bounds[1]
    prune = pruning(bound, cost, args.subsets, args.seed)
    cols = list(prune[str(KS[0])])
    print(f"\nshare matched in full by knn ({args.preset}); * = projected")
    print(f"{'k':>4} " + " ".join(f"{c:>9}" for c in cols))
    for k, per in prune.items():
        cells = []
        for c in cols:
            if c in per:
                cells.append(f"{per[c]['computed']:>8.3f}{'' if per[c]['measured'] else '*'}")
            else:
                cells.append(f"{'':>9}")
        print(f"{k:>4} " + " ".join(f"{c:>9}" for c in cells))
    check = None
    if args.check_knn:
        st: dict = {}
        knn(queries, database, cfg, k=40, workers=2, stats=st)
        check = {
            "k": 40,
            "knn_full": int(st["full"]),
            "replay_full": int(replay(bound, cost, 40).sum()),
        }
        print(f"\nknn check (k=40): knn {check['knn_full']} full, replay {check['replay_full']}")
    dask_rec = None
    if not args.no_dask:
        from bench_dask import measure

        ids = rng.choice(n_all, args.dask_shapes, replace=False)
        dask_rec = measure([ds.curves[i] for i in ids], args.preset, workers=2, repeat=2)
        print(
            f"\ndask local:2 vs 2 threads on {args.dask_shapes} shapes: end to end "
            f"{dask_rec['end_to_end_over_threads']:.2f}x the threaded time, warm "
            f"{dask_rec['warm_over_threads']:.2f}x, bitwise equal {dask_rec['bitwise_equal']}"
        )
    proj = projection(rate, bound_rec, prune, bounds, cost, args.preset)
    print(f"\nprojection ({args.preset}, CPU-hours; cascade: keep_from 3 -> 1 -> full)")
    head = [f"knn{k}" for k in KS] + [f"casc{k}" for k in KS]
    print(f"{'shapes':>8} {'exhaustive':>11} " + " ".join(f"{h:>8}" for h in head))
    for n, row in proj.items():
        cells = [row[f"knn{k}_cpu_hours"] for k in KS] + [row[f"cascade{k}_cpu_hours"] for k in KS]
        line = " ".join(f"{c:>8.0f}" for c in cells)
        print(f"{n:>8} {row['exhaustive_cpu_hours']:>11.0f} {line}")
    rec = {
        "command": "python benchmarks/bench_scale.py " + " ".join(argv or sys.argv[1:]),
        "rates": rate,
        "rate_shapes": int(args.rate_shapes),
        "bound": bound_rec,
        "pruning": prune,
        "knn_check": check,
        "dask": dask_rec,
        "projection": proj,
        "seconds": time.perf_counter() - t_all,
        "machine": machine(),
    }
    write_json(Path(args.output), rec)
    print(f"\nwrote {args.output} ({rec['seconds']:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
