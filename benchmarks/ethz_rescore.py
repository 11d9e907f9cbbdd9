"""ETHZ: how much the frame prior adds, and how well its weight transfers to an unseen class.

Usage::

    python3 benchmarks/ethz_rescore.py [--workers 2]

Runs (or reads from the detection cache) every class model over all 255 images with
detections ranked by cost alone (``frame_prior=0``, every other ``DetectParams`` at its
default), then re-scores the kept detections with
``-cost + w * log(sqrt(box area / image area))`` for each weight ``w`` of a grid.  The frame
prior only re-orders kept detections, so this equals running the detector with
``frame_prior=w``.  Reports the mean DR at 0.4 FPPI (20% rule) for every ``w`` and a
leave-one-class-out estimate: the weight is picked on four classes and scored on the fifth.
Writes ``benchmarks/results/ethz_frame_prior.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import RESULTS, machine, write_json  # noqa: E402

from shapetree.detection import DetectParams, dr_at_fppi, dr_fppi_curve, evaluate_ethz  # noqa: E402
from shapetree.detection._ethz_eval import ETHZ_CLASSES, _gt_boxes, _images, ethz_root  # noqa: E402

WEIGHTS = (0.0, 0.025, 0.05, 0.075, 0.1, 0.15, 0.2)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--data", default=os.environ.get("SHAPETREE_DATA", str(REPO.parent / "shared" / "datasets"))
    )
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--cache-dir", default=str(REPO / "cache" / "ethz_detect"))
    ap.add_argument("--json", default=str(RESULTS / "ethz_frame_prior.json"))
    args = ap.parse_args()
    t0 = time.perf_counter()
    params = DetectParams(frame_prior=0.0)
    res = evaluate_ethz(
        args.data, cache_dir=args.cache_dir, params=params, k=5, workers=args.workers
    )
    root = ethz_root(args.data)
    cache = Path(res["cache_dir"])
    imgs = _images(root)
    share = {}
    for folder, stem in imgs:
        with Image.open(root / folder / f"{stem}.jpg") as im:
            w, h = im.size
        share[(folder, stem)] = float(w * h)
    table: dict[float, dict[str, float]] = {}
    for wt in WEIGHTS:
        row = {}
        for cls in ETHZ_CLASSES:
            dets, gts = [], {}
            for folder, stem in imgs:
                key = f"{folder}/{stem}"
                gts[key] = _gt_boxes(root, folder, stem, cls)
                doc = json.loads((cache / cls / f"{folder}__{stem}.json").read_text())
                for d in doc["detections"]:
                    x1, y1, x2, y2 = d["bbox"]
                    r = min(max(x2 - x1, 1.0) * max(y2 - y1, 1.0) / share[(folder, stem)], 1.0)
                    dets.append((key, d["score"] + wt * 0.5 * math.log(r), d["bbox"]))
            fppi, dr, _ = dr_fppi_curve(dets, gts, len(imgs), 0.2)
            row[cls] = round(dr_at_fppi(fppi, dr, 0.4), 4)
        row["mean"] = round(float(np.mean([row[c] for c in ETHZ_CLASSES])), 4)
        table[wt] = row
    loco = {}
    for cls in ETHZ_CLASSES:
        others = [c for c in ETHZ_CLASSES if c != cls]
        best = max(WEIGHTS, key=lambda w: (np.mean([table[w][c] for c in others]), -w))
        loco[cls] = {"weight": best, "dr": table[best][cls]}
    loco_mean = round(float(np.mean([v["dr"] for v in loco.values()])), 4)
    print("frame_prior   " + "  ".join(f"{c[:9]:>9}" for c in ETHZ_CLASSES) + "       mean")
    for wt, row in table.items():
        print(
            f"{wt:>11.3f}   "
            + "  ".join(f"{row[c]:>9.3f}" for c in ETHZ_CLASSES)
            + f"  {row['mean']:>9.3f}"
        )
    print(
        "leave one class out: "
        + ", ".join(f"{c} w={v['weight']} {v['dr']:.3f}" for c, v in loco.items())
    )
    print(f"leave-one-class-out mean DR@0.4 FPPI (20% rule): {loco_mean:.3f}")
    out = {
        "measure": "DR at 0.4 FPPI, 20% rule, k=5 detections per image",
        "by_weight": {str(w): r for w, r in table.items()},
        "leave_one_class_out": loco,
        "leave_one_class_out_mean": loco_mean,
        "params": params.as_dict(),
        "seconds": round(time.perf_counter() - t0, 1),
        "machine": machine(),
        "command": "python3 benchmarks/ethz_rescore.py " + " ".join(sys.argv[1:]),
    }
    write_json(Path(args.json), out)
    print("json:", args.json)


if __name__ == "__main__":
    main()
