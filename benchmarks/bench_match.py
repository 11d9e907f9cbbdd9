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
  with ``band=3``; ``f32 x`` is the float32 speed-up over float64 in the same run;
* ``dense``: the same stack, float32, ``band=3``, against the targets sampled at ``2n``
  points (``target_factor=2``, the held-out choices' setting);
* ``chunk x``: one shape-tree's tables against such a target filled node by node over
  the time with the kernel's chunks of target lengths (same tables, checked bit for bit).

The options of issue 15 (``--option-sizes``, default n = m = 16, 24, 32, 50; one matching
of one pair, float64, cost only, ratios to the directed Procrustes shape-tree matcher in
the same run and with the same band):

* ``hyperbolic``: ``dif="hyperbolic"`` in the shape-tree kernel;
* ``symmetric``: ``matcher="symmetric"`` (:mod:`shapetree.matching._subcurves`, all pairs
  of subcurves, O(n^2 m^2 (n + m))), exact and with ``band=3``;
* ``replace_any``: arbitrary replacement, O(n^3 m^3): **slow, exact, single-pair** (tens of
  seconds at n = m = 50 without a band), exact and with ``band=3``.

``python benchmarks/bench_match.py --options-only`` measures only these and updates the
``options`` entry of the existing JSON.

The height-function fusion (``MatchConfig.height_weight``; ``--height-only`` measures only
it and updates the ``height`` entry): ``distance_matrix`` of 40 random closed shapes against
themselves (1600 ordered pairs, the two cores' threads, float32, the ``n64 T3 none tmean``
base of ``eval_height_variants.py``, no cache), without the fusion and with it at
``height_points`` 64 and 100; ``x`` is the time over the base's in the same run.
"""

from __future__ import annotations

import argparse
import json
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
from shapetree.matching._kernels import fill_tables, length_chunk  # noqa: E402
from shapetree.matching._match import _bands  # noqa: E402
from shapetree.matching._reference import reference_match_cost  # noqa: E402
from shapetree.matching._subcurves import pair_curve, pair_tables, pair_top  # noqa: E402
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


def time_once(fn, repeats: int) -> float:
    """Median seconds per call; one call (after the warm-up) when a call takes over 2 s."""
    t0 = time.perf_counter()
    fn()
    first = time.perf_counter() - t0
    if first > 2.0:
        return first
    return timeit(fn, repeats)


def fill_order(model, target, repeats: int) -> dict:
    """One shape-tree's tables (float32, band 3) filled node by node (one chunk of every
    target length) and by the kernel's chunks of lengths (:func:`._kernels.fill_tables`),
    timed in turn; the tables are checked to be the same bit for bit."""
    td = model.trees[0]
    m = target.n_points
    lmin, lmax = _bands(td, m, 3.0)
    # entries outside the bands are never written: both start from the same value
    tabs = {c: np.full((td.n_tables, m, 2 * m), -1.0, np.float32) for c in (0, 10**6)}

    def run(chunk):
        fill_tables(
            td.left_tab, td.right_tab, *td.kernel_arrays(np.float32), target.tri, target.deg,
            target.base_table("procrustes"), target.blen, True, 0.0, 1.0, lmin, lmax,
            tabs[chunk], False, chunk,
        )  # fmt: skip

    best = {c: np.inf for c in tabs}
    for _ in range(max(3, repeats)):
        for c in tabs:  # in turn, so that a drift of the machine's speed hits both
            t0 = time.perf_counter()
            run(c)
            best[c] = min(best[c], time.perf_counter() - t0)
    assert np.array_equal(tabs[0], tabs[10**6]), "the fill order changed a table"
    return {
        "fill_dense_node_by_node_ms": 1e3 * best[10**6],
        "fill_dense_chunked_ms": 1e3 * best[0],
        "fill_dense_chunk": int(length_chunk(m, 4)),
        "fill_dense_chunk_speedup": best[10**6] / best[0],
    }


def option_rows(sizes: list[int], repeats: int) -> list[dict]:
    """Timings of the issue-15 options against the directed matcher (module docstring)."""
    rng = np.random.default_rng(15)
    # compile every kernel once on a small pair (numba's first call)
    a0, b0 = shape(rng, 8), shape(rng, 8)
    for sym, rep in ((True, False), (False, True)):
        c0, c1 = (pair_curve(x, closed=True, weight=1.0, length_power=1.0, dif="procrustes")
                  for x in (a0, b0))  # fmt: skip
        pair_tables(c0, c1, symmetric=sym, replace_any=rep, dif="procrustes", occlusion=1.0)
    rows = []
    for n in sizes:
        a, b = shape(rng, n), shape(rng, n)
        row: dict = {"n": n}
        tg = prepare_target(b)
        for band in (None, 3.0):
            tag = "exact" if band is None else "band3"
            for dif in ("procrustes", "hyperbolic"):
                md = prepare_model(a, dif=dif)
                p = MatchParams(band=band, dif=dif, occlusion=1.0)
                row[f"directed_{dif}_{tag}_ms"] = 1e3 * timeit(
                    lambda md=md, p=p, tg=tg: match_cost(md, tg, p), repeats
                )
            row[f"hyperbolic_over_directed_{tag}"] = (
                row[f"directed_hyperbolic_{tag}_ms"] / row[f"directed_procrustes_{tag}_ms"]
            )
            ca = pair_curve(a, closed=True, weight=1.0, length_power=1.0, dif="procrustes")
            cb = pair_curve(b, closed=True, weight=1.0, length_power=1.0, dif="procrustes")
            for name, sym, rep in (("symmetric", True, False), ("replace_any", False, True)):

                def run(sym=sym, rep=rep, band=band, ca=ca, cb=cb):
                    S, _, _ = pair_tables(
                        ca, cb, symmetric=sym, replace_any=rep, dif="procrustes",
                        occlusion=1.0, band=band,
                    )  # fmt: skip
                    return pair_top(S, ca, cb, symmetric=sym)[0]

                ms = 1e3 * time_once(run, repeats)
                row[f"{name}_{tag}_ms"] = ms
                row[f"{name}_over_directed_{tag}"] = ms / row[f"directed_procrustes_{tag}_ms"]
        rows.append(row)
    return rows


def height_rows(repeats: int, n_shapes: int = 40) -> list[dict]:
    """Timings of the height-function fusion against the shape-tree matrix alone (module
    docstring)."""
    from shapetree.matching import MatchConfig
    from shapetree.retrieval import distance_matrix

    rng = np.random.default_rng(64)
    curves = [shape(rng, 200) for _ in range(n_shapes)]
    base = MatchConfig(n_points=64, n_trees=3, tree_combine="mean", length_power=1.0, phases=1)
    cfgs = {"psi alone": base}
    cfgs.update({f"fused, h at {n}": base.replace(height_weight=0.5, height_points=n)
                 for n in (64, 100)})  # fmt: skip
    for cfg in cfgs.values():  # compile
        distance_matrix(curves[:3], config=cfg, progress=False)
    rows = []
    for label, cfg in cfgs.items():
        s = time_once(lambda cfg=cfg: distance_matrix(curves, config=cfg, progress=False), repeats)
        rows.append({"label": label, "height_points": cfg.height_points if cfg.height_weight
                     else None, "seconds": s, "ms_per_pair": 1e3 * s / n_shapes**2})  # fmt: skip
    for r in rows:
        r["over_psi_alone"] = r["seconds"] / rows[0]["seconds"]
    return rows


def print_height(rows: list[dict]) -> None:
    print("Height-function fusion, distance_matrix of 40 shapes (1600 pairs), 2 threads (medians)")
    print(f"{'':18s} {'s':>7} {'ms/pair':>8} {'x':>6}")
    for r in rows:
        print(f"{r['label']:18s} {r['seconds']:>7.2f} {r['ms_per_pair']:>8.2f} "
              f"{r['over_psi_alone']:>6.2f}")  # fmt: skip


def print_options(rows: list[dict]) -> None:
    print("Issue-15 options, one closed pair, one matching, float64 (medians; x = / directed)")
    print(
        f"{'n=m':>5} {'dir ms':>8} {'hyp x':>6} {'sym ms':>9} {'sym x':>7} {'rep ms':>10} "
        f"{'rep x':>9} | band 3: {'dir ms':>7} {'hyp x':>6} {'sym ms':>8} {'sym x':>7} "
        f"{'rep ms':>9} {'rep x':>8}"
    )
    for r in rows:
        print(
            f"{r['n']:>5} {r['directed_procrustes_exact_ms']:>8.3f} "
            f"{r['hyperbolic_over_directed_exact']:>6.2f} {r['symmetric_exact_ms']:>9.1f} "
            f"{r['symmetric_over_directed_exact']:>7.0f} {r['replace_any_exact_ms']:>10.1f} "
            f"{r['replace_any_over_directed_exact']:>9.0f} |         "
            f"{r['directed_procrustes_band3_ms']:>7.3f} "
            f"{r['hyperbolic_over_directed_band3']:>6.2f} "
            f"{r['symmetric_band3_ms']:>8.1f} {r['symmetric_over_directed_band3']:>7.0f} "
            f"{r['replace_any_band3_ms']:>9.1f} {r['replace_any_over_directed_band3']:>8.0f}"
        )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[32, 50, 64, 100])
    ap.add_argument("--reference-sizes", type=int, nargs="+", default=[16, 24, 32])
    ap.add_argument("--pairs", type=int, default=8, help="random curve pairs per size")
    ap.add_argument("--bands", type=float, nargs="+", default=[2.0, 3.0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats")
    ap.add_argument("--json", type=Path, default=RESULTS / "bench_match.json")
    ap.add_argument("--option-sizes", type=int, nargs="*", default=[16, 24, 32, 50])
    ap.add_argument(
        "--options-only",
        action="store_true",
        help="only the issue-15 options; update the 'options' entry of the existing JSON",
    )
    ap.add_argument(
        "--height-only",
        action="store_true",
        help="only the height-function fusion; update the 'height' entry of the existing JSON",
    )
    args = ap.parse_args(argv)
    rng = np.random.default_rng(0)
    reps = 3 if args.quick else 7
    command = "python benchmarks/bench_match.py" + (" " + " ".join(argv) if argv else "")
    only = {"height": args.height_only, "options": args.options_only}
    for entry, asked in only.items():
        if asked:  # measure this part alone and update its entry of the existing JSON
            if entry == "height":
                rows = height_rows(5)
                print_height(rows)
            else:
                rows = option_rows(args.option_sizes, reps)
                print_options(rows)
            out = json.loads(args.json.read_text()) if args.json.exists() else {}
            out[entry] = {"command": command, "machine": machine(), "rows": rows}
            write_json(args.json, out)
            print(f"wrote {args.json}")
            return 0
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
        # the dense target of the held-out choices (README, "Pairwise accuracy"): the
        # target sampled at 2n points, float32, band 3, as the engine runs it
        dense = [
            prepare_target(resample(b, 2 * n, closed=True), dtype=np.float32) for _, b in pairs
        ]
        stack = ModelStack(models, 2 * n, MatchParams(band=3.0), dtype=np.float32)

        def run_dense(stack=stack, tgs=dense):
            for tg in tgs:
                stack.costs(tg)

        row["stack_f32_band3_dense_ms"] = 1e3 * timeit(run_dense, reps) / len(pairs) ** 2
        row.update(fill_order(models[0], dense[0], reps))
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
        + f" {'stack32':>8} {'f32 x':>6} {'st32 b3':>8} {'f32 x':>6} {'dense b3':>8} {'chunk x':>7}"
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
            f"{r['stack_f32_band3_dense_ms']:>8.3f} {r['fill_dense_chunk_speedup']:>7.2f} "
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
        "command": command,
        "machine": machine(),
        "rows": rows,
        "growth_exponent": slope,
        "target": "exact closed matching at n = m = 50 in <= 5 ms on one core",
    }
    if args.option_sizes:
        opt = option_rows(args.option_sizes, reps)
        print_options(opt)
        out["options"] = {"command": command, "machine": machine(), "rows": opt}
    elif args.json.exists():
        # not measured in this run: keep the earlier run's entry (it names its command)
        earlier = json.loads(args.json.read_text()).get("options")
        if earlier is not None:
            out["options"] = earlier
    if args.json.exists():  # measured only with --height-only: keep it
        earlier = json.loads(args.json.read_text()).get("height")
        if earlier is not None:
            out["height"] = earlier
    write_json(args.json, out)
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
