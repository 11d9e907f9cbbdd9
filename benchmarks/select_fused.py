"""The ``fused`` preset: the height-function fusion chosen on all three sets (issue 15, item 4)

``eval_height_variants.py`` scores 49 values (``w = 0`` and 6 height-function forms x 8
fusion weights ``w``) on the selection subsets of the three sets, on the base ``n64 T3 none
tmean`` (itself the held-out choice within the 65-minute budget for MPEG-7 and Swedish leaf,
README "Beyond the paper"), and chooses each set's value on the *other two* subsets. Each of
those three held-out choices beats ``w = 0`` on the full set it was not chosen on (MPEG-7
87.14 -> 88.82, Swedish leaf 94.12 -> 95.89, Kimia-99 964 -> 972): the fusion wins without
being tuned on the set it is scored on, which is the issue's rule for a preset.

The preset is then chosen the way ``general`` was (``select_general.py``): the value with the
best mean rank over **all three** subsets (ties: ``eval_height_variants``'s order). This
script reads the committed scores and does no matching:

* ``beyond_paper_height_variants.json``: the subset scores, the held-out choices, MPEG-7's
  full run and Kimia-99's rows (its subset is the whole set);
* ``swedish_cv.json``: every value's full Swedish-leaf accuracy.

It prints the choice, what it scores on each full set (chosen with that set in view, like
``general``'s own row) beside each set's held-out estimate, and writes
``benchmarks/results/preset_fused.json``. ``shapetree.matching.PRESETS["fused"]`` must be the
choice (``tests/test_benchmarks_selection.py`` checks it). Run::

    python3 benchmarks/select_fused.py
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import asdict
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
import eval_beyond as base  # noqa: E402
import eval_height_variants as hv  # noqa: E402
from _common import RESULTS, write_json  # noqa: E402

from shapetree.matching import MatchConfig  # noqa: E402


def choose_all(subsets: dict[str, dict[str, Any]]) -> tuple[str, dict[str, float]]:
    """The grid value with the best mean rank over every set's subset, and the mean ranks."""
    keys = [str(v) for v in hv.GRID]
    names = tuple(base.TARGETS)
    scores = {n: {k: {"score": subsets[n]["scores"][k]} for k in keys} for n in names}
    mr = {k: float(v) for k, v in base.mean_ranks(scores, names, keys).items()}
    return min(hv.GRID, key=lambda v: (mr[str(v)], *hv.KNOB.tie(v))), mr


def as_config(value: str) -> MatchConfig:
    """A grid value as the library's configuration (the base with the fusion switched on);
    the form must be one the library computes (harmonic weights, ``round(3 n / 64)``)."""
    hp, w = hv.parse(value)
    cfg = hv.hf.CONFIG
    if hp is None:
        return cfg
    if (hp.weighting, hp.group) != ("harmonic", max(1, round(3 * hp.n_points / 64))):
        raise ValueError(f"{value!r} is not a form the library's height_points gives")
    return cfg.replace(
        height_weight=w, height_points=hp.n_points, height_complexity=bool(hp.complexity)
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--json", default=str(RESULTS / "preset_fused.json"))
    args = ap.parse_args(argv)
    hvj = json.loads((RESULTS / "beyond_paper_height_variants.json").read_text())
    swj = json.loads((RESULTS / "swedish_cv.json").read_text())
    chosen, mr = choose_all(hvj["subsets"])
    mp = hvj["full_runs"]["mpeg7"]
    [mp_form] = [label for label, hp in hv.FORMS.items() if asdict(hp) == mp["form"]]
    mp_value = f"{mp_form} w={mp['w']}"
    sw_value = hvj["held_out_choice"]["swedish_leaf"]["chosen_form_w"]
    kimia_rows = hvj["subsets"]["kimia99"]["ranks"]
    full = {
        "kimia99": {
            "preset": {"row": kimia_rows[chosen], "sum": sum(kimia_rows[chosen])},
            "held_out": hvj["kimia99_held_out"] | {"sum": sum(hvj["kimia99_held_out"]["row"])},
            "without_fusion": sum(kimia_rows[hv.OFF]),
        },
        "mpeg7": {
            "preset": {"bullseye": mp["with"]["bullseye"]} if mp_value == chosen else None,
            "held_out": {"form_w": mp_value, "bullseye": mp["with"]["bullseye"]},
            "without_fusion": mp["without"]["bullseye"],
        },
        "swedish_leaf": {
            "preset": {"accuracy_mean": swj["in_sample_accuracy_by_value"][chosen]},
            "held_out": {
                "form_w": sw_value,
                "accuracy_mean": swj["in_sample_accuracy_by_value"][sw_value],
                "by_species": swj["held_out_by_species"]["accuracy_mean"],
                "by_training_leaves": swj["held_out_by_training_leaves"]["accuracy_mean"],
            },
            "without_fusion": swj["in_sample_accuracy_by_value"][hv.OFF],
        },
    }
    out = {
        "command": "python3 benchmarks/select_fused.py",
        "measure": "pairwise: each distance depends only on the two shapes (no re-ranking)",
        "protocol": " ".join(__doc__.split("\n\n")[1:3]).replace("\n", " "),
        "chosen": chosen,
        "config": as_config(chosen).as_dict(),
        "mean_rank_top": dict(sorted(mr.items(), key=lambda kv: kv[1])[:6]),
        "full_sets": full,
        "sources": ["beyond_paper_height_variants.json", "swedish_cv.json"],
    }
    write_json(Path(args.json), out)
    print(f"chosen on all three subsets: {chosen} (mean rank {mr[chosen]:.2f})")
    print(f"{'set':13s} {'w = 0':>8s} {'preset (in view)':>18s} {'held out':>10s}")
    k = full["kimia99"]
    print(
        f"{'kimia99':13s} {k['without_fusion']:>8d} {k['preset']['sum']:>18d} "
        f"{k['held_out']['sum']:>10d}"
    )
    m = full["mpeg7"]
    pm = m["preset"]["bullseye"] if m["preset"] else float("nan")
    print(
        f"{'mpeg7':13s} {m['without_fusion']:>8.2f} {pm:>18.2f} {m['held_out']['bullseye']:>10.2f}"
    )
    s = full["swedish_leaf"]
    print(
        f"{'swedish_leaf':13s} {s['without_fusion']:>8.2f} {s['preset']['accuracy_mean']:>18.2f} "
        f"{s['held_out']['accuracy_mean']:>10.2f}"
    )
    print(f"json: {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
