"""Time per pair of every shipped preset, as a ratio to ``general`` measured in the same run.

The all-pairs ``distance_matrix`` of the same MPEG-7 shapes (every 35th of the 1,400, so all
classes) is computed under each preset, interleaved over ``--repeats`` rounds (``general``,
``paper``, ... then again) after one warm-up round, so that a busy or drifting machine
slows every preset alike; the median of the rounds is reported with its ratio to
``general``'s. No cache is used, so every pair is matched each round.

Run::

    SHAPETREE_DATA=/work/shared/datasets python3 benchmarks/bench_presets.py

Prints a table and writes ``benchmarks/results/bench_presets.json``.
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
from shapetree.matching import PRESETS  # noqa: E402
from shapetree.retrieval import distance_matrix  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--shapes", type=int, default=40, help="MPEG-7 shapes, evenly spaced")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", type=Path, default=RESULTS / "bench_presets.json")
    args = ap.parse_args(argv)
    curves = load("mpeg7", n_points=None, progress=False).curves
    step = max(1, len(curves) // args.shapes)
    shapes = curves[::step][: args.shapes]
    names = ["general", *(n for n in PRESETS if n != "general")]
    pairs = len(shapes) ** 2

    def once(name: str) -> float:
        t0 = time.perf_counter()
        distance_matrix(shapes, config=name, workers=args.workers, progress=False)
        return time.perf_counter() - t0

    for name in names:  # warm-up: compile or load every kernel the presets use
        once(name)
    times: dict[str, list[float]] = {n: [] for n in names}
    for _ in range(args.repeats):
        for name in names:
            times[name].append(once(name))
    med = {n: float(np.median(t)) for n, t in times.items()}
    rows = {
        n: {
            "seconds_median": round(med[n], 3),
            "seconds": [round(t, 3) for t in times[n]],
            "ms_per_pair": round(1e3 * med[n] / pairs, 4),
            "ratio_to_general": round(med[n] / med["general"], 3),
            "config": PRESETS[n].as_dict(),
        }
        for n in names
    }
    print(f"{len(shapes)} MPEG-7 shapes ({pairs} ordered pairs), {args.workers} threads, "
          f"median of {args.repeats} interleaved rounds")  # fmt: skip
    print(f"{'preset':14s}{'s':>9s}{'ms/pair':>10s}{'x general':>11s}")
    for n, r in rows.items():
        print(
            f"{n:14s}{r['seconds_median']:>9.2f}{r['ms_per_pair']:>10.3f}{r['ratio_to_general']:>11.2f}"
        )
    out = {
        "command": " ".join(["python3", "benchmarks/bench_presets.py", *(argv or sys.argv[1:])]),
        "shapes": len(shapes),
        "pairs": pairs,
        "workers": args.workers,
        "repeats": args.repeats,
        "presets": rows,
        "machine": machine(),
    }
    write_json(args.json, out)
    print(f"json: {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
