"""ETHZ: two of the detector's own settings, chosen held out.

The re-ranking experiments (``ethz_class_norm.py``, ``ethz_hard_rows.py``,
``ethz_within_image.py``, ``ethz_upright.py``, ``ethz_self_training.py``) all leave the
held-out figure where it is, and ``ethz_misses.py`` shows where the rest is lost: giraffes
found as a part of the animal (a small box inside the true one, the legs matched by gaps),
and true boxes that lose to another detection of their own image. Two settings of the
stitching bear on exactly that and were set on ETHZ in view of all five classes:

- ``gap_cost`` (0.8): what leaving a share of the model unmatched costs. Cheaper gaps let a
  giraffe's legs be skipped; dearer ones make the match find them or fail;
- ``nms_iou`` (0.3): a detection is dropped when its box overlaps a better one by more
  than this IoU. A true box that holds a better-scoring part of the object (IoU of a part
  with the whole is small, but not always below 0.3) is dropped before any ranking.

Protocol, written before any of the new runs were made:

- runs: the shipped settings and ``gap_cost`` 0.6 and 1.0 and ``nms_iou`` 0.5, one at a
  time (``python3 benchmarks/eval_ethz.py --edges pb --param KEY=VALUE --json ...
  --cache-dir ...``), each with its rows (``ethz_template.py --rows``);
- for each run, the shipped held-out procedure (``ethz_template.py``'s
  ``set_chosen_in_each_fold``: term set and L2 chosen inside each fold, fitted on four
  classes, the fifth scored) and its ``recall_any_k`` (the share of objects one of their
  image's kept detections overlaps);
- headline ``setting_chosen_in_each_fold``: for each class left out, the setting with the
  best mean DR at 0.4 FPPI (20% rule) over the four training classes, each of them scored
  by the twelve shipped terms' logistic fit (L2 1000, as shipped) on the three others
  (no label of the left-out class is used); ties to the shipped setting, then the earlier
  run named; that setting's held-out DR of the left-out class is its score.

Added after the four runs' scores were seen (none of them won): a run with 40 model
samples instead of 30 (``--param m=40``, its rows made by ``ethz_template.py --param
m=40 --rows``), since a giraffe's legs get two or three of the 30 and are then skipped or
folded. It joins the same choice as a fifth run (``setting_chosen_in_each_fold`` then
chooses among five).

Added on 2026-12-07 (session 45), before either run was made: the order of the
suppression (``score_pool``, new in ``DetectParams``). The shipped detector suppresses in
cost order: a box is dropped when it overlaps any cheaper kept box, and only then are the
kept ``k`` re-ordered by their score (outline check, frame prior, shape context). A
giraffe's cheap neck-and-back match thus suppresses the dearer whole-animal match before
the score can prefer it. ``score_pool=N`` scores the ``N`` cheapest complete matches with
distinct boxes (near-duplicates at IoU > 0.7 left out) and suppresses in score order.
Runs ``score_pool=30`` and ``score_pool=100`` (``--param score_pool=N``; rows by
``ethz_template.py --param score_pool=N --rows``; N = 300 kept the same boxes as 100 on
the four giraffe images timed, at three times the cost, and was not run). They join the
same choice as a sixth and seventh run; adopted only if the setting chosen inside each
fold beats the shipped 0.836 held out (20% rule) and the median time stays under 1 s.

Added later on 2026-12-07, after ``score_pool`` 30 was adopted and before these runs were
made: two runs on top of it, ``nms_iou`` 0.5 (``--param nms_iou=0.5``) and 10 detections per
image (``--k 10``; named ``k=10``), the two changes that raised the ceiling of the cost-order
detections. Measured, not adopted this session whatever they score: adopting one means
re-running every edge source and refitting the re-scorer. They are scored against
``score_pool=30`` (now the shipped setting) in a second call of this script.

Added in session 46, after the within-image re-scorer shipped and before either score
below was seen: the runs on top of ``score_pool`` 30 (``shipped``, ``nms_iou=0.5``,
``k=10``) again, each class now scored by the shipped held-out procedure, the within-image
re-scorer (``--within NAME=RECORD``: the ``chosen_in_each_fold`` DR of
``ethz_within_image.py --rows <that run's rows>``). The setting of each fold is chosen by
the same proxy as above, which does not depend on the re-scorer (so the folds pick as
before: ``shipped`` for apple logos and bottles, ``k=10`` for the other three); the
setting the proxy picks on all five classes (``setting_on_all_five``: each class scored by
the proxy fitted on the other four) is the one that would ship. Adoption rule: adopt that
setting if it is not ``shipped``, the setting chosen in each fold scores higher held out
under the 20% rule than the shipped 0.8886 and not lower under PASCAL (0.8224), and the
median time stays under 1 s.

Added in session 47 (2026-12-07), before the run was made: ``nms_nested`` 0.8 on top of
``score_pool`` 30 (``--param nms_nested=0.8``, new in ``DetectParams``: a better kept box
lying inside a candidate by at least 80% of its area does not suppress it). Under PASCAL
33 of the 91 giraffes have no kept box at IoU >= 0.5; for 17 of them the best kept box
lies (by 79% or more) inside the true box at 17-62% of its area (14 wholly inside, at
17-49%): the neck is kept and the
whole animal, whose IoU with the neck exceeds ``nms_iou``, is suppressed. Of the 30 scored
candidates of each image, left unsuppressed, one overlaps 88% of the giraffes at IoU >=
0.5. The share 0.8 was picked, against 0.9, by a scratch simulation of the suppression on
those pools (giraffe, mug and bottle images, in view of their boxes): the share of objects
one of the 5 kept boxes overlaps at IoU >= 0.5 / 0.2 went, from ``nms_iou`` 0.3 alone,
giraffes 0.637 -> 0.758 / 0.967 -> 0.967, mugs 0.848 -> 0.848 / 0.924 -> 0.894, bottles
0.964 -> 0.964 / 0.982 -> 0.982 (0.9: giraffes 0.747, bottles 0.945 at 0.5). So the
setting is chosen in view of three classes' labels, and its held-out figures are not held
out as to it. Scored like the session 46 runs (``--within``; the proxy's per-fold choice
now among four settings). Adoption rule: adopt ``nms_nested`` 0.8 if its own rows' held-out
figure (``chosen_in_each_fold`` of ``ethz_within_image.py``) is higher under PASCAL than
the shipped 0.8224 and not lower under the 20% rule than 0.8886, and the median time stays
under 1 s; the proxy's choice is reported beside it.

Result, added after the run (``ethz_detector_params_nested_pb.json``): **not adopted**. Its
held-out figure is 0.8413 / 0.7927 (shipped 0.8886 / 0.8224): the ceiling at IoU >= 0.5
rises (``recall_any_k`` 0.876 -> 0.900, giraffes 0.637 -> 0.758) but no ranking puts the
whole animal above its neck (giraffes under PASCAL 0.560 in sample with the shipped
weights, 0.517 held out), and the part kept beside the whole is one more false positive
under the 20% rule. The proxy picks ``nms_nested`` in no fold.

Added in session 48 (2026-12-08), before any of its runs was made: ``upright_cost`` (new
in ``DetectParams``, 0 by default), an upright prior *in the stitching*: a contour matched
to a model interval of share ``f`` pays ``upright_cost * f * (1 - cos theta)``, ``theta``
the turn of the least-squares similarity taking the interval's samples onto the contour's
(``shapetree.detection._upright``). ``ethz_turned_context.py`` found 13 of the 56 true mug
boxes holding the model turned by a quarter, and ``ethz_upright.py`` that the turn of the
whole placement tells true from false (AUC 0.61-0.80) but adds nothing as a re-scorer
term: by then the rotation-invariant stitching has already chosen the turned match inside
the right box, or let a turned false match suppress it. Runs, all with the box refinement
off (``--param box_refine=None``: the rows hold match boxes, and ``ethz_box_refine.py``
refines them afterwards as for the shipped figure): ``shipped_off`` (the shipped settings),
``upright_cost=0.25`` and ``upright_cost=0.5``, the two values fixed by scale before any run
(a piece turned by a quarter over the whole model then pays 0.25 or 0.5, against
``gap_cost`` 0.8 for leaving it unmatched). Each run: rows (``ethz_template.py --param
box_refine=None [--param upright_cost=V] --rows``), its within-image record
(``ethz_within_image.py``), and its refined held-out record (``ethz_box_refine.py --rows
--within``, the refinement's setting chosen inside each fold), which is the record passed
here with ``--within``; the proxy chooses each fold's setting as above. Adoption rule: make
the value the default if the proxy's choice on all five classes (``setting_on_all_five``)
is an ``upright_cost`` run, the setting chosen in each fold scores higher held out under
the 20% rule than the shipped 0.8886 and not lower under PASCAL than 0.8414, and the
median time stays under 1 s.

Result, added after the runs (``ethz_detector_params_upright_pb.json``): **adopted**,
``upright_cost`` 0.25 the default. The setting chosen in each fold scores 0.9081 / 0.8607
held out (``upright_cost`` 0.5 in three folds, 0.25 for mugs and swans); the proxy picks
0.25 on all five classes (0.9007, against 0.8963 for 0.5 and 0.8617 for the shipped
detector); medians 0.43 s (0.25) and 0.48 s (0.5) per image and model against 0.42 s
for the shipped detector, the same day. Each run alone, held out with the boxes refined:
shipped 0.8886 / 0.8414 (session 47's figure reproduced), 0.25 0.8888 / 0.8356, 0.5
0.9050 / 0.8607: the value shipped by the rule is not the one that scores best held out,
and the headline is the figure of the whole choice, not of 0.25 alone. The one-call
reproduction::

    python3 benchmarks/ethz_detector_params.py shipped_off@R0 upright_cost=0.25@R1 \
        upright_cost=0.5@R2 --within shipped_off=B0 --within upright_cost=0.25=B1 \
        --within upright_cost=0.5=B2 --json benchmarks/results/ethz_detector_params_upright_pb.json

(The first attempt at ``shipped_off`` ran with the refinement on: ``DetectParams.as_dict``
dropped ``box_refine=None`` and the workers rebuilt the default. It was stopped, the bug
fixed (42ab0a9) and all three runs made after the fix.) With ``R*`` the rows and ``B*``
the ``ethz_box_refine.py`` records of the three runs
(``ethz_box_refine_pb_upright_0.25.json``, ``..._0.5.json`` and, for the shipped detector,
``ethz_box_refine_pb_rerun_session48.json``).

Mean DR at 0.4 FPPI under the 20% rule and under PASCAL's 50%. Usage::

    python3 benchmarks/ethz_detector_params.py shipped@ROWS gap_cost=0.6@ROWS ...

Writes ``benchmarks/results/ethz_detector_params_pb.json`` (or ``--json``).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import ethz_verify as V  # noqa: E402
from _ethz_rows import Rows, finish, held_line, held_record  # noqa: E402
from ethz_template import choose_in_folds  # noqa: E402

from shapetree.detection._ethz_eval import ETHZ_CLASSES, _iou  # noqa: E402

SHIPPED_L2 = 1000.0


def recall_any(sc, rows, thr: float) -> dict:
    """Share of each class's objects that one of their image's kept detections overlaps."""
    out = {}
    for c in ETHZ_CLASSES:
        idx = np.flatnonzero(sc.cls == c)
        by_key: dict = {}
        for i in idx:
            by_key.setdefault(rows[i]["key"], []).append(np.asarray(rows[i]["bbox"], float))
        hit = n = 0
        for key, g in sc.gts[c].items():
            for box in g:
                n += 1
                hit += any(_iou(b, box[None])[0] >= thr for b in by_key.get(key, []))
        out[c] = round(hit / max(n, 1), 4)
    out["mean"] = round(float(np.mean([out[c] for c in ETHZ_CLASSES])), 4)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", help="NAME@ROWS, the shipped settings first")
    ap.add_argument("--data", default=None)
    ap.add_argument("--json", default=None)
    ap.add_argument(
        "--within",
        action="append",
        default=[],
        help="NAME=RECORD: score run NAME held out by an ethz_within_image.py record "
        "(chosen_in_each_fold) instead of the global re-scorer; give one per run",
    )
    args = ap.parse_args()
    within = dict(w.rsplit("=", 1) for w in args.within)  # NAME may hold "="
    names = [spec.split("@", 1)[0] for spec in args.runs]
    if within and set(within) != set(names):
        ap.error(f"--within needs one NAME=RECORD per run: runs {names}, records {sorted(within)}")
    t0 = time.perf_counter()
    classes = list(ETHZ_CLASSES)
    runs: dict = {}
    for spec in args.runs:
        name, path = spec.split("@", 1)
        r = Rows.read(path, args.data)
        sc, label = r.sc, r.label
        if within:
            wr = json.loads(Path(within[name]).read_text())["chosen_in_each_fold"]
            chosen = wr["chosen"]
            held = {c: (wr["loco_overlap_20"][c], wr["loco_overlap_50"][c]) for c in classes}
        else:
            held, chosen = choose_in_folds(sc, label, r.candidates())
        x = r.matrix()
        inner = {
            c_out: {
                c: sc.dr(c, V._fit_score(x, label, ~np.isin(sc.cls, [c_out, c]), SHIPPED_L2))[0]
                for c in classes
                if c != c_out
            }
            for c_out in classes
        }
        on_all = [sc.dr(c, V._fit_score(x, label, sc.cls != c, SHIPPED_L2))[0] for c in classes]
        runs[name] = {
            "rows": path,
            "proxy_on_all_five": float(np.mean(on_all)),
            "held": held,
            "inner": inner,
            "record": held_record(held, chosen)
            | {
                "recall_any_k_overlap_20": recall_any(sc, r.rows, 0.2),
                "recall_any_k_overlap_50": recall_any(sc, r.rows, 0.5),
            },
        }
        rec = runs[name]["record"]
        print(
            f"{held_line(f'{name:14s}', rec)}  recall_any_k "
            f"{rec['recall_any_k_overlap_20']['mean']:.3f} / "
            f"{rec['recall_any_k_overlap_50']['mean']:.3f}",
            flush=True,
        )
    held, chosen = {}, {}
    for c_out in classes:
        mean = {n: float(np.mean(list(runs[n]["inner"][c_out].values()))) for n in names}
        best = max(mean.values())
        pick = next(n for n in names if mean[n] == best)
        chosen[c_out] = {"setting": pick, "inner_mean": round(best, 4)}
        held[c_out] = runs[pick]["held"][c_out]
    out: dict = {
        "protocol": __doc__,
        "runs": {n: runs[n]["record"] | {"rows": runs[n]["rows"]} for n in names},
        "setting_chosen_in_each_fold": held_record(held, chosen),
        "setting_on_all_five": max(
            names, key=lambda n: (runs[n]["proxy_on_all_five"], -names.index(n))
        ),
        "proxy_on_all_five": {n: round(runs[n]["proxy_on_all_five"], 4) for n in names},
    }
    if within:
        out["within_records"] = within
    print(
        f"{held_line('setting chosen in each fold:', out['setting_chosen_in_each_fold'])} "
        f"{ {c: v['setting'] for c, v in chosen.items()} }; on all five: "
        f"{out['setting_on_all_five']} {out['proxy_on_all_five']}"
    )
    finish(out, args, t0, "ethz_detector_params.py", "ethz_detector_params_pb.json")


if __name__ == "__main__":
    main()
