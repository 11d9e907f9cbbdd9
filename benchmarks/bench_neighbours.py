"""``evaluate --neighbours K`` (exact pruned k-NN) against the exhaustive matrix, same run.

For each ``SET[:CLASSES]`` given, runs ``shapetree.retrieval.evaluate`` twice with the set's
tuned preset, once exhaustive and once with ``neighbours=K`` (the fewest the protocol
needs, or ``--k``), and records both scores (they must be equal), both wall times, their
ratio, the full matchings performed and the share skipped, in
``benchmarks/results/neighbours.json`` (one entry per set, replaced when rerun). No cache
is used, so both times are real computation.

Run::

    python benchmarks/bench_neighbours.py kimia99 mpeg7:20 swedish_leaf:5
    python benchmarks/bench_neighbours.py mpeg7            # the whole set (about 2 x 45 min)

``mpeg7:20`` keeps the first 20 classes (sorted by name); ``--neighbours`` sets K for every
set (default: mpeg7 41, kimia99 11, swedish_leaf 10).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, machine, write_json  # noqa: E402

from shapetree.datasets import load  # noqa: E402
from shapetree.retrieval import evaluate  # noqa: E402

KEYS = {"kimia99": "ranks", "mpeg7": "bullseye", "swedish_leaf": "accuracy_mean"}
#: K per set: the protocol's minimum (mpeg7, kimia99); for Swedish leaf 10, so that few test
#: leaves (about (2/3)^9 = 3%) lack a training leaf among their neighbours and need a full row
NEED = {"kimia99": 11, "mpeg7": 41, "swedish_leaf": 10}


def run(spec: str, k: int | None, workers: int) -> dict:
    name, _, n_cls = spec.partition(":")
    params: dict = {"workers": workers, "cache_dir": None}
    if n_cls:
        classes = sorted(set(load(name, n_points=None, progress=False).labels))
        params["classes"] = ",".join(classes[: int(n_cls)])
    kk = k or NEED[name]
    t0 = time.perf_counter()
    full = evaluate(name, name, progress=False, verbose=False, **params)
    t_full = time.perf_counter() - t0
    t0 = time.perf_counter()
    pruned = evaluate(name, name, progress=False, verbose=False, neighbours=kk, **params)
    t_pruned = time.perf_counter() - t0
    key = KEYS[name]
    return {
        "set": spec,
        "n_shapes": full["n_shapes"],
        "preset": name,
        "neighbours": kk,
        "score_key": key,
        "exhaustive_score": full[key],
        "pruned_score": pruned[key],
        "equal": full[key] == pruned[key]
        and full.get("bullseye_per_class") == pruned.get("bullseye_per_class")
        and full.get("accuracy_splits") == pruned.get("accuracy_splits"),
        "exhaustive_seconds": round(t_full, 1),
        "pruned_seconds": round(t_pruned, 1),
        "speedup": round(t_full / t_pruned, 3),
        "pairs": full["pairs"],
        "full_matchings": pruned["neighbours"]["full_matchings"],
        "skipped": pruned["neighbours"]["skipped"],
        "bound_seconds": pruned["neighbours"]["bound_seconds"],
        "full_seconds": pruned["neighbours"]["full_seconds"],
        "rows_completed": pruned["neighbours"]["rows_completed"],
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sets", nargs="+", metavar="SET[:CLASSES]")
    ap.add_argument("--neighbours", type=int, default=None)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args(argv)
    out = RESULTS / "neighbours.json"
    doc = json.loads(out.read_text()) if out.exists() else {"runs": {}}
    print(f"{'set':<16} {'n':>5} {'K':>3} {'equal':>5} {'exh. s':>8} {'knn s':>8} {'ratio':>6}")
    for spec in args.sets:
        r = run(spec, args.neighbours, args.workers)
        r["command"] = f"python benchmarks/bench_neighbours.py {spec}" + (
            f" --neighbours {args.neighbours}" if args.neighbours else ""
        )
        r["machine"] = machine()
        doc["runs"][spec] = r
        print(
            f"{spec:<16} {r['n_shapes']:>5} {r['neighbours']:>3} {r['equal']!s:>5} "
            f"{r['exhaustive_seconds']:>8.1f} {r['pruned_seconds']:>8.1f} {r['speedup']:>6.2f}"
            f"   skipped {100 * r['skipped']:.1f}% of the pairs"
        )
        write_json(out, doc)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
