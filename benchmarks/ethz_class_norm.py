"""ETHZ: the re-scorer's terms normalised within each model's own collection.

The collection re-scorer (``shapetree.detection.rescore_collection``) is one logistic
regression over all five classes: each term is standardised by its mean and spread over
the training classes' detections, and the same weights then rank every class. Held out
(fitted on four classes, the fifth scored) it loses to the fit in view of all five (0.836
against 0.858 at 0.4 FPPI), most on giraffes and mugs. One reason may be that a term's
scale is a property of the model as much as of the detection: a 30-point giraffe with four
legs stitches at another cost, and reaches another context agreement, than a mug. A
weight learned on four models then meets the fifth model's terms at another offset and
spread.

This script asks whether normalising each term *within one model's collection* (all the
detections that model keeps over the images searched) transfers better. That uses no label,
only the other photos of the search, as the colour agreement already does: it is a
transductive re-ranking. Protocol, written before any of its scores were seen:

- rows: the twelve shipped terms (the eight ``SHIPPED`` of
  ``ethz_collection_terms.py`` and the four template terms) of every kept detection, read
  from the rows that ``ethz_template.py --rows`` writes;
- transforms of the twelve terms (the label is IoU >= 0.2 with a ground-truth box):

  * ``global``: as shipped (standardised on the training rows);
  * ``per_model_z``: each term z-scored over its own model's detections;
  * ``per_model_rank``: each term replaced by its rank quantile in ``[0, 1]`` over its own
    model's detections (ties averaged);
  * ``global_and_per_model_z``: both the global and the per-model z columns (24);

- each transform is refitted as the shipped re-scorer is: logistic regression on the
  standardised columns, its L2 penalty chosen inside each fold from ``L2_GRID`` by an inner
  leave-one-class-out over the four training classes, scored on the fifth;
- headline (``transform_chosen_in_each_fold``): the transform *and* the penalty chosen
  inside each fold by the same inner leave-one-class-out mean DR at 0.4 FPPI (20% rule),
  fitted on the four classes, scored on the fifth. Ties go to the earlier transform in
  the list above (``global`` first).

Mean DR at 0.4 FPPI under the 20% rule and under PASCAL's 50%. Usage::

    python3 benchmarks/ethz_class_norm.py --rows ROWS_OF_ethz_template.py

Writes ``benchmarks/results/ethz_class_norm_<edges>.json`` (or ``--json``).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.stats import rankdata

sys.path.insert(0, str(Path(__file__).resolve().parent))

import ethz_verify as V  # noqa: E402
from _ethz_rows import RESCORER_TERMS, Rows, finish, held_line, held_record, parser  # noqa: E402
from ethz_template import _inner_best  # noqa: E402

from shapetree.detection._ethz_eval import ETHZ_CLASSES  # noqa: E402

TRANSFORMS = ("global", "per_model_z", "per_model_rank", "global_and_per_model_z")


def transform(x: np.ndarray, cls: np.ndarray, name: str) -> np.ndarray:
    """The columns of ``x`` (rows x terms) under one transform; ``cls`` names each row's
    model. Label-free: a per-model transform sees only that model's own rows."""
    if name == "global":
        return x
    out = np.empty_like(x)
    for c in np.unique(cls):
        r = cls == c
        if name == "per_model_rank":
            out[r] = (rankdata(x[r], axis=0) - 0.5) / r.sum()
        else:
            out[r] = (x[r] - x[r].mean(0)) / (x[r].std(0) + 1e-12)
    if name == "global_and_per_model_z":
        return np.hstack([x, out])
    return out


def chosen_in_each_fold(sc, label, x_of: dict) -> dict:
    """The transform and L2 chosen inside each fold (inner leave-one-class-out over the
    four training classes; ties to the earlier transform), scored on the fifth."""
    held, chosen = {}, {}
    classes = list(ETHZ_CLASSES)
    for c_out in classes:
        inner = [c for c in classes if c != c_out]
        res = {n: _inner_best(sc, x_of[n], label, inner) for n in TRANSFORMS}
        best = max(res.values())[0]
        name = next(n for n in TRANSFORMS if res[n][0] == best)
        l2 = res[name][1]
        chosen[c_out] = {"transform": name, "l2": l2, "inner_mean": round(best, 4)}
        held[c_out] = sc.dr(c_out, V._fit_score(x_of[name], label, sc.cls != c_out, l2))
    return held_record(held, chosen)


def main() -> None:
    ap = parser(__doc__)
    ap.add_argument("--edges", default="pb", choices=("pb", "own"))
    args = ap.parse_args()
    r = Rows.read(args.rows, args.data)
    sc, label = r.sc, r.label
    x = r.matrix()
    x_of = {n: transform(x, sc.cls, n) for n in TRANSFORMS}
    out: dict = {"protocol": __doc__, "edges": args.edges, "terms": list(RESCORER_TERMS)}
    out["logistic"] = {}
    for n in TRANSFORMS:
        res = V._logistic_nested(sc, x_of[n], label)
        out["logistic"][n] = res
        ins = res["logistic_in_sample"]["overlap_20"]["mean"]
        print(f"{held_line(f'{n:24s}', res['logistic_nested_l2'])}  in sample {ins:.4f}")
    out["transform_chosen_in_each_fold"] = ch = chosen_in_each_fold(sc, label, x_of)
    print(
        f"{held_line('transform chosen in each fold:', ch)} "
        f"{ {c: v['transform'] for c, v in ch['chosen'].items()} }"
    )
    finish(out, args, r.t0, "ethz_class_norm.py", f"ethz_class_norm_{args.edges}.json")


if __name__ == "__main__":
    main()
