"""One knob on a base configuration, chosen held out: the driver shared by
``eval_global_term.py``, ``eval_length_power.py`` and ``eval_height_function.py``.

Each of those scripts varies one value (a weight ``w`` or a power ``p``) over a grid fixed in
advance, scores every value on the three selection subsets of ``eval_beyond.py``, chooses the
value for each target set by the best mean rank on the *other two* subsets, and scores the
choice on the full set when asked (``--full NAME``). The value that switches the knob off
(``Knob.off``) needs no full run: the base configuration's committed score stands.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import eval_beyond as base  # noqa: E402
from _common import RESULTS, machine, write_json  # noqa: E402

#: the protocol parameters of the full sets (``evaluate``'s defaults)
PROTOCOL = {"k": 40, "n_train": 25, "n_splits": 10, "seed": 0}
FULL_SETS = ("mpeg7", "swedish_leaf")


@dataclass(frozen=True)
class Knob:
    """What one script varies.

    Attributes
    ----------
    script : str
        The script's file name, for the commands recorded in the JSON.
    symbol : str
        The knob's name in the JSON and the output (``w``, ``p``).
    grid : tuple of float or str
        The values tried, fixed before any score was seen.
    off : float or str
        The value that leaves the base configuration as it is.
    json_name : str
        The results file in ``benchmarks/results/``.
    base_full : str
        Where the base configuration's full-set scores were made (a JSON key and command,
        with ``{name}`` for the set); by default ``eval_tree_combine.py``'s runs of the base
        ``n64 T3 none tmean``.
    """

    script: str
    symbol: str
    grid: tuple[Any, ...]
    off: Any
    json_name: str
    base_full: str = (
        "beyond_paper_tree_mean.json full_runs.{name} (python3 "
        "benchmarks/eval_tree_combine.py --full {name})"
    )

    def tie(self, v: Any) -> tuple[float, float]:
        """How a value ranks among equals: nearer ``off`` first, then the smaller (numbers);
        earlier in the grid first (any other value)."""
        if isinstance(v, (int, float)):
            return abs(v - self.off), v
        return float(self.grid.index(v)), 0.0


def grid_scores(
    name: str, labels: np.ndarray, grid: tuple[float, ...], matrix: Callable[[float], np.ndarray]
) -> dict[str, Any]:
    """The selection score of ``matrix(value)`` on the subset of ``name`` for every value
    of the grid (keys ``str(value)``), and for Kimia-99 its rank rows too."""
    rec: dict[str, Any] = {"scores": {}}
    for v in grid:
        D = matrix(v)
        rec["scores"][str(v)] = round(base.subset_score(name, D, labels), 3)
        if name == "kimia99":
            rec.setdefault("ranks", {})[str(v)] = [int(r) for r in base.kimia_ranks(D, labels)]
    return rec


def full_base(name: str, config: Any, cache: Path) -> tuple[list, np.ndarray, np.ndarray, float]:
    """A full set's traced outlines, labels, base matrix (``directed_costs`` through the
    cache, not symmetrised) and the seconds that matrix took this run (~0 when cached)."""
    from shapetree import datasets
    from shapetree.retrieval import combine, directed_costs

    ds = datasets.load(name, n_points=None, progress=False)
    t0 = time.perf_counter()
    D = combine(directed_costs(ds.curves, None, config, cache_dir=cache, progress=True), "none")
    return ds.curves, np.asarray(ds.labels), D, time.perf_counter() - t0


def slim(rec: dict[str, Any]) -> dict[str, Any]:
    """A protocol record without its per-class and per-split lists."""
    rec.pop("bullseye_per_class", None)
    rec.pop("accuracy_splits", None)
    return rec


def choose(knob: Knob, target: str, subsets: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """The value with the best mean rank on the subsets of the two sets other than
    ``target`` (ranks as ``eval_beyond.mean_ranks``; ties as :meth:`Knob.tie`)."""
    others = tuple(n for n in base.TARGETS if n != target)
    keys = [str(v) for v in knob.grid]
    scores = {n: {k: {"score": subsets[n]["scores"][k]} for k in keys} for n in others}
    mr = {k: float(v) for k, v in base.mean_ranks(scores, others, keys).items()}
    chosen = min(knob.grid, key=lambda v: (mr[str(v)], *knob.tie(v)))
    return {"selected_on": list(others), "mean_rank": mr, f"chosen_{knob.symbol}": chosen}


def run(
    knob: Knob,
    doc: str,
    argv: list[str] | None,
    header: dict[str, Any],
    subset_scores: Callable[[Path], dict[str, dict[str, Any]]],
    full_score: Callable[[str, float, Path], dict[str, Any]],
    finish: Callable[[dict[str, Any], Path], None] | None = None,
) -> int:
    """Parse the command line, score the subsets, choose held out, run the full sets asked
    for, and write the JSON (after every stage, so a killed run leaves what it finished).

    ``header`` goes into the JSON after the command and the measure. ``subset_scores(cache)``
    returns, per set, ``{"scores": {str(value): score}}`` (Kimia-99 also ``"ranks"``);
    ``full_score(name, value, cache)`` returns the full set's record; ``finish(out, cache)``,
    if given, adds the script's own last records to the output before it is written.
    """
    ap = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--cache-dir", default=str(Path.home() / ".cache/shapetree/beyond"))
    ap.add_argument("--json", default=str(RESULTS / knob.json_name))
    ap.add_argument("--full", nargs="*", default=[], choices=FULL_SETS)
    args = ap.parse_args(argv)
    cache = Path(args.cache_dir)
    cache.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    path = Path(args.json)
    s = knob.symbol
    out: dict[str, Any] = {
        "command": f"python3 benchmarks/{knob.script} " + " ".join(argv or sys.argv[1:]),
        "measure": "pairwise: each distance depends only on the two shapes (no re-ranking)",
        **header,
        "full_runs": {},
    }
    if path.exists():  # keep the full runs of sets not rerun now
        kept = json.loads(path.read_text()).get("full_runs", {})
        out["full_runs"] = {k: v for k, v in kept.items() if k not in args.full}
    out["subsets"] = subset_scores(cache)
    out["held_out_choice"] = {t: choose(knob, t, out["subsets"]) for t in base.TARGETS}
    vk = out["held_out_choice"]["kimia99"][f"chosen_{s}"]
    ranks = out["subsets"]["kimia99"]["ranks"]
    out["kimia99_held_out"] = {
        s: vk,
        "row": ranks[str(vk)],
        "row_without": ranks[str(knob.off)],
        "paper": base.PAPER["kimia99"],
        "scored_on": "the full set (99 shapes): its selection subset is the whole set",
    }
    write_json(path, out)
    print(f"\n{'target':13s} chosen {s}  mean ranks on the other two sets")
    for t, c in out["held_out_choice"].items():
        print(f"{t:13s} {c[f'chosen_{s}']:<9} {c['mean_rank']}")
    k = out["kimia99_held_out"]
    print(f"Kimia-99 ({s} = {vk}): {k['row']} ({sum(k['row'])}), without {sum(k['row_without'])}")
    for name in args.full:
        v = out["held_out_choice"][name][f"chosen_{s}"]
        if v == knob.off:  # the knob is off: the score is the base configuration's own
            print(f"{name}: {s} = {v}, the base configuration's full score stands (no run)")
            out["full_runs"][name] = {s: v, "see": knob.base_full.format(name=name)}
            continue
        rec = full_score(name, v, cache)
        rec["command"] = f"python3 benchmarks/{knob.script} --full {name}"
        rec["machine"] = machine()
        out["full_runs"][name] = rec
        out["seconds"] = round(time.perf_counter() - t0, 1)
        write_json(path, out)
        shown = {a: b for a, b in rec.items() if a not in ("command", "machine")}
        print(f"{name}: {s} = {v}: {shown}", flush=True)
    if finish is not None:
        finish(out, cache)
    out["seconds"] = round(time.perf_counter() - t0, 1)
    out["machine"] = machine()
    write_json(path, out)
    print(f"json: {path}")
    return 0
