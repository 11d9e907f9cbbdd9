"""ETHZ Shape Classes: each hand-drawn model over all 255 images (paper §4 / §5.2).

Usage::

    python3 benchmarks/eval_ethz.py [--workers 2] [--classes swans bottles] [--k 5]
    python3 benchmarks/eval_ethz.py --edges own --workers 1   # -> results/ethz_own.json

Writes ``benchmarks/results/ethz.json`` (DR at 0.3 / 0.4 FPPI under the 20% and
50% IoU rules, per class and mean; seconds per image; all parameters), the
DR/FPPI plot and the swan / bottle galleries next to it.  Per-image detections
are cached under ``$SHAPETREE_CACHE/ethz_detect/`` (default
``~/.cache/shapetree/ethz_detect/``; ``--cache-dir`` to change), keyed by the
parameters and the code fingerprint, so a killed run resumes where it stopped
and an edited package never reuses stale detections.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import machine  # noqa: E402

from shapetree.detection import DetectParams, evaluate_ethz  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--data", default=os.environ.get("SHAPETREE_DATA", str(REPO.parent / "shared" / "datasets"))
    )
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--classes", nargs="*", default=None)
    ap.add_argument("--k", type=int, default=5)
    ap.add_argument(
        "--edges",
        choices=("pb", "own"),
        default="pb",
        help="pb: the shipped Pb maps; own: the project's edge map of each image",
    )
    ap.add_argument("--json", default=None, help="default results/ethz.json (ethz_own.json)")
    ap.add_argument(
        "--out-dir",
        default=None,
        help="figures (default results/ for pb, none for own: the figure names are shared)",
    )
    ap.add_argument(
        "--cache-dir",
        default=None,
        help="default: $SHAPETREE_CACHE/ethz_detect (else ~/.cache/shapetree/ethz_detect)",
    )
    args = ap.parse_args()
    results = REPO / "benchmarks" / "results"
    if args.json is None:
        args.json = str(results / ("ethz.json" if args.edges == "pb" else "ethz_own.json"))
    if args.out_dir is None and args.edges == "pb":
        args.out_dir = str(results)
    res = evaluate_ethz(
        args.data,
        json_path=None,
        out_dir=args.out_dir,
        classes=args.classes,
        cache_dir=args.cache_dir,
        params=DetectParams(),
        k=args.k,
        workers=args.workers,
        edges=args.edges,
    )
    res["machine"] = machine()
    res["command"] = "python3 benchmarks/eval_ethz.py " + " ".join(sys.argv[1:])
    from shapetree._atomic import atomic_write_bytes

    atomic_write_bytes(args.json, (json.dumps(res, indent=2) + "\n").encode())
    for key in ("overlap_20", "overlap_50"):
        for at in ("dr_fppi_0.3", "dr_fppi_0.4"):
            print(key, at, json.dumps(res[key][at]))
        print(key, "recall_any_k (ceiling at unlimited FPPI)", json.dumps(res[key]["recall_any_k"]))
    med, p90 = res["seconds_per_image_median"], res["seconds_per_image_p90"]
    print(
        f"seconds/image median {med:.3f} p90 {p90:.3f}",
        "breakdown (median s):",
        json.dumps(res["seconds_breakdown_median"]),
    )


if __name__ == "__main__":
    main()
