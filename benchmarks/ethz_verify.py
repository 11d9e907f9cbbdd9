"""ETHZ: does bounded edge evidence re-score kept detections better across images? (issue 14.1)

Usage::

    python3 benchmarks/ethz_verify.py --edges own     # after eval_ethz.py --edges own
    python3 benchmarks/ethz_verify.py --edges pb

Reads the cached detections of ``evaluate_ethz`` (default parameters, ``k=5``; nothing is
detected again), recomputes each image's edge map once (the Pb map, or the own edge map),
and adds to each kept detection two bounded verification terms:

- ``support``: the geometric mean over the model's samples of the edge strength at the
  place the detection puts them (the maximum within 2 px), each floored at ``FLOOR`` (a
  fixed penalty for a missing part), in ``[FLOOR, 1]``;
- ``clutter``: the share of the box's edge pixels (strength > 0.15) farther than 4 px from
  the placed outline (edges the hypothesis does not explain), in ``[0, 1]``;
- ``shape``: the §3 closed-curve shape-tree distance (``match(model, placed outline)``,
  the general preset) between the model and the outline the detection places in the image.

It re-scores ``score + a * log(support) - b * clutter - c * shape`` over a grid of
``(a, b, c)`` and reports
the mean DR at 0.4 FPPI (20% rule and PASCAL) for each pair, and the leave-one-class-out
estimate (the pair picked on four classes, scored on the fifth), which is the headline.
Writes ``benchmarks/results/ethz_verify_<edges>.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy import ndimage

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import RESULTS, machine, write_json  # noqa: E402

from shapetree.detection import (  # noqa: E402
    DetectParams,
    dr_at_fppi,
    dr_fppi_curve,
    edge_map,
    load_edges,
    load_image,
)
from shapetree.detection._ethz_eval import (  # noqa: E402
    ETHZ_CLASSES,
    _gt_boxes,
    _images,
    _params_key,
    default_cache_dir,
    ethz_root,
)

FLOOR = 0.05
A_GRID = (0.0, 0.025, 0.05, 0.1, 0.2, 0.4)
B_GRID = (0.0, 0.1, 0.2, 0.4, 0.8)
C_GRID = (0.0, 0.1, 0.2, 0.4, 0.8)


def _evidence(e: np.ndarray, pts: np.ndarray, box: list[float]) -> tuple[float, float]:
    """(support, clutter) of one detection on the edge map ``e``."""
    h, w = e.shape
    near = ndimage.maximum_filter(e, size=5)
    c = np.clip(np.rint(pts[:, 0]).astype(int), 0, w - 1)
    r = np.clip(np.rint(pts[:, 1]).astype(int), 0, h - 1)
    inside = (pts[:, 0] >= 0) & (pts[:, 0] < w) & (pts[:, 1] >= 0) & (pts[:, 1] < h)
    s = np.where(inside, near[r, c], 0.0)
    support = float(np.exp(np.mean(np.log(np.maximum(s, FLOOR)))))
    x1, y1, x2, y2 = (int(round(v)) for v in box)
    x1, y1 = max(x1, 0), max(y1, 0)
    x2, y2 = min(x2, w - 1), min(y2, h - 1)
    if x2 <= x1 or y2 <= y1:
        return support, 1.0
    sub = e[y1 : y2 + 1, x1 : x2 + 1] > 0.15
    if not sub.any():
        return support, 0.0
    mask = np.zeros_like(sub)
    ring = np.vstack([pts, pts[:1]])
    for a, b in zip(ring[:-1], ring[1:], strict=True):
        n = int(np.ceil(np.hypot(*(b - a)))) + 1
        xs = np.rint(np.linspace(a[0], b[0], n)).astype(int) - x1
        ys = np.rint(np.linspace(a[1], b[1], n)).astype(int) - y1
        ok = (xs >= 0) & (xs < sub.shape[1]) & (ys >= 0) & (ys < sub.shape[0])
        mask[ys[ok], xs[ok]] = True
    far = ndimage.distance_transform_edt(~mask) > 4.0
    return support, float((sub & far).sum() / sub.sum())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--data", default=os.environ.get("SHAPETREE_DATA", str(REPO.parent / "shared" / "datasets"))
    )
    ap.add_argument("--edges", choices=("pb", "own"), default="own")
    ap.add_argument(
        "--detections",
        default=None,
        help="the cached detections (default: the cache_dir recorded in results/ethz.json "
        "or ethz_own.json, i.e. the run whose numbers are committed)",
    )
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    t0 = time.perf_counter()
    root = ethz_root(args.data)
    params = DetectParams()
    if args.detections:
        cache = Path(args.detections)
    else:
        res = RESULTS / ("ethz.json" if args.edges == "pb" else "ethz_own.json")
        cache = Path(json.loads(res.read_text())["cache_dir"]) if res.is_file() else None
        if cache is None or not cache.is_dir():
            cache = default_cache_dir() / _params_key(params, 5, args.edges)
    imgs = _images(root)
    from shapetree.detection import load_model
    from shapetree.matching import match

    models = {
        c: load_model(root / "models" / f"{ETHZ_CLASSES[c][1]}.tif", m=params.m).points
        for c in ETHZ_CLASSES
    }
    cand: dict[str, list] = {c: [] for c in ETHZ_CLASSES}
    gts: dict[str, dict[str, np.ndarray]] = {c: {} for c in ETHZ_CLASSES}
    from tqdm import tqdm

    store = Path(tempfile.gettempdir()) / f"ethz_verify_{args.edges}_{cache.name}.json"
    if store.is_file():  # the evidence of this cache, computed before
        saved = json.loads(store.read_text())
        cand, gts = (
            saved["cand"],
            {c: {k: np.asarray(v) for k, v in g.items()} for c, g in saved["gts"].items()},
        )
        imgs_todo = []
    else:
        imgs_todo = imgs
    for folder, stem in tqdm(imgs_todo, desc="evidence", unit="img"):
        key = f"{folder}/{stem}"
        if args.edges == "pb":
            e = load_edges(root / folder / f"{stem}_edges.tif")
        else:
            e = edge_map(load_image(root / folder / f"{stem}.jpg"), method="own")
        for cls in ETHZ_CLASSES:
            gts[cls][key] = _gt_boxes(root, folder, stem, cls)
            path = cache / cls / f"{folder}__{stem}.json"
            if not path.is_file():
                raise SystemExit(f"missing cached detection {path}: run eval_ethz.py first")
            for d in json.loads(path.read_text())["detections"]:
                pts = np.asarray(d["image_points"])
                sup, clut = _evidence(e, pts, d["bbox"])
                try:
                    shape = float(match(models[cls], pts, closed=True).cost)
                except ValueError:  # a degenerate placed outline
                    shape = 1.0
                cand[cls].append((key, d["score"], np.log(sup), clut, shape, d["bbox"]))
    if imgs_todo:
        gts_json = {c: {k: v.tolist() for k, v in g.items()} for c, g in gts.items()}
        store.write_text(json.dumps({"cand": cand, "gts": gts_json}))
    table: dict = {}
    for a in A_GRID:
        for b in B_GRID:
            for c in C_GRID:
                row: dict[str, dict[str, float]] = {"overlap_20": {}, "overlap_50": {}}
                for cls in ETHZ_CLASSES:
                    dets = [
                        (k, s + a * ls - b * cl - c * sh, bx) for k, s, ls, cl, sh, bx in cand[cls]
                    ]
                    for thr, name in ((0.2, "overlap_20"), (0.5, "overlap_50")):
                        fppi, dr, _ = dr_fppi_curve(dets, gts[cls], len(imgs), thr)
                        row[name][cls] = round(dr_at_fppi(fppi, dr, 0.4), 4)
                for name in row:
                    row[name]["mean"] = round(
                        float(np.mean([row[name][x] for x in ETHZ_CLASSES])), 4
                    )
                table[(a, b, c)] = row
    loco = {}
    for cls in ETHZ_CLASSES:
        others = [x for x in ETHZ_CLASSES if x != cls]
        best = max(
            table,
            key=lambda ab: (np.mean([table[ab]["overlap_20"][x] for x in others]), -sum(ab)),
        )
        loco[cls] = {
            "a": best[0],
            "b": best[1],
            "c": best[2],
            "dr_20": table[best]["overlap_20"][cls],
            "dr_50": table[best]["overlap_50"][cls],
        }
    loco_20 = round(float(np.mean([v["dr_20"] for v in loco.values()])), 4)
    loco_50 = round(float(np.mean([v["dr_50"] for v in loco.values()])), 4)
    plain = table[(0.0, 0.0, 0.0)]
    for c in C_GRID:
        print(f"edges {args.edges}, c = {c}: mean DR at 0.4 FPPI (20% rule); rows a, columns b")
        print("        " + "".join(f"{b:>8.3f}" for b in B_GRID))
        for a in A_GRID:
            vals = "".join(f"{table[(a, b, c)]['overlap_20']['mean']:>8.3f}" for b in B_GRID)
            print(f"{a:>6.3f}  " + vals)
    top = max(table, key=lambda k: table[k]["overlap_20"]["mean"])
    print("best on all five classes (optimistic, not the headline):", top, json.dumps(table[top]))
    print("without the terms:", json.dumps(plain))
    print("leave one class out:", json.dumps(loco))
    print(f"leave-one-class-out mean DR@0.4 FPPI: 20% rule {loco_20:.3f}, PASCAL {loco_50:.3f}")
    out = {
        "measure": "DR at 0.4 FPPI, k=5 detections per image, re-scored kept detections",
        "edges": args.edges,
        "score": "score + a * log(support) - b * clutter - c * shape",
        "floor": FLOOR,
        "without_terms": plain,
        "by_weights": [{"a": a, "b": b, "c": c, **r} for (a, b, c), r in table.items()],
        "leave_one_class_out": loco,
        "leave_one_class_out_mean": {"overlap_20": loco_20, "overlap_50": loco_50},
        "cache_dir": str(cache),
        "seconds": round(time.perf_counter() - t0, 1),
        "machine": machine(),
        "command": "python3 benchmarks/ethz_verify.py " + " ".join(sys.argv[1:]),
    }
    write_json(Path(args.json or RESULTS / f"ethz_verify_{args.edges}.json"), out)
    print("json:", args.json or RESULTS / f"ethz_verify_{args.edges}.json")


if __name__ == "__main__":
    main()
