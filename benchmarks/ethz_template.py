"""ETHZ: an upright template check of each detection, beside the shipped re-scorer's terms.

The stitching is invariant to rotation, and about half of the correct mug detections place
the model turned by 90 degrees: the box is right, the outline is not the mug's, and every
term computed on that placement (context agreement, outline check, edge support) judges the
wrong outline. This script asks whether a second, independent look at the *box* helps: the
model as drawn (upright, or mirrored left to right) is fitted to the edge map around the
detection's box by a small exhaustive search of similarity placements, and scored by an
oriented chamfer match, bounded in ``[0, 1]``:

``template``, ``template_support``, ``template_gain`` and ``box_density``, defined in
:mod:`shapetree.detection._template` (computed here by the library from the cached
detections' boxes and the image's edge map).

Each term is added to the shipped eight one at a time (and in the pairs and the whole set
of ``CANDIDATES``) and the logistic re-scorer of ``ethz_collection_terms.py`` is refitted
held out (four classes fitted, the fifth scored; the L2 penalty chosen by an inner
leave-one-class-out). ``set_chosen_in_each_fold`` also chooses the term set inside each
fold, so that its figure is held out as to the choice of terms too; its ``fit_all`` is the
set chosen the same way on all five classes, fitted on all five: the constants the library
ships (``RESCORER_WEIGHTS``). Usage::

    python3 benchmarks/ethz_template.py --edges pb --detections CACHE_DIR

Writes ``benchmarks/results/ethz_template_<edges>.json`` (or ``--json``).
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import ethz_collection_terms as CT  # noqa: E402
import ethz_verify as V  # noqa: E402
from _common import RESULTS, add_param_option, ethz_parser, machine, write_json  # noqa: E402

from shapetree.detection import DetectParams, edge_map, load_edges, load_image, load_model  # noqa: E402
from shapetree.detection._ethz_eval import ETHZ_CLASSES, _images, ethz_root  # noqa: E402
from shapetree.detection._template import (  # noqa: E402
    TEMPLATE_TERMS,
    template_fields,
    template_model,
    template_terms,
)

TERMS = TEMPLATE_TERMS
EDGE = DetectParams().threshold
_T: dict = {}


def _init(root: str, cache: str, edges: str) -> None:
    CT._init(root, cache)
    params = DetectParams()
    _T["edges"] = edges
    _T["models"] = {
        c: template_model(load_model(Path(root) / "models" / f"{mf}.tif", m=params.m).points)
        for c, (_f, mf) in ETHZ_CLASSES.items()
    }


def _image(item: tuple[str, str]):
    """One image's detections with the template terms: those the records carry (made by
    the detector), else computed from the image's edge map (a cache made before them)."""
    key, shape, per_cls = CT._image(item)
    if all(t in d for dets in per_cls.values() for d in dets for t in TERMS):
        return key, shape, per_cls
    folder, stem = item
    root = CT._STATE["root"]
    if _T["edges"] == "pb":
        e = load_edges(root / folder / f"{stem}_edges.tif")
    else:
        e = edge_map(load_image(root / folder / f"{stem}.jpg"), method="own")
    f = template_fields(e, EDGE)
    for cls, dets in per_cls.items():
        for d in dets:
            d.update(template_terms(f, _T["models"][cls], d["bbox"]))
    return key, shape, per_cls


CANDIDATES = {
    "shipped terms": (),
    **{f"shipped + {t}": (t,) for t in TERMS},
    "shipped + template + template_gain": ("template", "template_gain"),
    "shipped + template_support + template_gain": ("template_support", "template_gain"),
    "shipped + all four": TERMS,
}


def _inner_best(sc, x, label, classes) -> tuple[float, float]:
    """Best mean DR over ``classes`` (each scored by a fit on the others of them) over
    the L2 grid, and that L2."""
    best = None
    for l2 in V.L2_GRID:
        others = [(sc.cls != c) & np.isin(sc.cls, classes) for c in classes]
        m = float(
            np.mean([sc.dr(c, V._fit_score(x, label, tr, l2))[0] for c, tr in zip(classes, others)])
        )
        if best is None or (m, l2) > best:
            best = (m, l2)
    return best


