"""ETHZ: candidate collection terms beside the shipped re-scorer's, scored held out.

The shipped collection re-scorer (``shapetree.detection.rescore_collection``) weighs eight
terms of each detection. Two of them look across the collection or the image (the colour
agreement with the most confident detections of the other photos; the margin and lead
within the photo). This script asks whether more of that kind helps, measured the same
way as ``ethz_appearance.py`` (a logistic regression on the standardised terms, its L2
penalty chosen by an inner leave-one-class-out, fitted on four classes and scored on the
fifth; mean DR at 0.4 FPPI):

``shape_agreement``  mean shape-context agreement of a detection's placed outline with the
                     placed outlines of the reference set (the 10 best image-best
                     detections by score, less any of its own photo). Every placement is
                     of the same model samples, so row ``i`` of one corresponds to row
                     ``i`` of the other: this asks whether it has the *layout the object
                     takes in these photos*, beside the context term's layout of the
                     drawing.
``collection_dif``   the same with the squared Procrustes distance (``outline_dif``).
``appearance_2``     the colour agreement with the reference set chosen by the shipped
                     re-scorer's collection score instead of the score (one more round).

The shipped eight are computed by the library's own ``collection_table``, so the reference
row of this script is the shipped rule (its held-out figure should be the 0.8229 of
``ethz_appearance.py``'s ``logistic_product_terms`` on the same Pb detections).

Usage::

    python3 benchmarks/ethz_collection_terms.py --edges pb --detections CACHE_DIR

Writes ``benchmarks/results/ethz_collection_terms_<edges>.json`` (or ``--json``).
"""

from __future__ import annotations

import json
import sys
import time
from multiprocessing import Pool
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import ethz_verify as V  # noqa: E402
from _common import RESULTS, ethz_parser, machine, write_json  # noqa: E402

from shapetree.detection import (  # noqa: E402
    DetectParams,
    colour_bins,
    context_agreement,
    interior_histogram,
    load_image,
    load_model,
)
from shapetree.detection._appearance import appearance_agreement  # noqa: E402
from shapetree.detection._ethz_eval import (  # noqa: E402
    ETHZ_CLASSES,
    _gt_boxes,
    _images,
    _iou,
    ethz_root,
)
from shapetree.detection._rescore import collection_table  # noqa: E402
from shapetree.geometry import outline_dif  # noqa: E402

SHIPPED = ("base", "context", "outline_dif", "frame", "coverage", "margin", "lead", "appearance")
NEW_TERMS = ("shape_agreement", "collection_dif", "appearance_2")
M_REF = 10
_STATE: dict = {}


def _init(root: str, cache: str) -> None:
    _STATE.update(root=Path(root), cache=Path(cache))


def _image(item: tuple[str, str]) -> tuple[str, tuple[int, int], dict]:
    """One image: its shape and, per class, its detections with their colour histograms."""
    folder, stem = item
    root, cache = _STATE["root"], _STATE["cache"]
    bins = colour_bins(load_image(root / folder / f"{stem}.jpg"))
    out = {}
    for cls in ETHZ_CLASSES:
        doc = json.loads((cache / cls / f"{folder}__{stem}.json").read_text())
        gt = _gt_boxes(root, folder, stem, cls)
        dets = []
        for d in doc["detections"]:
            iou = float(_iou(np.asarray(d["bbox"]), gt).max()) if len(gt) else 0.0
            h = interior_histogram(bins, d["image_points"])
            dets.append(dict(d, iou=iou, hist=h))
        out[cls] = dets
    return f"{folder}/{stem}", bins.shape[:2], out


def _reference(keys: list[str], s: np.ndarray) -> list[int]:
    best: dict[str, int] = {}
    for i, k in enumerate(keys):
        if k not in best or s[i] > s[best[k]]:
            best[k] = i
    return sorted(best.values(), key=lambda i: -s[i])[: M_REF + 1]


def _against_reference(keys: list[str], s: np.ndarray, pts: list[np.ndarray], fn) -> np.ndarray:
    ref = _reference(keys, s)
    out = np.zeros(len(keys))
    for i, k in enumerate(keys):
        others = [r for r in ref if keys[r] != k][:M_REF]
        out[i] = float(np.mean([fn(pts[i], pts[r]) for r in others])) if others else 0.0
    return out


def _safe_context(a: np.ndarray, b: np.ndarray) -> float:
    try:
        return context_agreement(a, b)
    except Exception:  # a collapsed placement
        return 0.0


