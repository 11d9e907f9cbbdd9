"""Should the 3-tree presets average their trees? A held-out adoption test (issue 15, item 4)

The ``kimia99`` and ``mpeg7`` presets match with three shape-trees; until this test they
kept the best one (``tree_combine="min"``, as the paper does). ``eval_tree_combine.py``
found the trees' mean better in 13 of 18 comparisons of the issue-15 grid, but no preset was
changed: a preset is tuned on its own set, and an option may join it only if it wins
*without* being tuned on that set. This script makes that test for each 3-tree preset:

* the preset's configuration, once with ``tree_combine="min"`` and once with ``"mean"``,
  every other field unchanged, is scored pairwise on the selection subsets of the **other
  two** sets (those of ``eval_beyond.py``: Kimia-99 all 99, rank-row sum; MPEG-7 35
  classes x 4, bull's-eye over 8; Swedish leaf 15 x 10, 1-NN over 10 splits);
* the rule, fixed before any score was seen: the mean is adopted into the preset when it
  scores at least the minimum's on both other sets and more on at least one; otherwise
  the preset keeps the minimum.

The preset's own set is never scored here. Where the mean is adopted, the preset's full
run on its own set is redone afterwards (``shapetree evaluate SET --preset SET``) and its
result is that preset's figure, still tuned on that set in every other field.

Run::

    SHAPETREE_DATA=/work/shared/datasets nice python3 benchmarks/eval_preset_tree_mean.py

Writes ``benchmarks/results/preset_tree_mean.json`` and prints a table (542 s on the two
cores of an Intel Xeon machine; distance tables are cached, ``--cache-dir``).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
import eval_beyond as base  # noqa: E402
from _common import RESULTS, machine, write_json  # noqa: E402

from shapetree.matching import PRESETS, MatchConfig  # noqa: E402
from shapetree.retrieval import combine, directed_costs  # noqa: E402

#: The presets with more than one shape-tree, where ``tree_combine`` matters.
PRESETS_TESTED = ("kimia99", "mpeg7")
COMBINES = ("min", "mean")


def adopt(scores: dict[str, dict[str, float]]) -> bool:
    """The rule: ``{other set: {"min": s, "mean": s}}`` -> whether the mean is adopted
    (at least the minimum's score on every other set, more on at least one)."""
    return all(v["mean"] >= v["min"] for v in scores.values()) and any(
        v["mean"] > v["min"] for v in scores.values()
    )


def subset_scores(
    preset: str, cfg: MatchConfig, cache: Path | None
) -> tuple[dict[str, dict[str, float]], dict[str, Any]]:
    """Scores of ``cfg`` with each tree combination on the other sets' selection subsets,
    and the Kimia-99 rows where Kimia-99 is one of them."""
    scores: dict[str, dict[str, float]] = {}
    extra: dict[str, Any] = {}
    for name in base.TARGETS:
        if name == preset:
            continue
        curves, labels = base.load_subset(name)
        for comb in COMBINES:
            t0 = time.perf_counter()
            costs = directed_costs(
                curves, None, cfg.replace(tree_combine=comb), cache_dir=cache, progress=False
            )
            D = combine(costs, cfg.symmetrize)
            score = round(base.subset_score(name, D, labels), 3)
            scores.setdefault(name, {})[comb] = score
            if name == "kimia99":
                extra[f"kimia99_ranks_{comb}"] = [int(x) for x in base.kimia_ranks(D, labels)]
            dt = time.perf_counter() - t0
            print(f"  {preset:8s} on {name:13s} {comb:4s} {score:8.3f}  ({dt:.0f} s)", flush=True)
    return scores, extra


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cache-dir", type=Path, default=None, help="distance-table cache")
    ap.add_argument("--json", type=Path, default=RESULTS / "preset_tree_mean.json")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    out: dict[str, Any] = {
        "command": "python3 benchmarks/eval_preset_tree_mean.py",
        "measure": "pairwise: each distance depends only on the two shapes (no re-ranking)",
        "rule": " ".join(adopt.__doc__.split("->")[1].split()),
        "subsets": {
            k: {"every_nth_class": s, "per_class": p} for k, (s, p) in base.SUBSETS.items()
        },
        "presets": {},
    }
    for preset in PRESETS_TESTED:
        cfg = PRESETS[preset]
        assert cfg.n_trees > 1, preset  # both combinations are scored whatever it holds now
        scores, extra = subset_scores(preset, cfg, args.cache_dir)
        verdict = adopt(scores)
        out["presets"][preset] = {
            "scored_on": sorted(scores),
            "scores": scores,
            **extra,
            "adopt_mean": verdict,
        }
        says = "adopt the mean" if verdict else "keep the minimum"
        print(f"{preset}: {says} {scores}", flush=True)
    out["seconds"] = round(time.perf_counter() - t0, 1)
    out["machine"] = machine()
    write_json(args.json, out)
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
