"""Choose the ``general`` preset leave-one-dataset-out (choose on two sets, score on the third).

A grid of candidate configurations is scored on a *selection subset* of each of MPEG-7,
Kimia-99 and Swedish leaf. For each held-out set, the candidate with the best mean rank on
the other two sets wins (ties: fewer kernel runs per pair); the preset itself is the
candidate that wins on all three folds' pooled ranks, and its held-out scores on the full
sets are measured by ``shapetree evaluate NAME`` (see the README, "Presets").

Every candidate must also pass the invariance check of the issue: for the first shape of 12
MPEG-7 classes, its cost against its own image rotated by 37° is, in the median, at most 0.1
times its cost against the nearest of shapes 2–4 of its class. Candidates are limited to at
most 8 kernel runs per ordered pair (a speed budget fixed before any score was seen: the
default must run all-pairs MPEG-7 in well under half an hour on 2 cores).

The grid is computed once per *base* (sampling, band, λ, occlusion, target factor): the
directed costs of every target phase (0, 1/4, 2/4, 3/4 of a spacing) with the mirrored model
as a second layer, so ``phases`` ∈ {1, 2, 4}, ``mirror`` and ``symmetrize`` ∈ {none, min} are
all read from the same tables (the engine keeps the minimum over phases and mirror passes,
which is what is taken here). One shape-tree only: 3 trees at 4 phases with mirror cost 24
runs per pair, three times the budget, and with 3 trees at 2 phases the rotation check
fails (median ratio 0.107 measured before the grid was run).

Run::

    SHAPETREE_DATA=../shared/datasets python benchmarks/select_general.py
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS  # noqa: E402

from shapetree import datasets  # noqa: E402
from shapetree._bench import machine_info  # noqa: E402
from shapetree.curves import as_curve, resample  # noqa: E402
from shapetree.matching import MatchConfig, match  # noqa: E402
from shapetree.retrieval import (  # noqa: E402
    bullseye,
    combine,
    directed_costs,
    kimia_ranks,
    nn_accuracy_splits,
)

SETS = ("kimia99", "mpeg7", "swedish_leaf")
#: selection subsets (the first shapes of every class); full sets are scored apart
SUBSETS = {"kimia99": None, "mpeg7": 6, "swedish_leaf": 20}

#: bases: everything but n_trees / phases / mirror / symmetrize
BASES = {
    "lp1": MatchConfig(n_points=50, band=3.0, length_power=1.0),
    "occ2": MatchConfig(n_points=50, band=3.0, length_power=1.0, occlusion=2.0),
    "lp1.5": MatchConfig(n_points=50, band=3.0, length_power=1.5),
    "tf2": MatchConfig(
        n_points=50, band=3.0, length_power=1.0, target_factor=2, segment_weight=0.0
    ),
    "exact": MatchConfig(n_points=50, band=None, length_power=1.0),
}
PHASE_SETS = {1: (0,), 2: (0, 2), 4: (0, 1, 2, 3)}  # in quarters of a spacing
MAX_RUNS = 8


def _score(name: str, D: np.ndarray, labels: np.ndarray) -> float:
    if name == "kimia99":
        return float(kimia_ranks(D, labels).sum())
    if name == "mpeg7":
        return float(bullseye(D, labels, k=2 * SUBSETS["mpeg7"]))
    n_train = SUBSETS["swedish_leaf"] // 2
    return float(nn_accuracy_splits(D, labels, n_train, 10, 0)[0])


def _layers(curves, base: MatchConfig, trees: int, quarters, cache: Path) -> dict:
    """Directed costs per target phase (quarters of a spacing), mirror as layer 1."""
    cfg = base.replace(n_trees=trees, mirror=True, phases=1, target_factor=1)
    n, tp = base.n_points, base.target_points
    models = [resample(as_curve(c, closed=True), n, closed=True) for c in curves]
    out = {}
    for q in quarters:
        targets = [resample(as_curve(c, closed=True), tp, closed=True, phase=q / 4) for c in curves]
        out[q] = directed_costs(
            models,
            targets,
            cfg.replace(target_factor=1, n_points=None),
            cache_dir=cache,
            progress=False,
        )
    return out


def _candidates(base_name: str, base: MatchConfig):
    phases = (1,) if base.target_factor > 1 or base.band is None else (1, 2, 4)
    trees = (1,)  # 3 trees: 24 runs per pair at 4 phases + mirror, over the budget
    mirrors = (False,) if base.band is None else (False, True)
    for t, p, mir, sym in itertools.product(trees, phases, mirrors, ("none", "min")):
        cfg = base.replace(n_trees=t, phases=p, mirror=mir, symmetrize=sym)
        if cfg.matchings_per_pair // (2 if sym == "min" else 1) <= MAX_RUNS:
            yield f"{base_name} T{t} P{p} {'M' if mir else '-'} {sym}", cfg


def _rotation_ratio(cfg: MatchConfig, items) -> float:
    ratios = []
    for own, rotated, others in items:
        self_cost = match(own, rotated, cfg).cost
        near = min(match(own, o, cfg).cost for o in others)
        ratios.append(self_cost / near)
    return float(np.median(ratios))


def rotation_items(n_classes: int = 12, angle: float = 37.0):
    """First shape of ``n_classes`` MPEG-7 classes, its image rotated, shapes 2-4."""
    from PIL import Image

    from shapetree.curves import curve_from_image

    ds = datasets.load("mpeg7", n_points=None, per_class=4, progress=False)
    labels = np.asarray(ds.labels)
    items = []
    for c in sorted(set(labels.tolist()))[:: max(1, 70 // n_classes)][:n_classes]:
        idx = np.flatnonzero(labels == c)
        path = ds.paths[idx[0]]
        img = Image.open(path).convert("L")
        grey = np.asarray(img)
        bg = int(np.median(np.r_[grey[0], grey[-1], grey[:, 0], grey[:, -1]]))
        rot = img.rotate(angle, resample=Image.NEAREST, expand=True, fillcolor=bg)
        rotated = curve_from_image(np.asarray(rot))
        items.append((ds.curves[idx[0]], rotated, [ds.curves[i] for i in idx[1:4]]))
    return items


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--cache-dir", default=str(Path.home() / ".cache/shapetree/select_general"))
    ap.add_argument("--json", default=str(RESULTS / "general_selection.json"))
    ap.add_argument("--bases", nargs="+", default=list(BASES), choices=list(BASES))
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    data = {
        name: datasets.load(name, n_points=None, per_class=SUBSETS[name], progress=False)
        for name in SETS
    }
    rot = rotation_items()
    scores: dict[str, dict] = {}
    for bname in args.bases:
        base = BASES[bname]
        cands = list(_candidates(bname, base))
        if not cands:
            continue
        quarters = sorted({q for _, c in cands for q in PHASE_SETS[c.phases]})
        trees = sorted({c.n_trees for _, c in cands})
        for name, ds in data.items():
            labels = np.asarray(ds.labels)
            tb = time.perf_counter()
            lay = {t: _layers(ds.curves, base, t, quarters, Path(args.cache_dir)) for t in trees}
            print(f"{bname:6s} {name:13s} tables {time.perf_counter() - tb:7.1f} s", flush=True)
            for label, cfg in cands:
                c = np.min([lay[cfg.n_trees][q] for q in PHASE_SETS[cfg.phases]], axis=0)
                c = c if cfg.mirror else c[:1]
                rec = scores.setdefault(label, {"config": cfg.as_dict(), "scores": {}})
                rec["scores"][name] = _score(name, combine(c, cfg.symmetrize), labels)
        for label, cfg in cands:
            scores[label]["rotation_ratio"] = _rotation_ratio(cfg, rot)
            scores[label]["runs_per_pair"] = cfg.matchings_per_pair

    labels_ = list(scores)
    ok = [k for k in labels_ if scores[k]["rotation_ratio"] <= 0.1]

    def ranks(name: str) -> dict[str, float]:
        vals = np.array([scores[k]["scores"][name] for k in ok])
        order = (-vals).argsort(kind="stable").argsort(kind="stable")
        # average rank of ties
        r = {}
        for v in np.unique(vals):
            members = np.flatnonzero(vals == v)
            for i in members:
                r[ok[i]] = float(order[members].mean()) + 1
        return r

    rk = {name: ranks(name) for name in SETS}

    def pick(on: tuple[str, ...]) -> str:
        return min(
            ok,
            key=lambda k: (np.mean([rk[n][k] for n in on]), scores[k]["runs_per_pair"], k),
        )

    folds = {held: pick(tuple(n for n in SETS if n != held)) for held in SETS}
    pooled = pick(SETS)
    print(f"\n{'candidate':28s} {'kimia':>6s} {'mpeg7':>7s} {'swed':>7s} {'rot':>6s} runs")
    for k in sorted(labels_, key=lambda k: np.mean([rk[n].get(k, 999) for n in SETS])):
        s = scores[k]["scores"]
        mark = "*" if k == pooled else ("h" if k in folds.values() else " ")
        print(
            f"{mark}{k:27s} {s['kimia99']:6.0f} {s['mpeg7']:7.2f} {s['swedish_leaf']:7.2f} "
            f"{scores[k]['rotation_ratio']:6.3f} {scores[k]['runs_per_pair']:4d}"
        )
    for held, k in folds.items():
        print(f"held out {held:13s}: chosen on the other two = {k}")
    print(f"pooled choice (the general preset): {pooled}")
    rec = {
        "command": "python benchmarks/select_general.py " + " ".join(argv or sys.argv[1:]),
        "subsets_per_class": SUBSETS,
        "protocols": {
            "kimia99": "sum of the rank row (of 990)",
            "mpeg7": f"bull's-eye, k = {2 * SUBSETS['mpeg7']}",
            "swedish_leaf": f"1-NN accuracy, {SUBSETS['swedish_leaf'] // 2} training leaves per "
            "class, 10 seeded splits",
        },
        "rotation_check": "median over 12 MPEG-7 classes of cost(shape 1, its image rotated "
        "37 deg) / min cost(shape 1, shapes 2-4); candidates above 0.1 are excluded",
        "max_runs_per_pair": MAX_RUNS,
        "candidates": scores,
        "eligible": ok,
        "folds": folds,
        "general": pooled,
        "general_config": scores[pooled]["config"],
        "seconds": round(time.perf_counter() - t0, 1),
        "machine": machine_info(),
    }
    Path(args.json).write_text(json.dumps(rec, indent=1) + "\n")
    print(f"json: {args.json}  ({rec['seconds']} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