def rows_for(
    root: Path,
    cache: Path,
    imgs: list,
    workers: int,
    image_fn=None,
    init=None,
    init_args: tuple = (),
    extra: tuple[str, ...] = (),
    params: DetectParams | None = None,
) -> list[dict]:
    """Every kept detection of every class with the shipped terms and the new ones.

    ``image_fn`` (default :func:`_image`) reads one image's detections in a worker that
    ``init(root, cache, *init_args)`` (default :func:`_init`) set up; the detection keys
    named in ``extra`` are copied into the rows (another script's terms). ``params``
    (default ``DetectParams()``) must be those of the run: its ``m`` samples the model
    that the records' image points belong to."""
    from tqdm import tqdm

    per_image: dict = {}
    shapes: dict = {}
    image_fn, init = image_fn or _image, init or _init
    with Pool(workers, initializer=init, initargs=(str(root), str(cache), *init_args)) as pool:
        for key, shape, dets in tqdm(pool.imap(image_fn, imgs), total=len(imgs), unit="img"):
            per_image[key], shapes[key] = dets, shape
    params = DetectParams() if params is None else params
    rows: list[dict] = []
    for cls, (_folder, model_file) in ETHZ_CLASSES.items():
        model = load_model(root / "models" / f"{model_file}.tif", m=params.m).points
        keys, dets = [], []
        for f, s in imgs:
            for d in per_image[f"{f}/{s}"][cls]:
                keys.append(f"{f}/{s}")
                dets.append(d)
        hists = np.array([d["hist"] for d in dets])
        cs, table = collection_table(keys, dets, model, shapes, hists, params)
        score = np.array([d["score"] for d in dets])
        pts = [np.asarray(d["image_points"], float) for d in dets]
        new = {
            "shape_agreement": _against_reference(keys, score, pts, _safe_context),
            "collection_dif": _against_reference(keys, score, pts, outline_dif),
            "appearance_2": appearance_agreement(keys, cs, hists, M_REF),
        }
        for i, (k, d) in enumerate(zip(keys, dets, strict=True)):
            row = {"cls": cls, "key": k, "bbox": d["bbox"], "iou": d["iou"]}
            row.update({t: float(table[t][i]) for t in SHIPPED})
            row.update({t: float(v[i]) for t, v in new.items()})
            row.update({t: float(d[t]) for t in extra})
            row["collection_score"] = float(cs[i])
            rows.append(row)
    return rows


def _aucs(sc: V._Scorer, term: str, label: np.ndarray) -> dict:
    v = sc.col(term)
    return {
        c: round(V._auc(v[(sc.cls == c) & label], v[(sc.cls == c) & ~label]), 3)
        for c in ETHZ_CLASSES
    }


def main() -> None:
    ap = ethz_parser(__doc__)
    args = ap.parse_args()
    t0 = time.perf_counter()
    root = ethz_root(args.data)
    imgs = _images(root)
    rows = rows_for(root, Path(args.detections), imgs, args.workers)
    sc = V._Scorer(root, rows, len(imgs))
    label = sc.col("iou") >= 0.2
    shipped = {c: sc.dr(c, sc.col("collection_score")) for c in ETHZ_CLASSES}
    out: dict = {
        "protocol": __doc__,
        "edges": args.edges,
        "detections": args.detections,
        "shipped_in_view": {
            "note": "ranked by the shipped collection score (weights fitted on the Pb run)",
            "overlap_20": V._with_mean(shipped, 0),
            "overlap_50": V._with_mean(shipped, 1),
        },
        "auc": {t: _aucs(sc, t, label) for t in NEW_TERMS},
    }
    sets = {"shipped terms": SHIPPED}
    for t in NEW_TERMS:
        sets[f"shipped + {t}"] = SHIPPED + (t,)
    sets["shipped + all three"] = SHIPPED + NEW_TERMS
    out["logistic"] = {}
    for name, terms in sets.items():
        x = np.stack([sc.col(t) for t in terms], 1)
        res = V._logistic_nested(sc, x, label)
        out["logistic"][name] = {"terms": list(terms), **res}
        held = res["logistic_nested_l2"]
        print(
            f"{name:28s} held out {held['loco_overlap_20']['mean']:.4f} / "
            f"{held['loco_overlap_50']['mean']:.4f}  in sample "
            f"{res['logistic_in_sample']['overlap_20']['mean']:.4f}  {held['loco_overlap_20']}"
        )
    out["seconds"] = round(time.perf_counter() - t0, 1)
    out["machine"] = machine()
    out["command"] = "python3 benchmarks/ethz_collection_terms.py " + " ".join(sys.argv[1:])
    write_json(
        Path(args.json) if args.json else RESULTS / f"ethz_collection_terms_{args.edges}.json", out
    )


if __name__ == "__main__":
    main()
