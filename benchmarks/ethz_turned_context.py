"""ETHZ: do right detections fail the context check because their placement is turned?

A diagnosis, not a method (session 47). ``ethz_misses.py --within`` leaves mugs the weakest
class held out (0.727), and a look at the mug photos shows right boxes (IoU 0.9 with the
true mug) whose shape-context agreement (``context``, computed in the image frame, so an
upright placement agrees more than one on its side) is near 0.1: the model is placed
turned by a quarter, the handle on the rim. For every kept detection of a run this script
computes the agreement of the model with its placement turned back by 0, 90, 180 and 270
degrees about its centroid, and reports per class:

- ``right_low_context``: the share of right detections (IoU >= 0.5) with ``context`` < 0.3,
  and with the best of the four turns (``turned_context``) < 0.3;
- ``auc``: how well each of the two tells right (IoU >= 0.2) from wrong detections of the
  class (the area under the ROC curve, 0.5 = chance);
- ``best_turn_of_right_low``: for the right detections with ``context`` < 0.3, which turn
  agrees best (counts; 0 = as placed).

A term that helps one class and hurts another cannot be learnt by the held-out protocol
(fitted on the other four classes), which is why this is reported and not tried as a
re-scorer term. Usage::

    python3 benchmarks/ethz_turned_context.py --rows ROWS --detections CACHE_DIR

(``ROWS`` of ``ethz_template.py --rows``, ``CACHE_DIR`` the run's ``cache_dir``.) Writes
``benchmarks/results/ethz_turned_context_pb.json`` (or ``--json``).
"""

from __future__ import annotations

import json
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np
from scipy.stats import mannwhitneyu

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _ethz_rows import finish, parser  # noqa: E402

from shapetree.detection import context_agreement  # noqa: E402
from shapetree.detection._ethz_eval import ETHZ_CLASSES, ethz_root  # noqa: E402
from shapetree.detection._model import load_model  # noqa: E402

TURNS = (0, 90, 180, 270)
LOW = 0.3


def turned(points: np.ndarray, quarters: int) -> np.ndarray:
    """``points`` (n, 2) turned by ``quarters`` x 90 degrees about their centroid."""
    c = points.mean(0)
    q = points - c
    for _ in range(quarters % 4):
        q = np.c_[-q[:, 1], q[:, 0]]
    return q + c


def auc(score: np.ndarray, right: np.ndarray) -> float:
    """Area under the ROC curve of ``score`` for ``right`` against the rest."""
    u = mannwhitneyu(score[right], score[~right]).statistic
    return float(u / (right.sum() * (~right).sum()))


def placements(rows: list[dict], cache: Path) -> list[np.ndarray]:
    """The image points of every row, from the run's per-image cache (matched by box)."""
    docs: dict[Path, dict] = {}
    out = []
    for r in rows:
        folder, stem = r["key"].split("/")
        path = cache / r["cls"] / f"{folder}__{stem}.json"
        if path not in docs:
            docs[path] = json.loads(path.read_text())
        same = [d for d in docs[path]["detections"] if np.allclose(d["bbox"], r["bbox"])]
        if len(same) != 1:
            raise SystemExit(f"{r['key']}: {len(same)} cached detections with the row's box")
        out.append(np.asarray(same[0]["image_points"], float))
    return out


def main() -> None:
    ap = parser(__doc__)
    ap.add_argument("--detections", required=True, help="the run's cache_dir (eval_ethz.py)")
    args = ap.parse_args()
    t0 = time.perf_counter()
    root = ethz_root(args.data)
    rows = json.loads(Path(args.rows).read_text())
    models = {
        c: load_model(root / "models" / f"{ETHZ_CLASSES[c][1]}.tif", m=30).points
        for c in ETHZ_CLASSES
    }
    ctx = np.zeros((len(rows), len(TURNS)))
    for i, (r, pts) in enumerate(zip(rows, placements(rows, Path(args.detections)), strict=True)):
        ctx[i] = [context_agreement(models[r["cls"]], turned(pts, q)) for q in range(4)]
    stored = np.array([r["context"] for r in rows])
    if not np.allclose(ctx[:, 0], stored, atol=1e-9):
        raise SystemExit("the context as placed differs from the rows' (another run?)")
    cls = np.array([r["cls"] for r in rows])
    iou = np.array([r["iou"] for r in rows])
    best = ctx.max(1)
    out: dict = {"protocol": __doc__, "rows": args.rows, "detections": args.detections}
    per: dict = {}
    for c in ETHZ_CLASSES:
        m = cls == c
        right, hit = iou[m] >= 0.5, iou[m] >= 0.2
        low = right & (ctx[m, 0] < LOW)
        per[c] = {
            "right": int(right.sum()),
            "right_low_context": round(float(np.mean(ctx[m, 0][right] < LOW)), 3),
            "right_low_turned_context": round(float(np.mean(best[m][right] < LOW)), 3),
            "auc": {
                "context": round(auc(ctx[m, 0], hit), 3),
                "turned_context": round(auc(best[m], hit), 3),
            },
            "best_turn_of_right_low": {
                str(TURNS[k]): v for k, v in sorted(Counter(ctx[m][low].argmax(1)).items())
            },
        }
        low_turned = per[c]["right_low_turned_context"]
        print(
            f"{c:10s} right {per[c]['right']:3d}: context < {LOW} in "
            f"{per[c]['right_low_context']:.2f} (best turn {low_turned:.2f});"
            f" AUC context {per[c]['auc']['context']:.3f}, turned "
            f"{per[c]['auc']['turned_context']:.3f}; best turn of the low ones "
            f"{per[c]['best_turn_of_right_low']}"
        )
    out["per_class"] = per
    finish(out, args, t0, "ethz_turned_context.py", "ethz_turned_context_pb.json")


if __name__ == "__main__":
    main()
