"""Exact k-NN pruned by a lower bound (``retrieval.knn``) against exhaustive search.

Prints a table and writes ``benchmarks/results/bench_knn.json``. Everything is measured in
this one run, on the same queries and database:

* ``search``: the exhaustive twin, ``retrieval.search(q, database, config)`` once per query
  (every database shape prepared as a target for each query);
* ``matrix``: the exhaustive block engine, ``distance_matrix(queries, database, config)``
  (targets prepared once per block of queries): the fastest exhaustive way;
* per ``keep_from``: the bound of every pair (``lower_bounds``), its time per pair against
  a full matching's (``matrix`` time per pair), its tightness ``bound / cost`` (mean and
  quantiles, and how many pairs exceed the cost: must be 0), the fraction of pairs whose
  bound exceeds the query's k-th cost (``ideal skip``: what a best-first search can skip),
  and ``knn`` itself: its wall time, the fraction of full matchings it skipped, and whether
  its indices and distances equal ``search``'s (they must);
* ``skip_if_tightness``: the fraction a bound equal to ``r`` times the cost would skip
  (how tight a bound must be on this set).

Run::

    python benchmarks/bench_knn.py                              # 20 MPEG-7 queries vs 300 shapes
    python benchmarks/bench_knn.py --queries 100 --database 0   # the whole set (slow)
    python benchmarks/bench_knn.py --preset paper --keep paper  # keep_top levels (no band)
    python benchmarks/bench_knn.py --preset fused --json benchmarks/results/bench_knn_fused.json

With the height-function fusion (``--preset fused``) the bound is ``B^(1 - w) h^w`` with
``h`` exact for every pair (``knn_height_seconds``: their time inside ``knn``).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, machine, write_json  # noqa: E402

from shapetree.datasets import load  # noqa: E402
from shapetree.matching import MatchConfig  # noqa: E402
from shapetree.retrieval import distance_matrix, search  # noqa: E402
from shapetree.retrieval._knn import knn, lower_bounds  # noqa: E402

#: kept levels tried: ``keep_from`` (top levels dropped) under a band; ``keep_top`` without
KEEPS = {
    "band": [{"keep_from": 1}, {"keep_from": 2}],
    "paper": [{"keep_from": None, "keep_top": 3}, {"keep_from": None, "keep_top": 4}],
}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset", default="mpeg7")
    ap.add_argument("--preset", default="mpeg7")
    ap.add_argument("--queries", type=int, default=20)
    ap.add_argument("--database", type=int, default=300, help="0: the whole set")
    ap.add_argument("--k", type=int, default=40)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--keep", choices=sorted(KEEPS), default=None)
    ap.add_argument(
        "--keep-from", type=int, action="append", default=None, help="only these (repeatable)"
    )
    ap.add_argument(
        "--no-search",
        action="store_true",
        help="skip the per-query search twin (slow): knn is compared with the stable argsort "
        "of distance_matrix's rows (the same numbers), and with search on 3 queries",
    )
    ap.add_argument("--json", type=Path, default=RESULTS / "bench_knn.json")
    args = ap.parse_args(argv)

    cfg = MatchConfig.preset(args.preset)
    keeps = KEEPS[args.keep or ("paper" if cfg.band is None else "band")]
    if args.keep_from:
        keeps = [{"keep_from": int(v)} for v in args.keep_from]
    curves = load(args.dataset, n_points=None, progress=False).curves
    rng = np.random.default_rng(args.seed)
    n_db = len(curves) if args.database <= 0 else min(args.database, len(curves))
    db_idx = np.sort(rng.choice(len(curves), n_db, replace=False))
    q_idx = db_idx[np.sort(rng.choice(n_db, min(args.queries, n_db), replace=False))]
    database = [curves[i] for i in db_idx]
    queries = [curves[i] for i in q_idx]
    nq, pairs = len(queries), len(queries) * n_db
    k = min(args.k, n_db)
    print(
        f"{args.dataset}: {nq} queries x {n_db} shapes ({pairs} pairs), preset {args.preset}, "
        f"k = {k}, {args.workers} workers, seed {args.seed}",
        flush=True,
    )

    t0 = time.perf_counter()
    d_full = distance_matrix(queries, database, cfg, workers=args.workers, progress=False)
    t_matrix = time.perf_counter() - t0
    d_full = np.maximum(d_full, 0.0)
    t0 = time.perf_counter()
    checked = queries[:3] if args.no_search else queries
    ref = [search(q, database, cfg, k=k, workers=args.workers) for q in checked]
    t_search = None if args.no_search else time.perf_counter() - t0
    ref_idx = np.array([r[0] for r in ref])
    ref_dist = np.array([r[1] for r in ref])
    if args.no_search:
        order = np.argsort(d_full, axis=1, kind="stable")[:, :k]
        assert np.array_equal(order[:3], ref_idx), "matrix ranking differs from search"
        ref_idx, ref_dist = order, np.take_along_axis(d_full, order, axis=1)
    tau = np.sort(d_full, axis=1)[:, k - 1 : k]
    full_pair_ms = 1e3 * t_matrix / pairs
    # what a bound of uniform tightness r (bound = r * cost) would skip: how tight a bound
    # must be for a given skip fraction on this set
    skip_if = {str(r): float(np.mean(r * d_full > tau)) for r in (0.5, 0.6, 0.7, 0.8, 0.9, 0.95)}
    print("skip fraction of a bound = r * cost:", skip_if, flush=True)
    t_s = "skipped" if t_search is None else f"{t_search:.1f} s"
    print(
        f"exhaustive: search {t_s}, distance_matrix {t_matrix:.1f} s ({full_pair_ms:.3f} ms/pair)",
        flush=True,
    )

    rows = []
    for keep in keeps:
        t0 = time.perf_counter()
        b = lower_bounds(queries, database, cfg, workers=args.workers, **keep)
        t_bound = time.perf_counter() - t0
        ratio = b / np.maximum(d_full, 1e-12)
        stats: dict = {}
        t0 = time.perf_counter()
        idx, dist = knn(queries, database, cfg, k=k, workers=args.workers, stats=stats, **keep)
        t_knn = time.perf_counter() - t0
        row = dict(
            keep=keep,
            bound_seconds=t_bound,
            bound_ms_per_pair=1e3 * t_bound / pairs,
            bound_over_full_time=t_bound / t_matrix,
            tightness_mean=float(ratio.mean()),
            tightness_quantiles={
                str(q): float(np.quantile(ratio, q)) for q in (0.05, 0.25, 0.5, 0.75, 0.95)
            },
            bound_above_cost=int(np.sum(b > d_full)),
            ideal_skip=float(np.mean(b > tau)),
            knn_seconds=t_knn,
            knn_skipped=stats["skipped"],
            knn_rounds=stats["rounds"],
            knn_bound_seconds=stats["bound_seconds"],
            knn_height_seconds=stats["height_seconds"],
            knn_full_seconds=stats["full_seconds"],
            knn_equals_search=bool(np.array_equal(idx, ref_idx) and np.array_equal(dist, ref_dist)),
            speedup_vs_search=None if t_search is None else t_search / t_knn,
            speedup_vs_matrix=t_matrix / t_knn,
        )
        rows.append(row)
        print(
            f"{keep}: bound {row['bound_ms_per_pair']:.3f} ms/pair "
            f"({row['bound_over_full_time']:.2f} of a full pass), tightness mean "
            f"{row['tightness_mean']:.3f} median {row['tightness_quantiles']['0.5']:.3f}, "
            f"above cost {row['bound_above_cost']}, ideal skip {row['ideal_skip']:.3f}; "
            f"knn {t_knn:.1f} s, skipped {row['knn_skipped']:.3f}, "
            f"equal {row['knn_equals_search']}, x{row['speedup_vs_matrix']:.2f} vs matrix",
            flush=True,
        )

    print()
    print(f"{'kept levels':<34}{'bound/full':>11}{'tight':>8}{'skip':>8}{'knn s':>8}"
          f"{'x search':>10}{'x matrix':>10}{'equal':>7}")  # fmt: skip
    for r in rows:
        print(
            f"{str(r['keep']):<34}{r['bound_over_full_time']:>11.2f}{r['tightness_mean']:>8.3f}"
            f"{r['knn_skipped']:>8.3f}{r['knn_seconds']:>8.1f}{r['speedup_vs_search'] or 0:>10.2f}"
            f"{r['speedup_vs_matrix']:>10.2f}{str(r['knn_equals_search']):>7}"
        )
    out = dict(
        command=" ".join(["python", "benchmarks/bench_knn.py", *(argv or sys.argv[1:])]),
        dataset=args.dataset,
        preset=args.preset,
        config=cfg.as_dict(),
        queries=nq,
        database=n_db,
        pairs=pairs,
        k=k,
        seed=args.seed,
        workers=args.workers,
        search_seconds=t_search,
        matrix_seconds=t_matrix,
        full_ms_per_pair=full_pair_ms,
        skip_if_tightness=skip_if,
        rows=rows,
        machine=machine(),
    )
    write_json(args.json, out)
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
