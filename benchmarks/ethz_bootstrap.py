"""ETHZ: how far the held-out detection rate moves with the images drawn.

The held-out mean DR at 0.4 FPPI is measured on one set of 255 photos, and differences of
0.01 between rankings are one or two objects of one class. This script puts an interval
on the shipped figure and on its gain over the global re-scorer alone, by resampling the
photos (a bootstrap over images, the unit the detections and the false positives per image
belong to):

- every row is scored held out twice: by the within-image record's choice for its class
  (``ethz_misses.held_out_within``, the shipped headline) and by the global re-scorer with
  its term set and penalty chosen inside the fold (``ethz_misses.held_out_scores``);
- each replicate draws 255 photos with replacement (the same draw for both rankings and
  all five classes; a photo drawn twice brings its detections and its objects twice) and
  computes each class's DR at 0.4 FPPI under the 20% rule and PASCAL, and their mean;
- reported: the median and the 2.5 and 97.5 percentiles of each mean and of the
  difference, and the share of replicates in which the shipped mean reaches 0.90 (20%
  rule) or 0.85 (PASCAL). The DR at a fixed FPPI is the best of a step curve, and a photo
  drawn twice brings its false positives twice, so the replicates' median may sit below the
  figure as measured; the median says by how much.

The rankings are fitted once on all photos (only the scoring is resampled), so the interval
is the spread due to which photos are scored, not to which were trained on.

``--other-rows`` (issue 14, item 2): the rows of the same detector on another edge source
over the same photos (the own edge map), scored held out as to class and edge source (the
record's choices, both models fitted on ``--rows``' other four classes, as
``ethz_within_image.py --score-rows``); each replicate also gives that run's mean on the
same draw, and the gap (this run less the other) is reported like the gain, with the share
of draws in which it is at most 0.03 (the item's goal). Usage::

    python3 benchmarks/ethz_bootstrap.py --rows ROWS \
        --within benchmarks/results/ethz_within_image_pb.json

Writes ``benchmarks/results/ethz_bootstrap_pb.json`` (or ``--json``).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _ethz_rows import Rows, finish, parser  # noqa: E402
from ethz_misses import held_out_scores, held_out_within  # noqa: E402

from shapetree.detection._ethz_eval import ETHZ_CLASSES, dr_at_fppi, dr_fppi_curve  # noqa: E402

RULES = {"overlap_20": 0.2, "overlap_50": 0.5}
GOALS = {"overlap_20": 0.90, "overlap_50": 0.85}


def replicate_dr(rows, cls_rows: dict, gts: dict, scores: np.ndarray, draw: list[str]) -> dict:
    """Each class's DR at 0.4 FPPI under both rules on the photos ``draw`` (with repeats)."""
    out = {}
    for c, by_key in cls_rows.items():
        dets, g = [], {}
        for copy, key in enumerate(draw):
            name = f"{key}#{copy}"
            g[name] = gts[c].get(key, np.zeros((0, 4)))
            dets += [(name, float(scores[i]), rows[i]["bbox"]) for i in by_key.get(key, [])]
        out[c] = {
            rule: dr_at_fppi(*dr_fppi_curve(dets, g, len(draw), thr)[:2], 0.4)
            for rule, thr in RULES.items()
        }
    return out