def best_set(sc, label, x_of: dict, classes: list[str]) -> tuple[str, float, float]:
    """The term set of ``x_of`` with the best inner leave-one-class-out mean over
    ``classes`` (ties to the larger L2, then the earlier set): ``(name, l2, mean)``."""
    res = {n: _inner_best(sc, x, label, classes) for n, x in x_of.items()}
    name = max(res, key=lambda n: res[n])
    return name, res[name][1], res[name][0]


def fit_all(sc, x: np.ndarray, label: np.ndarray, l2: float, rows=None) -> dict:
    """The logistic re-scorer fitted on ``rows`` (default all) of every class, standardised
    over them, and scored in sample: the constants a script would ship."""
    rows = np.ones(len(label), bool) if rows is None else rows
    mu, sd = x[rows].mean(0), x[rows].std(0) + 1e-12
    w = V._logistic((x[rows] - mu) / sd, label[rows].astype(float), l2)
    ins = {c: sc.dr(c, ((x - mu) / sd) @ w[:-1]) for c in ETHZ_CLASSES}
    return {
        "l2": l2,
        "mean": mu.tolist(),
        "std": sd.tolist(),
        "weights": w[:-1].tolist(),
        "intercept": float(w[-1]),
        "in_sample_overlap_20": V._with_mean(ins, 0),
        "in_sample_overlap_50": V._with_mean(ins, 1),
    }


def choose_in_folds(sc, label, x_of: dict) -> tuple[dict, dict]:
    """For each class left out, the term set (and L2) with the best inner
    leave-one-class-out mean over the four training classes, fitted on them and scored on
    the fifth: ``({class: DR}, {class: choice})``."""
    held, chosen = {}, {}
    classes = list(ETHZ_CLASSES)
    for c_out in classes:
        name, l2, m = best_set(sc, label, x_of, [c for c in classes if c != c_out])
        chosen[c_out] = {"set": name, "l2": l2, "inner_mean": round(m, 4)}
        held[c_out] = sc.dr(c_out, V._fit_score(x_of[name], label, sc.cls != c_out, l2))
    return held, chosen


def held_text(name: str, held: dict) -> str:
    """One printed line: a held-out record's mean DR under both rules and per class."""
    return (
        f"{name} held out {held['loco_overlap_20']['mean']:.4f} / "
        f"{held['loco_overlap_50']['mean']:.4f}  {held['loco_overlap_20']}"
    )


def nested_choice(sc, label, x_of: dict) -> dict:
    """The term set chosen inside each fold (the best inner leave-one-class-out mean over
    the four training classes, its L2 with it), scored on the fifth; and the set and L2
    chosen on all five, fitted on all five: the constants to ship."""
    held, chosen = choose_in_folds(sc, label, x_of)
    name, l2, m = best_set(sc, label, x_of, list(ETHZ_CLASSES))
    return {
        "note": "term set and L2 chosen inside each fold by leave-one-class-out over the "
        "four training classes, scored on the fifth (held out); fit_all: the set and L2 "
        "chosen the same way over all five, fitted on all five (the constants to ship; "
        "in sample)",
        "chosen": chosen,
        "loco_overlap_20": V._with_mean(held, 0),
        "loco_overlap_50": V._with_mean(held, 1),
        "fit_all": {
            "set": name,
            "terms": list(CT.SHIPPED + CANDIDATES[name]),
            "inner_mean": round(m, 4),
            **fit_all(sc, x_of[name], label, l2),
        },
    }


def cross_from(sc_tr, label_tr, x_tr_of: dict, sc_te, x_te_of: dict) -> dict:
    """Trained on another edge source's rows (``_tr``: the set and L2 chosen inside each
    fold on its four training classes, fitted on them), scored on this run's fifth class:
    held out as to class, term set and edge source."""
    held, chosen = {}, {}
    classes = list(ETHZ_CLASSES)
    for c_out in classes:
        name, l2, _ = best_set(sc_tr, label_tr, x_tr_of, [c for c in classes if c != c_out])
        chosen[c_out] = {"set": name, "l2": l2}
        x_tr, tr = x_tr_of[name], sc_tr.cls != c_out
        mu, sd = x_tr[tr].mean(0), x_tr[tr].std(0) + 1e-12
        w = V._logistic((x_tr[tr] - mu) / sd, label_tr[tr].astype(float), l2)
        held[c_out] = sc_te.dr(c_out, ((x_te_of[name] - mu) / sd) @ w[:-1])
    return {
        "note": "term set and L2 chosen inside each fold on the training run's four "
        "classes, fitted on them, scored on this run's fifth class",
        "chosen": chosen,
        "loco_overlap_20": V._with_mean(held, 0),
        "loco_overlap_50": V._with_mean(held, 1),
    }


