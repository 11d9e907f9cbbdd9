"""ETHZ: does the look of a model's confident detections help rank the rest? (issue 14.1)

Every term of ``ethz_verify.py`` judges one detection alone, so a stitched outline on a
tree trunk and one on a giraffe can score alike. Across a collection of photos searched
with one model, though, the detections the detector is surest of are mostly the object,
and the object looks alike from photo to photo (a giraffe's coat, a swan's white). This
script measures that, as an *appearance consistency* term of each kept detection:

1. Inside the outline the detection places in the image (farther than 2 px from it):
   the Lab colour histogram (8 x 8 x 8 bins, as ``ethz_verify``'s ``figure`` term) and a
   texture histogram (uniform local binary patterns of the grey image, 8 neighbours at
   radius 1 and at radius 3, 10 bins each; :func:`skimage.feature.local_binary_pattern`).
2. The *reference set* of a model: the best detection of each image, by the score the
   detector ranks with (the shipped default, context term included), the ``M_REF = 10``
   best of them over the collection. No ground truth is used: which detections are
   confident is the detector's own call.
3. ``appearance``: the mean over the reference set (less any member from the
   detection's own image) of the histogram intersection of the two detections, colour
   and texture averaged, in ``[0, 1]``; ``appearance_colour`` and
   ``appearance_texture`` are the two halves alone.

The terms are then scored exactly as ``ethz_verify.py`` scores its own (weights chosen
leave one class out; the term or pair chosen inside each fold too), beside them.

The colour half is the detector's collection stage
(:func:`shapetree.detection.collection_scores`, ``DetectParams.appearance_check``), and
this script uses the same functions for it (``colour_bins``, ``interior_mask``); the
reference set is made the same way. Alone it is an option (it wins on the Pb detections,
not with the own edge map); the shipped collection re-scorer is ``logistic_product_terms``
below, fitted on all Pb detections (``ethz_rescorer_cross.py``; README, *The collection
re-scorer*).

**What it is, honestly.** A transductive re-ranking: the term of a giraffe detection
uses the other giraffe-model detections of the same 255 images, but none of their
labels. Its weight is chosen leave one class out like every other term's; ``M_REF`` and
the descriptors were fixed before any run and not tuned.

Usage (after ``ethz_verify.py --rows R``, which measures the other terms)::

    python3 benchmarks/ethz_appearance.py --edges pb --detections DIR --rows R \
        --context-check 0.15 --without-context

Writes ``benchmarks/results/ethz_appearance_<edges>.json``.
"""

from __future__ import annotations

import json
import pickle
import sys
import time
from multiprocessing import Pool
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import ethz_verify as V  # noqa: E402
from _common import RESULTS, ethz_parser, machine, write_json  # noqa: E402

from shapetree.detection import load_image  # noqa: E402
from shapetree.detection._appearance import colour_bins, histogram, interior_mask  # noqa: E402
from shapetree.detection._ethz_eval import ETHZ_CLASSES, _images, ethz_root  # noqa: E402

#: size of a model's reference set (its most confident detections, one per image)
M_REF = 10
NEW_TERMS = ("appearance", "appearance_colour", "appearance_texture")
#: the terms the detector itself has for every kept detection (the parts of its score, the
#: shape context, the matched share, the margin to the image's best and the best one's
#: lead) and the colour agreement of its collection stage: a logistic re-scorer on these
#: alone could run inside the detector, one on all 21 terms could not
PRODUCT_TERMS = ("context", "od", "frame", "coverage", "margin", "lead", "appearance_colour")
_STATE: dict = {}