def main() -> None:
    ap = parser(__doc__)
    ap.add_argument("--within", required=True, help="the ethz_within_image.py record")
    ap.add_argument("--replicates", type=int, default=500)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--other-rows", default=None, help="rows of another edge source's run")
    args = ap.parse_args()
    r = Rows.read(args.rows, args.data)
    rows, sc, label = r.rows, r.sc, r.label
    record = json.loads(Path(args.within).read_text())
    shipped, _ = held_out_within(sc, rows, label, r.candidates(), record)
    glob, _ = held_out_scores(sc, label, r.candidates())
    photos = sorted({row["key"] for row in rows})
    runs = {"shipped": (rows, shipped, sc.gts), "global": (rows, glob, sc.gts)}
    if args.other_rows:
        other = Rows.read(args.other_rows, args.data)
        s_other, _ = held_out_within(sc, rows, label, r.candidates(), record, target=other)
        runs["other"] = (other.rows, s_other, other.sc.gts)
        photos = sorted(set(photos) | {row["key"] for row in other.rows})
    by_run = {}
    for name, (rows_, _, _) in runs.items():
        by_run[name] = {c: {} for c in ETHZ_CLASSES}
        for i, row in enumerate(rows_):
            by_run[name][row["cls"]].setdefault(row["key"], []).append(i)
    rng = np.random.default_rng(args.seed)
    means = {name: {rule: [] for rule in RULES} for name in runs}
    for b in range(args.replicates + 1):
        # replicate 0 is the photos as they are: it must reproduce the records
        draw = photos if b == 0 else list(rng.choice(photos, len(photos)))
        for name, (rows_, s, gts) in runs.items():
            res = replicate_dr(rows_, by_run[name], gts, s, draw)
            for rule in RULES:
                means[name][rule].append(float(np.mean([res[c][rule] for c in ETHZ_CLASSES])))
        if b % 50 == 0:
            print(f"replicate {b}/{args.replicates}", flush=True)
    out: dict = {"protocol": __doc__, "replicates": args.replicates, "seed": args.seed}
    if args.other_rows:
        out["other_rows"] = args.other_rows
    for rule in RULES:
        sh, gl = np.array(means["shipped"][rule]), np.array(means["global"][rule])
        d = sh[1:] - gl[1:]
        out[rule] = {
            "shipped_as_measured": round(sh[0], 4),
            "global_as_measured": round(gl[0], 4),
            "shipped_median": round(float(np.median(sh[1:])), 4),
            "global_median": round(float(np.median(gl[1:])), 4),
            "shipped_interval_95": np.percentile(sh[1:], [2.5, 97.5]).round(4).tolist(),
            "global_interval_95": np.percentile(gl[1:], [2.5, 97.5]).round(4).tolist(),
            "gain_interval_95": np.percentile(d, [2.5, 97.5]).round(4).tolist(),
            "share_gain_positive": round(float(np.mean(d > 0)), 3),
            "share_shipped_reaching_goal": round(float(np.mean(sh[1:] >= GOALS[rule])), 3),
        }
        if "other" in means:
            ot = np.array(means["other"][rule])
            gap = sh[1:] - ot[1:]
            out[rule] |= {
                "other_as_measured": round(ot[0], 4),
                "other_interval_95": np.percentile(ot[1:], [2.5, 97.5]).round(4).tolist(),
                "gap_as_measured": round(sh[0] - ot[0], 4),
                "gap_interval_95": np.percentile(gap, [2.5, 97.5]).round(4).tolist(),
                "share_gap_within_0.03": round(float(np.mean(gap <= 0.03)), 3),
            }
        o = out[rule]
        print(
            f"{rule}: shipped {o['shipped_as_measured']:.4f} {o['shipped_interval_95']}, "
            f"global {o['global_as_measured']:.4f} {o['global_interval_95']}, gain "
            f"{o['gain_interval_95']} (> 0 in {o['share_gain_positive']:.1%}), reaches "
            f"{GOALS[rule]} in {o['share_shipped_reaching_goal']:.1%}"
        )
        if "gap_as_measured" in o:
            print(
                f"  other {o['other_as_measured']:.4f} {o['other_interval_95']}, gap "
                f"{o['gap_as_measured']:.4f} {o['gap_interval_95']} (<= 0.03 in "
                f"{o['share_gap_within_0.03']:.1%})"
            )
    finish(out, args, r.t0, "ethz_bootstrap.py", "ethz_bootstrap_pb.json")


if __name__ == "__main__":
    main()