def main() -> None:
    ap = ethz_parser(__doc__)
    add_param_option(
        ap,
        "a DetectParams field of the run that made --detections, other than its "
        "default (eval_ethz.py --param; e.g. m=40)",
    )
    ap.add_argument("--rows", default=None, help="also write every row (JSON) here")
    ap.add_argument("--from-rows", default=None, help="read the rows --rows wrote instead")
    ap.add_argument(
        "--cross-rows",
        default=None,
        help="rows (--rows) of a run on another edge source: also train on them and score "
        "this run held out as to class and edge source (cross_from_other_edges)",
    )
    args = ap.parse_args()
    t0 = time.perf_counter()
    root = ethz_root(args.data)
    imgs = _images(root)
    if args.from_rows:
        rows = json.loads(Path(args.from_rows).read_text())
    else:
        rows = CT.rows_for(
            root,
            Path(args.detections),
            imgs,
            args.workers,
            image_fn=_image,
            init=_init,
            init_args=(args.edges,),
            extra=TERMS,
            params=DetectParams(**dict(args.param)),
        )
    if args.rows:
        Path(args.rows).write_text(json.dumps(rows))
    sc = V._Scorer(root, rows, len(imgs))
    label = sc.col("iou") >= 0.2
    out: dict = {
        "protocol": __doc__,
        "edges": args.edges,
        "detections": args.detections,
        "auc": {t: CT._aucs(sc, t, label) for t in TERMS},
        "single_term_in_view": {
            t: V._with_mean({c: sc.dr(c, sc.col(t)) for c in ETHZ_CLASSES}, 0) for t in TERMS
        },
    }
    x_of = {n: np.stack([sc.col(t) for t in CT.SHIPPED + e], 1) for n, e in CANDIDATES.items()}
    out["logistic"] = {}
    for name, x in x_of.items():
        res = V._logistic_nested(sc, x, label)
        out["logistic"][name] = {"terms": list(CT.SHIPPED + CANDIDATES[name]), **res}
        ins = res["logistic_in_sample"]["overlap_20"]["mean"]
        print(f"{held_text(f'{name:44s}', res['logistic_nested_l2'])}  in sample {ins:.4f}")
    out["set_chosen_in_each_fold"] = nc = nested_choice(sc, label, x_of)
    print(
        f"{held_text('set chosen in each fold:', nc)}  "
        f"{ {c: v['set'] for c, v in nc['chosen'].items()} }; on all five: "
        f"{nc['fit_all']['set']} (l2 {nc['fit_all']['l2']})"
    )
    if args.cross_rows:
        rows_tr = json.loads(Path(args.cross_rows).read_text())
        sc_tr = V._Scorer(root, rows_tr, len(imgs))
        x_tr_of = {
            n: np.stack([sc_tr.col(t) for t in CT.SHIPPED + e], 1) for n, e in CANDIDATES.items()
        }
        cr = cross_from(sc_tr, sc_tr.col("iou") >= 0.2, x_tr_of, sc, x_of)
        out["cross_from_other_edges"] = {"train_rows": args.cross_rows, **cr}
        print(
            f"trained on {args.cross_rows}, held out: {cr['loco_overlap_20']['mean']:.4f} / "
            f"{cr['loco_overlap_50']['mean']:.4f} {cr['loco_overlap_20']}"
        )
    out["seconds"] = round(time.perf_counter() - t0, 1)
    out["machine"] = machine()
    out["command"] = "python3 benchmarks/ethz_template.py " + " ".join(sys.argv[1:])
    write_json(Path(args.json) if args.json else RESULTS / f"ethz_template_{args.edges}.json", out)


if __name__ == "__main__":
    main()