def _texture_codes(img: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    from skimage.color import rgb2gray
    from skimage.feature import local_binary_pattern

    g = rgb2gray(img[..., :3]) if img.ndim == 3 else img
    g = np.rint(np.clip(g, 0, 1) * 255).astype(np.uint8)
    return tuple(  # type: ignore[return-value]
        local_binary_pattern(g, 8, r, method="uniform").astype(int) for r in (1, 3)
    )


def _image_hists(item: tuple[str, str]) -> dict[tuple[str, str, int], tuple]:
    """``(cls, key, rank) -> (colour histogram, texture histogram)`` of one image."""
    folder, stem = item
    root, cache = _STATE["root"], _STATE["cache"]
    img = load_image(root / folder / f"{stem}.jpg")
    q = colour_bins(img)
    t1, t3 = _texture_codes(img)
    out = {}
    key = f"{folder}/{stem}"
    for cls in ETHZ_CLASSES:
        dets = json.loads((cache / cls / f"{folder}__{stem}.json").read_text())["detections"]
        for rank, d in enumerate(dets):
            core = interior_mask(q.shape, d["image_points"])
            ht = np.concatenate([np.bincount(t[core], minlength=10)[:10] for t in (t1, t3)])
            ht = ht / max(ht.sum() / 2, 1.0)  # each half sums to 1
            out[(cls, key, rank)] = (histogram(q, core), ht / 2)
    return out


def _init(root: str, cache: str) -> None:
    _STATE.update(root=Path(root), cache=Path(cache))


def add_appearance(rows: list[dict], hists: dict, m_ref: int = M_REF) -> None:
    """Add the three appearance terms to ``rows`` (in place), reference sets by ``score``."""
    rank: dict[tuple[str, str], int] = {}
    for r in rows:
        k = (r["cls"], r["key"])
        r["_rank"] = rank.get(k, 0)
        rank[k] = r["_rank"] + 1
    for cls in ETHZ_CLASSES:
        mine = [r for r in rows if r["cls"] == cls]
        best: dict[str, dict] = {}
        for r in mine:
            if r["key"] not in best or r["score"] > best[r["key"]]["score"]:
                best[r["key"]] = r
        ref = sorted(best.values(), key=lambda r: -r["score"])[: m_ref + 1]
        ref_h = [(r["key"], hists[(cls, r["key"], r["_rank"])]) for r in ref]
        for r in mine:
            hc, ht = hists[(cls, r["key"], r["_rank"])]
            others = [hr for k, hr in ref_h if k != r["key"]][:m_ref]
            ic = np.mean([np.minimum(hc, o[0]).sum() for o in others])
            it = np.mean([np.minimum(ht, o[1]).sum() for o in others])
            r["appearance_colour"], r["appearance_texture"] = float(ic), float(it)
            r["appearance"] = float(0.5 * (ic + it))
    for r in rows:
        del r["_rank"]


def rows_with_appearance(
    root: Path, imgs: list, detections: str | Path, rows_file: str | Path, workers: int
) -> list[dict]:
    """The terms pickle ``ethz_verify.py --rows`` wrote, with the three appearance terms
    added (reference sets by the score the detector ranks with)."""
    from tqdm import tqdm

    rows = pickle.loads(Path(rows_file).read_bytes())
    hists: dict = {}
    with Pool(workers, initializer=_init, initargs=(str(root), str(detections))) as pool:
        for h in tqdm(pool.imap(_image_hists, imgs), total=len(imgs), desc="looks", unit="img"):
            hists.update(h)
    add_appearance(rows, hists)
    return rows


def main() -> None:
    ap = ethz_parser(__doc__)
    ap.add_argument("--rows", required=True, help="the terms pickle ethz_verify.py --rows wrote")
    ap.add_argument("--context-check", type=float, default=0.15)
    ap.add_argument("--without-context", action="store_true")
    args = ap.parse_args()
    t0 = time.perf_counter()
    root = ethz_root(args.data)
    imgs = _images(root)
    rows = rows_with_appearance(root, imgs, args.detections, args.rows, args.workers)
    if args.without_context:
        rows = V.without_context(rows, args.context_check)
    sc = V._Scorer(root, rows, len(imgs))
    out = V.analyse(sc, V.TERMS + NEW_TERMS)
    x = np.stack([sc.col(t) for t in ("score",) + PRODUCT_TERMS], 1)
    sub = V._logistic_nested(sc, x, sc.col("iou") >= 0.2)
    out["logistic_product_terms"] = {"terms": ["score", *PRODUCT_TERMS], **sub}
    print(f"edges {args.edges}: reference {out['reference']['overlap_20']['mean']:.4f}")
    for t in NEW_TERMS + ("context",):
        a = " ".join(f"{out['auc'][t][c]:.2f}" for c in ETHZ_CLASSES)
        st = out["single_term"][t]
        print(
            f"{t:20s} AUC {a}  LOCO {st['loco_overlap_20']['mean']:.4f} / "
            f"{st['loco_overlap_50']['mean']:.4f}  {st['loco_overlap_20']}"
        )
    for name in ("single_term_nested", "pair_with_context_nested", "logistic_nested_l2"):
        r = out[name]
        print(
            f"{name:26s} {r['loco_overlap_20']['mean']:.4f} / {r['loco_overlap_50']['mean']:.4f}"
            f"  {r['loco_overlap_20']}  {r.get('chosen', r.get('l2_chosen'))}"
        )
    r = out["logistic_product_terms"]["logistic_nested_l2"]
    print(
        f"logistic on score + {', '.join(PRODUCT_TERMS)}: {r['loco_overlap_20']['mean']:.4f} / "
        f"{r['loco_overlap_50']['mean']:.4f}  {r['loco_overlap_20']}  {r['l2_chosen']}"
    )
    for t in NEW_TERMS:
        r = out["pair_with_context"][t]
        print(
            f"context + {t:20s} {r['loco_overlap_20']['mean']:.4f} / "
            f"{r['loco_overlap_50']['mean']:.4f}  {r['loco_overlap_20']}"
        )
    cmd = "python3 benchmarks/ethz_appearance.py " + " ".join(sys.argv[1:])
    res = {
        "protocol": __doc__,
        "m_ref": M_REF,
        "new_terms": list(NEW_TERMS),
        "edges": args.edges,
        "detections": str(args.detections),
        "without_context": args.without_context,
        **out,
        "seconds": round(time.perf_counter() - t0, 1),
        "machine": machine(),
        "command": cmd,
    }
    write_json(
        Path(args.json) if args.json else RESULTS / f"ethz_appearance_{args.edges}.json", res
    )


if __name__ == "__main__":
    main()
