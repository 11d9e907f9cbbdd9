"""Speed of closed-curve matching: compiled kernel vs the pure-Python reference.

Prints a table and writes ``benchmarks/results/bench_match.json``. All timings are on one
core (the kernel is single-threaded) in this one run; compare them as ratios.

Run::

    python benchmarks/bench_match.py            # n = m = 32, 50, 64, 100; reference up to 32
    python benchmarks/bench_match.py --quick    # fewer repeats

What is measured, per size ``n = m``:

* ``exact``: ψ(A, B) for closed curves over all cyclic alignments, one shape-tree, cost only
  (``match_cost``), target precomputation excluded (it is done once per curve);
* ``traceback``: the same plus the full correspondence (``match_prepared``);
* ``band=r``: the pruned mode (``MatchParams(band=r)``), its speed-up over exact and how
  much its costs differ from the exact ones (relative, mean and max over the pairs);
* ``reference``: the literal pure-Python recursion (``reference_match_cost``), for the
  sizes up to ``--reference-max``; the ratio reference/kernel is taken at the same size;
* ``stack``: the retrieval engine's path, all models against a target in one kernel call
  (``ModelStack``), in float64 and in float32 (the engine's default precision), exact and
  with ``band=3``; ``f32 x`` is the float32 speed-up over float64 in the same run.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, machine, write_json  # noqa: E402

from shapetree.curves import resample  # noqa: E402
from shapetree.matching import (  # noqa: E402
    MatchParams,
    match_cost,
    match_prepared,
    prepare_model,
    prepare_target,
)
from shapetree.matching._batch import ModelStack  # noqa: E402
from shapetree.matching._reference import reference_match_cost  # noqa: E402
from shapetree.tree import build_shape_tree  # noqa: E402


def shape(rng: np.random.Generator, n: int) -> np.ndarray:
    """A random smooth star-shaped closed curve, resampled to ``n`` points."""
    t = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    r = 1.0
    for k in range(2, 7):
        r = r + rng.normal(0, 0.25 / k) * np.cos(k * t + rng.uniform(0, 2 * np.pi))
    return resample(np.c_[r * np.cos(t), r * np.sin(t)], n, closed=True)


def timeit(fn, repeats: int) -> float:
    """Median seconds per call over ``repeats`` calls (after one warm-up)."""
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[32, 50, 64, 100])
    ap.add_argument("--reference-sizes", type=int, nargs="+", default=[16, 24, 32])
    ap.add_argument("--pairs", type=int, default=8, help="random curve pairs per size")
    ap.add_argument("--bands", type=float, nargs="+", default=[2.0, 3.0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats")
    ap.add_argument("--json", type=Path, default=RESULTS / "bench_match.json")
    args = ap.parse_args(argv)
    rng = np.random.default_rng(0)
    reps = 3 if args.quick else 7
    rows = []
    for n in sorted(set(args.sizes) | set(args.reference_sizes)):
        pairs = [(shape(rng, n), shape(rng, n)) for _ in range(args.pairs)]
        models = [prepare_model(a) for a, _ in pairs]
        targets = [prepare_target(b) for _, b in pairs]
        row: dict = {"n": n}
        exact_costs = np.array([match_cost(md, tg) for md, tg in zip(models, targets)])

        def run_exact(models=models, targets=targets):
            for md, tg in zip(models, targets):
                match_cost(md, tg)

        def run_tb(models=models, targets=targets):
            for md, tg in zip(models, targets):
                match_prepared(md, tg)

        def run_prep(pairs=pairs):
            for _, b in pairs:
                prepare_target(b)

        row["exact_ms"] = 1e3 * timeit(run_exact, reps) / len(pairs)
        row["exact_per_s"] = 1e3 / row["exact_ms"]
        row["traceback_ms"] = 1e3 * timeit(run_tb, reps) / len(pairs)
        row["prepare_target_ms"] = 1e3 * timeit(run_prep, reps) / len(pairs)
        for band in args.bands:
            p = MatchParams(band=band)

            def run_band(models=models, targets=targets, p=p):
                for md, tg in zip(models, targets):
                    match_cost(md, tg, p)

            ms = 1e3 * timeit(run_band, reps) / len(pairs)
            costs = np.array([match_cost(md, tg, p) for md, tg in zip(models, targets)])
            rel = (costs - exact_costs) / exact_costs
            row[f"band{band:g}"] = {
                "ms": ms,
                "speedup_vs_exact": row["exact_ms"] / ms,
                "cost_rel_diff_mean": float(rel.mean()),
                "cost_rel_diff_max": float(rel.max()),
            }
        for dt, tag in ((np.float64, "f64"), (np.float32, "f32")):
            for band in (None, 3.0):
                mp = MatchParams(band=band)
                stack = ModelStack(models, n, mp, dtype=dt)
                tgs = [prepare_target(b, dtype=dt) for _, b in pairs]

                def run_stack(stack=stack, tgs=tgs):
                    for tg in tgs:
                        stack.costs(tg)

                key = f"stack_{tag}" + ("" if band is None else f"_band{band:g}") + "_ms"
                row[key] = 1e3 * timeit(run_stack, reps) / len(pairs) ** 2
        row["f32_speedup"] = row["stack_f64_ms"] / row["stack_f32_ms"]
        row["f32_band3_speedup"] = row["stack_f64_band3_ms"] / row["stack_f32_band3_ms"]
        if n in args.reference_sizes:
            a, b = pairs[0]
            tree = build_shape_tree(a, closed=True)
            t0 = time.perf_counter()
            ref = reference_match_cost(tree, b)
            row["reference_ms"] = 1e3 * (time.perf_counter() - t0)
            row["reference_over_kernel"] = row["reference_ms"] / row["exact_ms"]
            row["reference_cost_rel_err"] = abs(ref - exact_costs[0]) / exact_costs[0]
        rows.append(row)

    sizes = np.array([r["n"] for r in rows], float)
    times = np.array([r["exact_ms"] for r in rows])
    big = sizes >= 32
    slope = (
        float(np.polyfit(np.log(sizes[big]), np.log(times[big]), 1)[0]) if big.sum() > 1 else None
    )

    hdr = (
        f"{'n=m':>5} {'exact ms':>9} {'match/s':>8} {'+corr ms':>9} {'prep ms':>8} "
        + " ".join(f"{'band' + format(b, 'g') + ' x':>9} {'Δcost':>7}" for b in args.bands)
        + f" {'stack32':>8} {'f32 x':>6} {'st32 b3':>8} {'f32 x':>6}"
        + f" {'ref ms':>9} {'ref/kern':>9}"
    )
    print("Closed-curve matching, one shape-tree, one core (medians)")
    print(hdr)
    for r in rows:
        line = (
            f"{r['n']:>5} {r['exact_ms']:>9.3f} {r['exact_per_s']:>8.0f} "
            f"{r['traceback_ms']:>9.3f} {r['prepare_target_ms']:>8.3f} "
        )
        for b in args.bands:
            d = r[f"band{b:g}"]
            line += f"{d['speedup_vs_exact']:>9.2f} {100 * d['cost_rel_diff_mean']:>6.2f}% "
        line += (
            f"{r['stack_f32_ms']:>8.3f} {r['f32_speedup']:>6.2f} "
            f"{r['stack_f32_band3_ms']:>8.3f} {r['f32_band3_speedup']:>6.2f} "
        )
        if "reference_ms" in r:
            line += f"{r['reference_ms']:>9.0f} {r['reference_over_kernel']:>9.0f}"
        print(line)
    if slope is not None:
        print(
            f"time grows as n^{slope:.2f} for n = m in {sorted(sizes[big].astype(int).tolist())}"
            " (theory: O(n m^3) = n^4)"
        )
    out = {
        "command": "python benchmarks/bench_match.py" + (" " + " ".join(argv) if argv else ""),
        "machine": machine(),
        "rows": rows,
        "growth_exponent": slope,
        "target": "exact closed matching at n = m = 50 in <= 5 ms on one core",
    }
    write_json(args.json, out)
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
