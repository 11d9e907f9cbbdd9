"""Would mirror-invariant detection help on ETHZ? (issue 14, item 1; tried, not adopted)

The matcher of §3 is invariant to similarity transforms, not to reflections, and the
detection pipeline runs the model as drawn. Mugs (handle left or right), swans and
giraffes (facing left or right) appear both ways in ETHZ, and some correct mug detections
place the model turned by about 90 degrees, where the context term (not rotation-
invariant) scores them low. This script runs each class's **mirrored** model (``x -> -x``)
on every image with the default :class:`~shapetree.detection.DetectParams` and Pb edges,
then scores three rankings with the evaluation's scorer:

* ``as_drawn``: the committed run (``results/ethz.json``'s detections);
* ``mirrored_only``: the mirrored model's detections alone;
* ``both``: per image, the two lists merged by ranking score, non-maximum suppression at
  ``nms_iou`` and the best ``k`` kept: what a ``mirror`` option would give.

and the first and last again ranked by the shipped collection re-scorer
(``as_drawn_rescored``, ``both_rescored``; each detection's terms taken with the model it
was found with, the colour agreement over the merged lists).

Run::

    SHAPETREE_DATA=/work/shared/datasets python3 benchmarks/ethz_mirror.py

The mirrored detections are cached per image (``--mirrored DIR``), so a rerun only scores.
Writes ``benchmarks/results/ethz_mirror.json`` and prints a table.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from multiprocessing import Pool
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, machine, write_json  # noqa: E402

from shapetree._atomic import atomic_write_bytes  # noqa: E402
from shapetree.detection import DetectParams, detect_detailed  # noqa: E402
from shapetree.detection._detect import _box_iou  # noqa: E402
from shapetree.detection._ethz_eval import (  # noqa: E402
    ETHZ_CLASSES,
    _gt_boxes,
    _images,
    dr_at_fppi,
    dr_fppi_curve,
    ethz_root,
)
from shapetree.detection._model import load_model, make_model  # noqa: E402

_MODELS: dict = {}


def mirrored_model(root: Path, cls: str, m: int):
    """The class model drawn the other way round (``x -> -x``, order reversed so the
    outline keeps its orientation)."""
    if cls not in _MODELS:
        mdl = load_model(root / "models" / f"{ETHZ_CLASSES[cls][1]}.tif", m=m)
        c = mdl.curve.copy()
        c[:, 0] = -c[:, 0]
        _MODELS[cls] = make_model(c[::-1], closed=mdl.closed, m=m, name=f"{mdl.name}-mirrored")
    return _MODELS[cls]


def _run(task: tuple[str, str, str, str, str, int]) -> int:
    """Detect with the mirrored model in one image (cached); 1 when computed now."""
    root_s, out_s, cls, folder, stem, k = task
    f = Path(out_s) / cls / f"{folder}__{stem}.json"
    if f.exists():
        return 0
    root, p = Path(root_s), DetectParams()
    run = detect_detailed(
        mirrored_model(root, cls, p.m), None, edges=root / folder / f"{stem}_edges.tif", k=k
    )
    doc = {
        "detections": [
            {
                "score": d.score,
                "bbox": list(d.bbox),
                "coverage": d.coverage,
                "image_points": d.image_points.tolist(),
            }
            for d in run.detections
        ]
    }
    f.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(f, json.dumps(doc).encode())
    return 1


def _load(folder: Path, cls: str, fo: str, st: str) -> list[dict]:
    return json.loads((folder / cls / f"{fo}__{st}.json").read_text())["detections"]


def _merged(lists: list[list[dict]], k: int, nms_iou: float) -> list[dict]:
    kept: list[dict] = []
    for d in sorted((d for ds in lists for d in ds), key=lambda d: -d["score"]):
        if kept and np.any(
            _box_iou(np.asarray(d["bbox"]), np.array([x["bbox"] for x in kept])) > nms_iou
        ):
            continue
        kept.append(d)
        if len(kept) >= k:
            break
    return kept


def _rescored(root: Path, imgs: list, drawn: Path, mirrored: Path, k: int) -> dict:
    """DR at 0.4 FPPI (20%, PASCAL) per class of ``as_drawn`` and ``both`` ranked by the
    shipped collection re-scorer, each detection's terms taken with the model it was
    found with (the mirrored one for a mirrored detection)."""
    from tqdm import tqdm

    from shapetree.detection import (
        appearance_agreement,
        colour_bins,
        detection_terms,
        interior_histogram,
        load_image,
        rescore_collection,
    )

    p = DetectParams()
    models = {
        c: (
            load_model(root / "models" / f"{ETHZ_CLASSES[c][1]}.tif", m=p.m).points,
            mirrored_model(root, c, p.m).points,
        )
        for c in ETHZ_CLASSES
    }
    modes = ("as_drawn", "both")
    per: dict = {(c, m): ([], [], [], []) for c in ETHZ_CLASSES for m in modes}
    for fo, st in tqdm(imgs, desc="re-scorer terms", unit="img"):
        key = f"{fo}/{st}"
        bins = colour_bins(load_image(root / fo / f"{st}.jpg"))
        for c in ETHZ_CLASSES:
            a = [dict(d, mirrored=False) for d in _load(drawn, c, fo, st)]
            b = [dict(d, mirrored=True) for d in _load(mirrored, c, fo, st)]
            for mode, lists in (("as_drawn", [a]), ("both", [a, b])):
                keys, dets, hists, terms = per[(c, mode)]
                for d in _merged(lists, k, p.nms_iou):
                    keys.append(key)
                    dets.append(d)
                    hists.append(interior_histogram(bins, d["image_points"]))
                    pts, box = models[c][int(d["mirrored"])], d["bbox"]
                    terms.append(
                        detection_terms(pts, d["image_points"], box, d["coverage"], bins.shape)
                    )
    res: dict = {}
    for (c, mode), (keys, dets, hists, terms) in per.items():
        scores = np.array([d["score"] for d in dets])
        table = {t: np.array([r[t] for r in terms]) for t in terms[0]}
        table["appearance"] = appearance_agreement(keys, scores, np.array(hists), 10)
        cs, _ = rescore_collection(keys, scores, table, p.context_check)
        gts = {f"{fo}/{st}": _gt_boxes(root, fo, st, c) for fo, st in imgs}
        ranked = [(kk, float(v), d["bbox"]) for kk, v, d in zip(keys, cs, dets, strict=True)]
        pair = []
        for thr in (0.2, 0.5):
            fppi, dr, _ = dr_fppi_curve(ranked, gts, len(imgs), thr)
            pair.append(round(dr_at_fppi(fppi, dr, 0.4), 4))
        res.setdefault(f"{mode}_rescored", {})[c] = pair
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=os.environ.get("SHAPETREE_DATA"))
    ap.add_argument("--mirrored", default=str(Path.home() / ".cache/shapetree/ethz_mirrored"))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", default=str(RESULTS / "ethz_mirror.json"))
    args = ap.parse_args()
    t0 = time.perf_counter()
    root = ethz_root(args.data)
    committed = json.loads((RESULTS / "ethz.json").read_text())
    drawn, k = Path(committed["cache_dir"]), int(committed["k"])
    imgs = _images(root)
    tasks = [(str(root), args.mirrored, c, fo, st, k) for c in ETHZ_CLASSES for fo, st in imgs]
    with Pool(args.workers) as pool:
        computed = sum(pool.imap_unordered(_run, tasks, chunksize=4))
    nms = DetectParams().nms_iou
    res: dict[str, dict] = {}
    for cls in ETHZ_CLASSES:
        gts = {f"{fo}/{st}": _gt_boxes(root, fo, st, cls) for fo, st in imgs}
        for mode in ("as_drawn", "mirrored_only", "both"):
            dets = []
            for fo, st in imgs:
                lists = []
                if mode != "mirrored_only":
                    lists.append(_load(drawn, cls, fo, st))
                if mode != "as_drawn":
                    lists.append(_load(Path(args.mirrored), cls, fo, st))
                dets += [(f"{fo}/{st}", d["score"], d["bbox"]) for d in _merged(lists, k, nms)]
            pair = []
            for thr in (0.2, 0.5):
                fppi, dr, _ = dr_fppi_curve(dets, gts, len(imgs), thr)
                pair.append(round(dr_at_fppi(fppi, dr, 0.4), 4))
            res.setdefault(mode, {})[cls] = pair
    res.update(_rescored(root, imgs, drawn, Path(args.mirrored), k))
    out = {
        "command": "python3 benchmarks/ethz_mirror.py " + " ".join(sys.argv[1:]),
        "protocol": __doc__.split("\n\n")[1].replace("\n", " "),
        "as_drawn_detections": str(drawn),
        "mirrored_detections": args.mirrored,
        "mirrored_computed_this_run": f"{computed} of {len(tasks)} (class, image) runs; the "
        "others were read from the cache, written by an earlier run of the same function",
        "measure": "mean DR at 0.4 FPPI, 20% rule and PASCAL, k = 5 per image",
    }
    print(
        f"{'ranking':14s} "
        + " ".join(f"{c[:8]:>13s}" for c in ETHZ_CLASSES)
        + "   mean 20% / PASCAL"
    )
    for mode, r in res.items():
        m20 = round(float(np.mean([v[0] for v in r.values()])), 4)
        m50 = round(float(np.mean([v[1] for v in r.values()])), 4)
        out[mode] = {"per_class": r, "mean_overlap_20": m20, "mean_overlap_50": m50}
        cells = " ".join(f"{v[0]:.3f}/{v[1]:.3f}" for v in r.values())
        print(f"{mode:14s} {cells}   {m20:.4f} / {m50:.4f}")
    out["seconds"] = round(time.perf_counter() - t0, 1)
    out["machine"] = machine()
    write_json(Path(args.json), out)
    print(f"json: {args.json}")


if __name__ == "__main__":
    main()
