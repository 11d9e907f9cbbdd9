"""Calibrate the own edge map's affine scale to the Pb maps' strength (issue 14, item 2).

``shapetree.detection._boundary`` maps its thinned boundary energy ``E`` to
``p = clip((E - E_OFFSET) / E_RANGE, 0, 1)``, one fixed map for every image, so that the
contour tracer's thresholds (chosen on Pb) mean the same on the own map. This script sets
the two constants the way the module's docstring says:

1. 20 ETHZ images, 4 per class evenly spaced in each class's list sorted by file name
   (``own_edge_weights.images(root, per_class=4)``); no ground-truth box or mask is read.
2. For each Pb strength ``t`` in 0.05, 0.15, 0.3, 0.5: the median over the images of the
   share of Pb pixels above ``t``, and the energy ``q_t`` at which the median share of own
   pixels above ``q_t`` is the same (bisection).
3. A least-squares line ``q_t = E_OFFSET + E_RANGE * t``.

The shipped constants (0.155 / 0.61) were set this way for the module's earlier scale
rule (images reduced to 640 px on their longer side when larger, never enlarged), on 20
images that were not recorded. When the scale rule changed (every image resampled to
``WORK_SIDE``), the constants were *carried over* rather than refitted from scratch, so
that the change of scale is the only change: the energies of both rules on these 20
images are matched at the four shares (step 2 for each rule), a line ``E_old ≈ α + β
E_new`` is fitted through the four pairs, and the new constants are those that map
``E_new`` to the shipped ``p`` of ``E_old``: ``E_OFFSET = (0.155 - α) / β``,
``E_RANGE = 0.61 / β``. The JSON holds both rules' own fits too.

When the colour cues moved from 2 and 4 px to ``COLOUR_SCALES`` (4 and 8 px), the
constants were carried over once more the same way, from the work-side map with the
earlier colour scales (whose constants are the first step's result) to the map with the
new ones: ``carried_over_colour``. The module ships that second result. Run::

    SHAPETREE_DATA=/work/shared/datasets python3 benchmarks/own_edge_calibration.py

Writes ``benchmarks/results/own_edge_calibration.json`` (with ``--json``, elsewhere).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, machine, write_json  # noqa: E402
from own_edge_weights import CAL_THRESHOLDS, images, share_levels  # noqa: E402

from shapetree.detection import _boundary as B  # noqa: E402
from shapetree.detection import load_edges, load_image  # noqa: E402
from shapetree.detection._edges import _as_channels  # noqa: E402
from shapetree.detection._ethz_eval import ethz_root  # noqa: E402


def fit(energies: list[np.ndarray], pbs: list[np.ndarray]) -> dict:
    """``E_OFFSET``, ``E_RANGE`` and the matched quantiles (step 2 and 3)."""
    target, qs = share_levels(energies, pbs)
    slope, off = np.polyfit(CAL_THRESHOLDS, qs, 1)
    return {
        "e_offset": round(float(off), 4),
        "e_range": round(float(slope), 4),
        "pb_median_share": [round(float(x), 5) for x in target],
        "own_energy_at_share": [round(float(x), 4) for x in qs],
    }


OLD_OFFSET, OLD_RANGE = 0.155, 0.61
#: The colour cues' scales before they moved to ``B.COLOUR_SCALES``.
EARLIER_COLOUR_SCALES = (2.0, 4.0)


def _energies(root: Path, names: list[tuple[str, str]], rule: str) -> list[np.ndarray]:
    """Thinned energies under a scale rule ("downscale-only", "work-side") and colour
    scales ("earlier colour": ``EARLIER_COLOUR_SCALES``; otherwise the module's)."""
    scale, colour = B.working_scale, B.COLOUR_SCALES
    if rule.startswith("downscale-only"):
        B.working_scale = lambda h, w: min(1.0, 640 / max(h, w))
    if rule.endswith("earlier colour"):
        B.COLOUR_SCALES = EARLIER_COLOUR_SCALES
    try:
        return [B.thinned_energy(_as_channels(load_image(root / c / f"{s}.jpg"))) for c, s in names]
    finally:
        B.working_scale, B.COLOUR_SCALES = scale, colour


def carry(fits: dict, old: str, new: str, offset: float, range_: float) -> dict:
    """Constants that give rule ``new``'s energies the ``p`` that ``offset`` / ``range_``
    give rule ``old``'s: a line ``E_old = alpha + beta E_new`` through the matched
    energies."""
    e_old = np.array(fits[old]["own_energy_at_share"])
    e_new = np.array(fits[new]["own_energy_at_share"])
    beta, alpha = np.polyfit(e_new, e_old, 1)
    return {
        "from": old,
        "to": new,
        "e_offset": round(float((offset - alpha) / beta), 4),
        "e_range": round(float(range_ / beta), 4),
        "alpha": round(float(alpha), 4),
        "beta": round(float(beta), 4),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--data", default=None)
    ap.add_argument("--json", default=str(RESULTS / "own_edge_calibration.json"))
    args = ap.parse_args(argv)
    root = ethz_root(args.data)
    t0 = time.perf_counter()
    names = images(root, per_class=4)
    pbs = [load_edges(root / c / f"{s}_edges.tif") for c, s in names]
    rules = ("downscale-only, earlier colour", "work-side, earlier colour", "work-side")
    fits = {rule: fit(_energies(root, names, rule), pbs) for rule in rules}
    carried = carry(fits, rules[0], rules[1], OLD_OFFSET, OLD_RANGE)
    colour = carry(fits, rules[1], rules[2], carried["e_offset"], carried["e_range"])
    out = {
        "command": "python3 benchmarks/own_edge_calibration.py " + " ".join(argv or sys.argv[1:]),
        "work_side": B.WORK_SIDE,
        "images": [f"{c}/{s}" for c, s in names],
        "thresholds": list(CAL_THRESHOLDS),
        "fits": fits,
        "carried_over": carried,
        "colour_scales": {"earlier": list(EARLIER_COLOUR_SCALES), "now": list(B.COLOUR_SCALES)},
        "carried_over_colour": colour,
        "earlier_constants": {"e_offset": OLD_OFFSET, "e_range": OLD_RANGE},
        "module_now": {"e_offset": B.E_OFFSET, "e_range": B.E_RANGE},
        "seconds": round(time.perf_counter() - t0, 1),
        "machine": machine(),
    }
    write_json(Path(args.json), out)
    for rule, r in fits.items():
        print(f"fit, {rule:15s}: E_OFFSET {r['e_offset']:.4f}  E_RANGE {r['e_range']:.4f}")
    for c in (carried, colour):
        print(
            f"carried over from {c['from']} to {c['to']}: E_OFFSET {c['e_offset']:.4f}  "
            f"E_RANGE {c['e_range']:.4f}"
        )
    print(f"module now {B.E_OFFSET} / {B.E_RANGE}")
    print(f"json: {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
