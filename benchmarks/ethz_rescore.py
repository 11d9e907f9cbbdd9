"""ETHZ: what the two ranking terms add, and how well their weights transfer to a new class.

Usage::

    python3 benchmarks/ethz_rescore.py [--workers 2]

Runs (or reads from the detection cache) every class model over all 255 images with
detections ranked by cost alone (``outline_check=0``, ``frame_prior=0``,
``context_check=0``, every other ``DetectParams`` at its default), then re-scores the
kept detections with ``-cost - c * outline_dif + f * log(sqrt(box area / image area))``
for every pair ``(c, f)`` of a grid.  Both terms only re-order kept detections, so this
equals running the detector with ``outline_check=c, frame_prior=f``.  Reports the mean DR
at 0.4 FPPI (20% rule) for each pair and a leave-one-class-out estimate: the pair is
picked on four classes and scored on the fifth.  Writes ``benchmarks/results/ethz_ranking.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import RESULTS, machine, write_json  # noqa: E402

from shapetree.curves._image import open_image  # noqa: E402
from shapetree.detection import DetectParams, dr_at_fppi, dr_fppi_curve, evaluate_ethz  # noqa: E402
from shapetree.detection._detect import frame_term  # noqa: E402
from shapetree.detection._ethz_eval import ETHZ_CLASSES, _gt_boxes, _images, ethz_root  # noqa: E402
from shapetree.detection._model import load_model  # noqa: E402
from shapetree.geometry import outline_dif  # noqa: E402

FRAME = (0.0, 0.025, 0.05, 0.075, 0.1, 0.15, 0.2)
CHECK = (0.0, 0.05, 0.1, 0.2, 0.4, 0.8)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--data", default=os.environ.get("SHAPETREE_DATA", str(REPO.parent / "shared" / "datasets"))
    )
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument(
        "--cache-dir",
        default=None,
        help="default: $SHAPETREE_CACHE/ethz_detect (else ~/.cache/shapetree/ethz_detect)",
    )
    ap.add_argument("--json", default=str(RESULTS / "ethz_ranking.json"))
    args = ap.parse_args()
    t0 = time.perf_counter()
    params = DetectParams(frame_prior=0.0, outline_check=0.0, context_check=0.0)
    res = evaluate_ethz(
        args.data, cache_dir=args.cache_dir, params=params, k=5, workers=args.workers
    )
    root = ethz_root(args.data)
    cache = Path(res["cache_dir"])
    imgs = _images(root)
    hw = {}
    for folder, stem in imgs:
        with open_image(root / folder / f"{stem}.jpg") as im:
            w, h = im.size
        hw[(folder, stem)] = (h, w)
    model_pts = {
        c: load_model(root / "models" / f"{ETHZ_CLASSES[c][1]}.tif", m=params.m).points
        for c in ETHZ_CLASSES
    }
    cand: dict[str, list[tuple[str, float, float, float, list]]] = {}
    gts: dict[str, dict[str, np.ndarray]] = {}
    for cls in ETHZ_CLASSES:
        cand[cls], gts[cls] = [], {}
        for folder, stem in imgs:
            key = f"{folder}/{stem}"
            gts[cls][key] = _gt_boxes(root, folder, stem, cls)
            doc = json.loads((cache / cls / f"{folder}__{stem}.json").read_text())
            for d in doc["detections"]:
                d2 = outline_dif(model_pts[cls], d["image_points"])
                lr = frame_term(d["bbox"], hw[(folder, stem)])
                cand[cls].append((key, d["score"], d2, lr, d["bbox"]))
    table: dict[tuple[float, float], dict[str, float]] = {}
    for c in CHECK:
        for f in FRAME:
            row = {}
            for cls in ETHZ_CLASSES:
                dets = [(k, s - c * d2 + f * lr, b) for k, s, d2, lr, b in cand[cls]]
                fppi, dr, _ = dr_fppi_curve(dets, gts[cls], len(imgs), 0.2)
                row[cls] = round(dr_at_fppi(fppi, dr, 0.4), 4)
            row["mean"] = round(float(np.mean([row[x] for x in ETHZ_CLASSES])), 4)
            table[(c, f)] = row
    loco = {}
    for cls in ETHZ_CLASSES:
        others = [x for x in ETHZ_CLASSES if x != cls]
        best = max(table, key=lambda cf: (np.mean([table[cf][x] for x in others]), -sum(cf)))
        loco[cls] = {"outline_check": best[0], "frame_prior": best[1], "dr": table[best][cls]}
    loco_mean = round(float(np.mean([v["dr"] for v in loco.values()])), 4)
    print("mean DR at 0.4 FPPI (20% rule); rows outline_check, columns frame_prior")
    print("        " + "".join(f"{f:>8.3f}" for f in FRAME))
    for c in CHECK:
        print(f"{c:>6.2f}  " + "".join(f"{table[(c, f)]['mean']:>8.3f}" for f in FRAME))
    dflt = DetectParams()
    row = table[(dflt.outline_check, dflt.frame_prior)]
    print(
        f"defaults (outline_check {dflt.outline_check}, frame_prior {dflt.frame_prior}): "
        + ", ".join(f"{x} {row[x]:.3f}" for x in [*ETHZ_CLASSES, "mean"])
    )
    print(
        "leave one class out: "
        + "; ".join(
            f"{x} (c={v['outline_check']}, f={v['frame_prior']}) {v['dr']:.3f}"
            for x, v in loco.items()
        )
    )
    print(f"leave-one-class-out mean DR@0.4 FPPI (20% rule): {loco_mean:.3f}")
    out = {
        "measure": "DR at 0.4 FPPI, 20% rule, k=5 detections per image",
        "by_weights": [{"outline_check": c, "frame_prior": f, **r} for (c, f), r in table.items()],
        "defaults": {"outline_check": dflt.outline_check, "frame_prior": dflt.frame_prior, **row},
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
