"""The issue-15 matcher options against the directed Procrustes matcher, pairwise, on subsets.

Each option is scored against the directed Procrustes shape-tree matcher with **the same
other settings**, on fixed subsets of the three retrieval sets (the full sets are too slow
for the single-pair matchers on two shared cores):

* Kimia-99: all 9 classes x the first 4 shapes (36 shapes);
* MPEG-7: 10 classes (every 7th of the 70 sorted names) x the first 4 shapes (40);
* Swedish leaf: all 15 classes x the first 3 leaves (45).

Comparisons (the base configuration of each, then the option changed on top of it):

* ``dif``: the ``general`` preset (n = 50, 4 phases, band 3, mirror) vs ``dif=hyperbolic``
  (the batched engine, :func:`shapetree.retrieval.distance_matrix`);
* ``matcher``: ``general`` with ``n_points=24, phases=1`` vs ``matcher=symmetric`` (each
  unordered pair once, :func:`shapetree.matching._api.pair_cost`); the directed matcher's
  ``symmetrize=mean`` (an average of two directed costs) is listed for reference;
* ``replace_any``: ``general`` with ``n_points=16, phases=1, occlusion=1`` (replacement of
  subtrees) vs ``replace_any=True`` (any part; every ordered pair).

Scores on a subset (pairwise, the query itself included in the ranking as in the full
protocols): MPEG-7 bull's-eye with ``k = 2 x 4`` (the protocol's "twice the class size");
Kimia-99 the count of same-class shapes at ranks 1..3 (the protocol's row, 3 ranks for 3
other class members; maximum 36 each) and their sum; for every set the leave-one-out
nearest-neighbour accuracy (Swedish leaf's protocol measure, 1-NN, on the subset without
train/test splits). Nothing here is adopted into a preset (README, issue 15 item 4).

Run (about 5-8 minutes on one core)::

    SHAPETREE_DATA=/work/shared/datasets nice -n 10 python benchmarks/eval_options.py

Writes ``benchmarks/results/options.json``. ``--full-kimia`` scores the ``dif`` comparison
on the whole of Kimia-99 with the protocol's ten ranks (the batched engine makes that
affordable, a few minutes) and stores it under ``full`` in the same file, keeping the
subset results already there.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, machine, write_json  # noqa: E402

from shapetree.datasets import load, load_labels  # noqa: E402
from shapetree.matching import MatchConfig  # noqa: E402
from shapetree.matching._api import pair_cost  # noqa: E402
from shapetree.retrieval import bullseye, distance_matrix, kimia_ranks  # noqa: E402

PER_CLASS = {"kimia99": 4, "mpeg7": 4, "swedish_leaf": 3}


def subset(name: str):
    """The fixed subset of a set (module docstring)."""
    _, labels, _ = load_labels(name)
    classes = sorted(set(labels.tolist()))
    if name == "mpeg7":
        classes = classes[::7]
    ds = load(name, classes=classes, per_class=PER_CLASS[name], progress=False)
    return ds.curves, np.asarray(ds.labels), classes


def loo_nn(D: np.ndarray, labels: np.ndarray) -> float:
    """Leave-one-out 1-NN accuracy (the query itself excluded)."""
    E = np.array(D, dtype=float)
    np.fill_diagonal(E, np.inf)
    return float(np.mean(labels[np.argmin(E, axis=1)] == labels))


def scores(name: str, D: np.ndarray, labels: np.ndarray) -> dict:
    out = {"loo_1nn": loo_nn(D, labels)}
    k = PER_CLASS[name]
    if name == "mpeg7":
        out["bullseye"] = float(bullseye(D, labels, k=2 * k))
    if name == "kimia99":
        row = kimia_ranks(D, labels, n_ranks=k - 1)
        out["ranks"] = [int(x) for x in row]
        out["ranks_sum"] = int(np.sum(row))
    out["headline"] = out.get("bullseye", out.get("ranks_sum", out["loo_1nn"]))
    return out


def pairwise(curves: list, cfg: MatchConfig, *, symmetric: bool) -> np.ndarray:
    """Every pair through :func:`pair_cost` (each unordered pair once when symmetric)."""
    n = len(curves)
    D = np.zeros((n, n))
    for i in range(n):
        for j in range(i if symmetric else 0, n):
            D[i, j] = pair_cost(curves[i], curves[j], cfg)
            if symmetric:
                D[j, i] = D[i, j]
    return D


def engine(curves: list, cfg: MatchConfig) -> np.ndarray:
    return distance_matrix(curves, config=cfg, workers=1, progress=False)


COMPARISONS = [
    # (option, base configuration, [(label, changes, runner)])
    (
        "dif",
        MatchConfig.preset("general"),
        [
            ("directed procrustes", {}, "engine"),
            ("dif=hyperbolic", {"dif": "hyperbolic"}, "engine"),
        ],
    ),
    (
        "matcher",
        MatchConfig.preset("general", n_points=24, phases=1),
        [
            ("directed", {}, "engine"),
            ("directed symmetrize=mean", {"symmetrize": "mean"}, "engine"),
            ("matcher=symmetric", {"matcher": "symmetric"}, "symmetric"),
        ],
    ),
    (
        "replace_any",
        MatchConfig.preset("general", n_points=16, phases=1, occlusion=1.0),
        [("directed occlusion=1", {}, "engine"), ("replace_any", {"replace_any": True}, "pairs")],
    ),
]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--sets", nargs="+", default=["kimia99", "mpeg7", "swedish_leaf"])
    ap.add_argument("--options", nargs="+", default=[c[0] for c in COMPARISONS])
    ap.add_argument("--json", type=Path, default=RESULTS / "options.json")
    ap.add_argument(
        "--full-kimia",
        action="store_true",
        help="only the dif comparison on all of Kimia-99 (10 ranks), merged into the JSON",
    )
    args = ap.parse_args(argv)
    command = "python benchmarks/eval_options.py" + (" " + " ".join(argv) if argv else "")
    if args.full_kimia:
        import json

        ds = load("kimia99", progress=False)
        labels = np.asarray(ds.labels)
        old = json.loads(args.json.read_text()) if args.json.exists() else {}
        full = {"command": command, "machine": machine(), "shapes": len(ds.curves), "runs": {}}
        for label, changes, _how in COMPARISONS[0][2]:
            cfg = COMPARISONS[0][1].replace(**changes)
            t0 = time.perf_counter()
            D = engine(ds.curves, cfg)
            secs = time.perf_counter() - t0
            row = [int(x) for x in kimia_ranks(D, labels, n_ranks=10)]
            full["runs"][label] = {
                "changes": changes,
                "seconds": secs,
                "ranks": row,
                "ranks_sum": int(sum(row)),
                "loo_1nn": loo_nn(D, labels),
            }
            print(f"kimia99 (all 99) {label:>22}: {row} = {sum(row)} ({secs:.0f} s)", flush=True)
        old.setdefault("full", {})["kimia99_dif"] = full
        write_json(args.json, old)
        print(f"wrote {args.json}")
        return 0
    out: dict = {
        "command": command,
        "machine": machine(),
        "subsets": {},
        "results": {},
    }
    for name in args.sets:
        curves, labels, classes = subset(name)
        out["subsets"][name] = {
            "shapes": len(curves),
            "classes": classes,
            "per_class": PER_CLASS[name],
        }
        for option, base, runs in COMPARISONS:
            if option not in args.options:
                continue
            rec = {"base": base.as_dict(), "runs": {}}
            for label, changes, how in runs:
                cfg = base.replace(**changes)
                t0 = time.perf_counter()
                if how == "engine":
                    D = engine(curves, cfg)
                else:
                    D = pairwise(curves, cfg, symmetric=how == "symmetric")
                secs = time.perf_counter() - t0
                sc = scores(name, D, labels)
                rec["runs"][label] = {"changes": changes, "seconds": secs, **sc}
                print(
                    f"{name:>12} {option:>11} {label:>26}: {sc['headline']:.4g} "
                    f"(1-NN {sc['loo_1nn']:.3f}"
                    + (f", ranks {sc['ranks']}" if "ranks" in sc else "")
                    + f") {secs:.0f} s",
                    flush=True,
                )
            out["results"].setdefault(name, {})[option] = rec
    if args.json.exists():  # keep a --full-kimia record made earlier
        import json

        prev = json.loads(args.json.read_text())
        if "full" in prev:
            out["full"] = prev["full"]
    write_json(args.json, out)
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
