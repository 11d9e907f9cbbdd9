"""ETHZ: where the objects missed at 0.4 FPPI are, and what outranks them.

A diagnosis of the shipped re-scorer's held-out ranking, not a new method. For each class,
each detection is scored by the re-scorer chosen and fitted on the other four classes (the
term set and L2 penalty chosen inside the fold, as ``ethz_template.py``'s
``set_chosen_in_each_fold``: the headline held-out figure), and the ranking is cut where
the false positives reach 0.4 per image. Then:

- each ground-truth object below the cut is put in one of three groups: its image's *best*
  detection overlaps it (the right hypothesis won in its image and lost to other images),
  a *lower* detection of its image overlaps it (it lost inside its own image), or *none* of
  the image's kept detections overlaps it (no ranking can find it);
- each false positive above the cut is counted by the class of the image it is in, and by
  its rank inside that image.

Both under the 20% rule and PASCAL's 50% (the overlap that counts as a hit). And, for
every true detection (IoU >= 0.2) that is not its image's best while that best is false,
the median difference of each term (the true one less the image's best), the share of
such pairs where it is positive, and the ratio of their box areas: what a ranking inside
the image would have to see (``inside_image``). Usage::

    python3 benchmarks/ethz_misses.py --rows ROWS_OF_ethz_template.py

Writes ``benchmarks/results/ethz_misses_pb.json`` (or ``--json``).

``--within RECORD`` (added in session 46, when the within-image re-scorer shipped): rank
by that record's held-out choice instead (``ethz_within_image.py``'s ``chosen_in_each_fold``:
for each class the term set, combination and penalties chosen on the other four, both
models fitted on them), the ranking of the shipped headline. Either way each class's
misses are also counted by whether their image holds several objects of the class
(``missed_in_images_with_several``, and per such image ``missed_by_image_with_several``).
Writes ``ethz_misses_within_pb.json``.
"""

from __future__ import annotations

import json
import sys
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import ethz_verify as V  # noqa: E402
from _ethz_rows import RESCORER_TERMS, Rows, finish, parser  # noqa: E402
from ethz_hard_rows import image_rank  # noqa: E402
from ethz_template import best_set  # noqa: E402

from shapetree.detection._ethz_eval import (  # noqa: E402
    ETHZ_CLASSES,
    _iou,
    dr_at_fppi,
    dr_fppi_curve,
    greedy_claims,
)

FPPI = 0.4


def held_out_scores(sc, label, x_of: dict) -> tuple[np.ndarray, dict]:
    """Every row scored by the re-scorer chosen (among the candidate term sets ``x_of``)
    and fitted without its class."""
    s = np.zeros(len(label))
    chosen = {}
    classes = list(ETHZ_CLASSES)
    for c in classes:
        name, l2, _ = best_set(sc, label, x_of, [k for k in classes if k != c])
        chosen[c] = {"set": name, "l2": l2}
        r = sc.cls == c
        s[r] = V._fit_score(x_of[name], label, sc.cls != c, l2)[r]
    return s, chosen


def held_out_within(
    sc, rows, label, x_of: dict, record: dict, target=None
) -> tuple[np.ndarray, dict]:
    """Every row scored by the within-image record's choice for its class, both models
    fitted without the class (``ethz_within_image.transfer``). ``target`` (an
    ``_ethz_rows.Rows`` of another run on the same photos, e.g. another edge source):
    score its rows instead, with the models fitted on these."""
    import ethz_within_image as W

    def parts(sc_, rows_):
        x_ = np.stack([sc_.col(t) for t in RESCORER_TERMS], 1)
        return x_, W.groups_of(np.array([row["key"] for row in rows_]), sc_.cls)

    x, group = parts(sc, rows)
    if target is None:
        sc_t, x_t, group_t, x_of_t = sc, x, group, x_of
    else:
        sc_t, x_of_t = target.sc, target.candidates()
        x_t, group_t = parts(sc_t, target.rows)
    chosen = record["chosen_in_each_fold"]["chosen"]
    s = np.zeros(len(sc_t.cls))
    for c in ETHZ_CLASSES:
        ch = chosen[c]
        f = W.transfer(
            x_of[ch["set"]],
            x,
            label,
            group,
            sc.cls != c,
            ch["set_l2"],
            ch["combination"],
            ch["within_l2"],
        )
        r = sc_t.cls == c
        s[r] = f(x_of_t[ch["set"]], x_t, group_t)[r]
    return s, chosen


