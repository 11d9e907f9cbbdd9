"""ETHZ: does a second edge source's detection agree? A term of the re-scorer, measured.

A detection found on the Pb map is also looked for among the detections the same model
gets in the same image on a second edge map (the project's own, or PiDiNet), run by
``eval_ethz.py`` with the same parameters. Three forms of agreement, each bounded:

- ``agree``: the largest IoU of the detection's box with any of the second run's boxes;
- ``agree_top``: its IoU with the second run's best detection (by its score);
- ``agree_score``: the second run's best score among its boxes overlapping this one by
  IoU > 0.5, less its best score in the image (0 when the best itself agrees; -1 when
  no box overlaps).

Each is added to the shipped re-scorer's twelve terms and the logistic is refitted held
out (four classes fitted, the fifth scored, the L2 penalty chosen by an inner
leave-one-class-out; ``ethz_verify._logistic_nested``). ``set_chosen_in_each_fold`` also
chooses among the four term sets (none or one of the three) inside each fold, so that its
figure is held out as to that choice too. Usage::

    python3 benchmarks/ethz_template.py --edges pb --detections PB_CACHE --rows pb_rows.json
    python3 benchmarks/eval_ethz.py --edges pidinet --edge-weights W.npz --cache-dir C2 ...
    python3 benchmarks/ethz_edge_agreement.py --rows pb_rows.json \\
        --second C2/<key> --second-name pidinet

Writes ``benchmarks/results/ethz_edge_agreement.json`` (or ``--json``), a record per second
source under ``runs``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import ethz_collection_terms as CT  # noqa: E402
import ethz_template as T  # noqa: E402
import ethz_verify as V  # noqa: E402
from _common import REPO, RESULTS, machine, write_json  # noqa: E402

from shapetree.detection._ethz_eval import ETHZ_CLASSES, _images, ethz_root  # noqa: E402

FORMS = ("agree", "agree_top", "agree_score")


def _iou(a, b) -> float:
    x1, y1 = max(a[0], b[0]), max(a[1], b[1])
    x2, y2 = min(a[2], b[2]), min(a[3], b[3])
    inter = max(0.0, x2 - x1) * max(0.0, y2 - y1)
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return inter / union if union > 0 else 0.0


def agreement(rows: list[dict], second: Path) -> dict[str, np.ndarray]:
    """The three agreement terms of every row with the second run's cached detections."""
    cache: dict[tuple[str, str], list] = {}
    out: dict[str, list[float]] = {f: [] for f in FORMS}
    for r in rows:
        folder, stem = r["key"].split("/")
        key = (r["cls"], r["key"])
        if key not in cache:
            doc = json.loads((second / r["cls"] / f"{folder}__{stem}.json").read_text())
            cache[key] = doc["detections"]
        dets = cache[key]
        ious = [_iou(r["bbox"], d["bbox"]) for d in dets]
        top = max(dets, key=lambda d: d["score"]) if dets else None
        over = [d["score"] for d, i in zip(dets, ious, strict=True) if i > 0.5]
        out["agree"].append(max(ious) if ious else 0.0)
        out["agree_top"].append(_iou(r["bbox"], top["bbox"]) if top else 0.0)
        out["agree_score"].append(max(over) - top["score"] if over else -1.0)
    return {f: np.asarray(v) for f, v in out.items()}


def _aucs(sc, v: np.ndarray, label: np.ndarray) -> dict:
    """Per class, the AUC of a term telling true detections (IoU >= 0.2) from false."""
    return {
        c: round(V._auc(v[(sc.cls == c) & label], v[(sc.cls == c) & ~label]), 3)
        for c in ETHZ_CLASSES
    }


def nested_set_choice(sc, label, x_of: dict) -> dict:
    """The term set chosen inside each fold (:func:`ethz_template.choose_in_folds`)."""
    held, chosen = T.choose_in_folds(sc, label, x_of)
    return {
        "chosen": chosen,
        "loco_overlap_20": V._with_mean(held, 0),
        "loco_overlap_50": V._with_mean(held, 1),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(REPO.parent / "shared" / "datasets"))
    ap.add_argument("--rows", required=True, help="the Pb rows (ethz_template.py --rows)")
    ap.add_argument("--second", required=True, help="a second edge source's detection cache")
    ap.add_argument("--second-name", required=True, help="its name in the record")
    ap.add_argument("--json", default=str(RESULTS / "ethz_edge_agreement.json"))
    args = ap.parse_args()
    t0 = time.perf_counter()
    root = ethz_root(args.data)
    rows = json.loads(Path(args.rows).read_text())
    sc = V._Scorer(root, rows, len(_images(root)))
    label = sc.col("iou") >= 0.2
    terms = CT.SHIPPED + T.TERMS
    base = np.stack([sc.col(t) for t in terms], 1)
    extra = agreement(rows, Path(args.second))
    x_of = {"none": base, **{f: np.column_stack([base, extra[f]]) for f in FORMS}}
    run: dict = {
        "command": "python3 benchmarks/ethz_edge_agreement.py " + " ".join(sys.argv[1:]),
        "second": args.second_name,
        "second_cache": args.second,
        "rows": args.rows,
        "terms": list(terms),
        "auc": {f: _aucs(sc, extra[f], label) for f in FORMS},
        "logistic": {},
    }
    for name, x in x_of.items():
        res = V._logistic_nested(sc, x, label)["logistic_nested_l2"]
        run["logistic"][name] = res
        print(T.held_text(f"{name:12s}", res), flush=True)
    run["set_chosen_in_each_fold"] = nc = nested_set_choice(sc, label, x_of)
    print(
        T.held_text("set chosen in each fold:", nc),
        {c: v["set"] for c, v in nc["chosen"].items()},
    )
    run["seconds"] = round(time.perf_counter() - t0, 1)
    path = Path(args.json)
    doc = json.loads(path.read_text()) if path.is_file() else {}
    doc.update(
        {
            "protocol": __doc__,
            "rows_made_by": "python3 benchmarks/ethz_template.py --edges pb --detections "
            "<the Pb cache of eval_ethz.py> --rows ROWS (the Pb run of ethz.json's headline)",
            "machine": machine(),
        }
    )
    doc.setdefault("runs", {})[args.second_name] = run
    write_json(path, doc)


if __name__ == "__main__":
    main()