def diagnose(sc, rows, s, rank, cls: str, thr: float) -> dict:
    """The groups of one class's misses and its false positives above the cut."""
    idx = np.flatnonzero(sc.cls == cls)
    gts = sc.gts[cls]
    dets = [(rows[i]["key"], float(s[i]), rows[i]["bbox"]) for i in idx]
    fppi, dr, scores = dr_fppi_curve(dets, gts, sc.n, thr)
    cut_dr = dr_at_fppi(fppi, dr, FPPI)
    # the last position of the curve at that DR within the FPPI limit: the cut
    ok = np.flatnonzero((fppi <= FPPI + 1e-12) & (dr == cut_dr))
    n_top = int(ok[-1]) + 1 if len(ok) else 0
    order, hit, claimed = greedy_claims(dets, gts, thr, n_top)
    fp_folder, fp_rank = Counter(), Counter()
    for j in np.asarray(order)[~hit]:
        fp_folder[dets[j][0].split("/")[0]] += 1
        fp_rank[int(rank[idx[j]])] += 1
    groups, several = Counter(), Counter()
    for key, g in gts.items():
        mine = [i for i in idx if rows[i]["key"] == key]
        for b, box in enumerate(g):
            if claimed[key][b]:
                continue
            if len(g) > 1:
                several[key] += 1
            over = [_iou(np.asarray(rows[i]["bbox"], float), box[None])[0] for i in mine]
            hits = [rank[i] for i, v in zip(mine, over) if v >= thr]
            groups["none" if not hits else "best" if min(hits) == 1 else "lower"] += 1
    n_gt = sum(len(g) for g in gts.values())
    return {
        "objects": n_gt,
        "found": int(round(cut_dr * n_gt)),
        "dr": round(cut_dr, 4),
        "missed": {k: groups.get(k, 0) for k in ("best", "lower", "none")},
        "missed_in_images_with_several": sum(several.values()),
        "missed_by_image_with_several": dict(several.most_common()),
        "false_positives_by_image_folder": dict(fp_folder.most_common()),
        "false_positives_by_rank_in_image": dict(sorted(fp_rank.items())),
    }


def inside_image(sc, rows, label, rank, cls: str) -> dict:
    """True detections below a false best of their image: term differences to that best."""
    keys = np.array([r["key"] for r in rows])
    terms = RESCORER_TERMS
    diffs = []
    for i in np.flatnonzero((sc.cls == cls) & label & (rank > 1)):
        best = np.flatnonzero((sc.cls == cls) & (keys == keys[i]) & (rank == 1))[0]
        if label[best]:
            continue
        a, b = np.asarray(rows[i]["bbox"], float), np.asarray(rows[best]["bbox"], float)
        area = (a[2] - a[0]) * (a[3] - a[1]) / max((b[2] - b[0]) * (b[3] - b[1]), 1e-9)
        diffs.append([rows[i][t] - rows[best][t] for t in terms] + [area])
    if not diffs:
        return {"pairs": 0}
    d = np.array(diffs)
    names = list(terms)
    return {
        "pairs": len(d),
        "median_difference": {t: round(float(np.median(v)), 3) for t, v in zip(names, d.T)},
        "share_positive": {t: round(float(np.mean(v > 0)), 2) for t, v in zip(names, d.T)},
        "median_area_ratio": round(float(np.median(d[:, -1])), 2),
    }


def main() -> None:
    ap = parser(__doc__)
    ap.add_argument("--within", default=None, help="an ethz_within_image.py record to rank by")
    args = ap.parse_args()
    r = Rows.read(args.rows, args.data)
    rows, sc, label = r.rows, r.sc, r.label
    if args.within:
        record = json.loads(Path(args.within).read_text())
        s, chosen = held_out_within(sc, rows, label, r.candidates(), record)
    else:
        s, chosen = held_out_scores(sc, label, r.candidates())
    rank = image_rank(np.array([row["key"] for row in rows]), sc.cls, s)
    out: dict = {"protocol": __doc__, "held_out_choice": chosen}
    for name, thr in (("overlap_20", 0.2), ("overlap_50", 0.5)):
        out[name] = {c: diagnose(sc, rows, s, rank, c, thr) for c in ETHZ_CLASSES}
        print(name)
        for c, d in out[name].items():
            print(
                f"  {c:10s} DR {d['dr']:.3f} ({d['found']}/{d['objects']}), missed {d['missed']} "
                f"({d['missed_in_images_with_several']} in images with several), "
                f"FP by folder {d['false_positives_by_image_folder']}, "
                f"by rank in image {d['false_positives_by_rank_in_image']}"
            )
    out["inside_image"] = {c: inside_image(sc, rows, label, rank, c) for c in ETHZ_CLASSES}
    for c, d in out["inside_image"].items():
        if d["pairs"]:
            print(f"  {c:10s} {d['pairs']} pairs, median true - best: {d['median_difference']}")
    default = "ethz_misses_within_pb.json" if args.within else "ethz_misses_pb.json"
    finish(out, args, r.t0, "ethz_misses.py", default)


if __name__ == "__main__":
    main()
