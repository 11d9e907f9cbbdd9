"""Benchmark evaluations of §5.1 (Tables 1–3): one function per call of ``shapetree evaluate``.

:func:`evaluate` loads a dataset, computes its distance matrix with the engine, applies the
dataset's protocol, prints the paper's table with our measured row beside the published
rows, and optionally writes a JSON record and pictures. :data:`EVAL_PARAMS` describes every
option (type, default, help) so a command-line front end can turn them into flags.
"""

from __future__ import annotations

import datetime as _dt
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from shapetree._errors import ShapeTreeError
from shapetree.retrieval._engine import SYMMETRIZE, combine, directed_costs
from shapetree.retrieval._protocols import (
    bullseye,
    bullseye_per_class,
    kimia_ranks,
    nn_accuracy_splits,
)
from shapetree.retrieval._rerank import RERANK_DEFAULTS, tpg_rerank

__all__ = [
    "DATASET_DEFAULTS",
    "EVAL_PARAMS",
    "PAPER_TABLES",
    "evaluate",
    "format_table",
    "machine_info",
    "protocol_score",
]

DATASETS = ("kimia99", "mpeg7", "swedish_leaf")

#: Published rows of the paper's Tables 1–3 (method, value); Table 3 rows are rank counts.
PAPER_TABLES: dict[str, dict[str, Any]] = {
    "mpeg7": {
        "title": "Table 1. Classification results on the MPEG-7 dataset (bull's-eye)",
        "rows": [
            ("Shape-tree (paper)", 87.70),
            ("IDSC + DP + EMD [17]", 86.56),
            ("Hierarchical Procrustes [19]", 86.35),
            ("IDSC + DP [16]", 85.40),
            ("Generative Models [27]", 80.03),
            ("Curve Edit [23]", 78.14),
            ("SC + TPS [3]", 76.51),
            ("Visual Parts [15]", 76.45),
            ("CSS [20]", 75.44),
        ],
    },
    "swedish_leaf": {
        "title": "Table 2. Classification results on the Swedish leaf dataset (1-NN)",
        "rows": [
            ("Shape-tree (paper)", 96.28),
            ("IDSC + DP [16]", 94.13),
            ("SC + DP [16]", 88.12),
            ("Fourier descriptors [16]", 89.60),
            ("Soderkvist [26]", 82.40),
        ],
    },
    "kimia99": {
        "title": "Table 3. Retrieval results on Kimia-99 (same-class shapes at ranks 1..10)",
        "rows": [
            ("Shape-tree (paper)", [99, 99, 99, 99, 99, 99, 99, 97, 93, 86]),
            ("IDSC + DP [16]", [99, 99, 99, 98, 98, 97, 97, 98, 94, 79]),
            ("Shock-Graph Edit [24]", [99, 99, 99, 98, 98, 97, 96, 95, 93, 82]),
            ("Generative Models [27]", [99, 97, 99, 98, 96, 96, 94, 83, 75, 48]),
        ],
    },
}

#: Options of :func:`evaluate`: ``{name: {"type", "default", "help"[, "choices"]}}``.
#: A default of ``None`` for a matching option means "the dataset's tuned default"
#: (:data:`DATASET_DEFAULTS`).
EVAL_PARAMS: dict[str, dict[str, Any]] = {
    "n_points": {
        "type": int,
        "default": None,
        "help": "sample points per curve (resampled evenly in arc length)",
    },
    "weight": {
        "type": float,
        "default": None,
        "help": "lambda factor of the shape-tree nodes (matters only with --occlusion)",
    },
    "occlusion": {
        "type": float,
        "default": None,
        "help": "replacement cost factor kappa (0 or omitted: no replacement)",
    },
    "n_trees": {
        "type": int,
        "default": None,
        "help": "shape-trees per model (rotated start points), best taken",
    },
    "split": {
        "type": str,
        "default": None,
        "choices": ["half", "best"],
        "help": "midpoint of each shape-tree node: half (the middle sample) or best (the sample "
        "whose triangle best approximates the subcurve, paper section 2)",
    },
    "mirror": {
        "type": bool,
        "default": None,
        "help": "also match the mirrored curve and keep the better cost",
    },
    "band": {
        "type": float,
        "default": None,
        "help": "pruned matching: max stretch of a subcurve (0: exact matching)",
    },
    "length_power": {
        "type": float,
        "default": None,
        "help": "lambda grows as (relative subcurve length)^p; the paper uses 1",
    },
    "smooth": {
        "type": float,
        "default": None,
        "help": "Gaussian smoothing of each traced outline before resampling, as a fraction "
        "of its length (0: none)",
    },
    "phases": {
        "type": int,
        "default": None,
        "help": "target phases: also match each target resampled 1/P, 2/P, ... of a sample "
        "spacing further along and keep the cheapest (1: the paper's single sampling)",
    },
    "target_factor": {
        "type": int,
        "default": None,
        "help": "targets get target_factor x n_points points (1: both curves alike, as in "
        "the paper)",
    },
    "segment_weight": {
        "type": float,
        "default": None,
        "help": "weight of the base case 'model segment vs a target subcurve' (paper: 1; 0 "
        "makes target detail finer than the model's sampling free)",
    },
    "precision": {
        "type": str,
        "default": "float32",
        "choices": ["float32", "float64"],
        "help": "precision of the matching tables (float32: about twice as fast, costs "
        "within about 1e-6 relative of float64)",
    },
    "symmetrize": {
        "type": str,
        "default": None,
        "choices": list(SYMMETRIZE),
        "help": "combine psi(q,x) and psi(x,q): min, mean, max, none (psi(query, x)), "
        "reverse (psi(x, query))",
    },
    "rerank": {
        "type": str,
        "default": "none",
        "choices": ["none", "tpg"],
        "help": "none: pairwise distances (the paper's measure); tpg: also re-rank the whole "
        "matrix by tensor product graph diffusion (k=10, alpha=0.8) and report that score "
        "as the headline, with the pairwise score kept under 'pairwise'",
    },
    "workers": {"type": int, "default": 2, "help": "threads"},
    "block": {
        "type": int,
        "default": None,
        "help": "rows per cached block (default: n / (4 workers), at most 32; each target is "
        "prepared once per block)",
    },
    "cache_dir": {
        "type": str,
        "default": None,
        "help": "resumable cache of finished blocks (default: none)",
    },
    "classes": {
        "type": str,
        "default": None,
        "help": "comma-separated subset of classes (quick runs)",
    },
    "per_class": {"type": int, "default": None, "help": "at most this many shapes per class"},
    "k": {"type": int, "default": 40, "help": "bull's-eye neighbourhood (mpeg7)"},
    "n_train": {"type": int, "default": 25, "help": "training shapes per class (swedish_leaf)"},
    "n_splits": {"type": int, "default": 10, "help": "random splits (swedish_leaf)"},
    "seed": {"type": int, "default": 0, "help": "seed of the splits (swedish_leaf)"},
    "n_show": {"type": int, "default": 10, "help": "matches per query in the retrieval grid"},
}

_MATCH_KEYS = (
    "n_points",
    "weight",
    "occlusion",
    "n_trees",
    "split",
    "mirror",
    "band",
    "length_power",
    "smooth",
    "phases",
    "target_factor",
    "segment_weight",
    "symmetrize",
)

#: Tuned matching settings per dataset (see ``benchmarks/results/*.json`` for the runs).
DATASET_DEFAULTS: dict[str, dict[str, Any]] = {
    # best measured settings per set (benchmarks/results/<set>.json records each run)
    "kimia99": {
        "n_points": 50,
        "weight": 1.0,
        "occlusion": None,
        "n_trees": 3,
        "split": "half",
        "mirror": True,
        "band": 4.0,
        "length_power": 1.0,
        "smooth": None,
        "phases": 4,  # targets at 0, 1/4, 2/4, 3/4 of a spacing: 970 of 990 (phases 1: 965)
        "target_factor": 1,
        "segment_weight": 1.0,
        "symmetrize": "none",
    },
    "mpeg7": {
        "n_points": 64,
        "weight": 1.0,
        "occlusion": 2.0,
        "n_trees": 3,
        "split": "half",
        "mirror": True,
        "band": 3.0,
        "length_power": 1.0,
        "smooth": None,
        "phases": 2,  # targets also at half a spacing: 87.76% (phases 1: 87.49%)
        "target_factor": 1,
        "segment_weight": 1.0,
        "symmetrize": "none",
    },
    "swedish_leaf": {
        "n_points": 64,  # models; targets 128 (target_factor 2). n 40 / 50: 94.97 / 95.21%
        "weight": 1.0,
        "occlusion": None,
        "n_trees": 1,
        "split": "half",
        "mirror": True,
        "band": 2.0,
        "length_power": 1.5,  # coarse (global) nodes weigh a little more; see swedish_leaf.json
        "smooth": None,
        "phases": 1,
        # targets sampled twice as densely, target detail between model points free
        "target_factor": 2,
        "segment_weight": 0.0,
        "symmetrize": "none",
    },
}


def machine_info() -> dict[str, Any]:
    """CPU model, core count, load average, Python / NumPy / numba versions, platform."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    import numba

    info: dict[str, Any] = {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "python": sys.version.split()[0],
        "numpy": np.__version__,
        "numba": numba.__version__,
        "platform": platform.platform(),
    }
    try:
        info["loadavg_at_end"] = [round(x, 2) for x in os.getloadavg()]
    except OSError:
        pass
    return info


def _resolve(name: str, params: dict[str, Any]) -> dict[str, Any]:
    unknown = set(params) - set(EVAL_PARAMS)
    if unknown:
        raise ShapeTreeError(f"unknown evaluate option(s): {sorted(unknown)}")
    p = {k: v["default"] for k, v in EVAL_PARAMS.items()}
    p.update({k: v for k, v in DATASET_DEFAULTS[name].items()})
    for k, v in params.items():
        if v is not None or k not in _MATCH_KEYS:
            p[k] = v
    # 0 means "off" for the optional numbers (handy on a command line)
    for k in ("occlusion", "band", "smooth"):
        if p[k] is not None and float(p[k]) == 0.0:
            p[k] = None
    if isinstance(p["classes"], str):
        p["classes"] = [c.strip() for c in p["classes"].split(",") if c.strip()]
    return p


def format_table(
    name: str,
    ours: Any = None,
    label: str = "Shape-tree (shapetree, measured)",
    *,
    rows: list[tuple[str, Any]] | None = None,
) -> str:
    """The paper's table for ``name`` with our row(s) on top.

    Parameters
    ----------
    name : {"kimia99", "mpeg7", "swedish_leaf"}
    ours : float or sequence of int, optional
        Our percentage (mpeg7, swedish_leaf) or ten rank counts (kimia99).
    label : str
        Label of ``ours``.
    rows : list of (str, value), optional
        Several labelled rows of ours instead of ``ours``/``label`` (e.g. pairwise and
        re-ranked).

    Returns
    -------
    str
    """
    table = PAPER_TABLES[name]
    if rows is None:
        if ours is None:
            raise ShapeTreeError("format_table needs ours or rows")
        rows = [(label, ours)]
    rows = list(rows) + list(table["rows"])
    width = max(len(r[0]) for r in rows) + 2
    lines = [table["title"]]
    if name == "kimia99":
        lines.append("Method".ljust(width) + " ".join(f"{r:>4}" for r in range(1, 11)) + "   sum")
        for m, v in rows:
            vals = [int(x) for x in v]
            lines.append(m.ljust(width) + " ".join(f"{x:>4d}" for x in vals) + f"  {sum(vals):4d}")
    else:
        lines.append("Method".ljust(width) + "Recognition rate")
        for m, v in rows:
            lines.append(m.ljust(width) + f"{float(v):.2f}%")
    return "\n".join(lines)


def evaluate(
    name: str,
    *,
    json_path: str | os.PathLike[str] | None = None,
    out_dir: str | os.PathLike[str] | None = None,
    progress: bool = True,
    verbose: bool = True,
    command: str | None = None,
    arrays: dict[str, Any] | None = None,
    **params: Any,
) -> dict[str, Any]:
    """Run one of the paper's benchmarks (Tables 1–3) and report it.

    Parameters
    ----------
    name : {"kimia99", "mpeg7", "swedish_leaf"}
    json_path : path-like, optional
        Write the result record here (atomically).
    out_dir : path-like, optional
        Write pictures here: ``<name>_retrieval.png`` (queries with their nearest shapes,
        wrong classes in red) and, for mpeg7, ``<name>_bullseye_per_class.png``.
    progress : bool
        Progress bar of the distance computation.
    verbose : bool
        Print the table.
    command : str, optional
        The command line to record (default: ``python -m ... evaluate`` reconstructed).
    arrays : dict, optional
        Filled with ``costs`` (the directed costs, shape ``(n_pass, n, n)``, see
        :func:`directed_costs`) and ``labels``, for further analysis without recomputing.
    **params
        Any key of :data:`EVAL_PARAMS`; matching options left at ``None`` take the
        dataset's tuned value from :data:`DATASET_DEFAULTS`.

    Returns
    -------
    dict
        The record also written to ``json_path``: ``dataset``, ``params`` (every value
        used), ``n_shapes``, ``seconds`` (wall time of the whole evaluation),
        ``seconds_matrix``, ``pairs``, ``pairs_computed`` (0 when every block came from the
        cache), ``machine``, the paper's rows, and the score: ``ranks`` (kimia99: ten
        ints), ``bullseye`` (mpeg7: percent, plus ``bullseye_per_class``) or
        ``accuracy_mean`` / ``accuracy_std`` / ``accuracy_splits`` (swedish_leaf, percent).
        The score keys hold the requested ``measure`` (pairwise, or TPG re-ranked with
        ``rerank="tpg"``); ``pairwise`` always holds the pairwise score and ``reranked``
        the re-ranked one when it was computed.
    """
    from shapetree import datasets

    if name not in DATASETS:
        raise ShapeTreeError(f"unknown benchmark {name!r}; choose one of {DATASETS}")
    t_start = time.perf_counter()
    p = _resolve(name, params)
    ds = datasets.load(
        name,
        # smoothing and phases work on the traced outline, so resampling waits for the engine
        n_points=None
        if (p["smooth"] or p["phases"] > 1 or p["target_factor"] > 1)
        else p["n_points"],
        progress=progress,
        classes=p["classes"],
        per_class=p["per_class"],
    )
    labels = np.asarray(ds.labels)
    stats: dict[str, Any] = {}
    t0 = time.perf_counter()
    costs = directed_costs(
        ds.curves,
        n_points=p["n_points"],
        weight=p["weight"],
        occlusion=p["occlusion"],
        n_trees=p["n_trees"],
        split=p["split"],
        mirror=bool(p["mirror"]),
        band=p["band"],
        length_power=p["length_power"],
        smooth=p["smooth"],
        phases=p["phases"],
        target_factor=p["target_factor"],
        segment_weight=p["segment_weight"],
        precision=p["precision"],
        workers=p["workers"],
        cache_dir=p["cache_dir"],
        block=p["block"],
        progress=progress,
        desc=name,
        stats=stats,
    )
    seconds_matrix = time.perf_counter() - t0
    if arrays is not None:
        arrays.update(costs=costs, labels=labels)
    D = combine(costs, p["symmetrize"])
    rec: dict[str, Any] = {"dataset": name}
    pairwise = protocol_score(name, D, labels, p)
    rec["pairwise"] = pairwise
    rows: list[tuple[str, Any]] = [("Shape-tree (shapetree, pairwise)", _headline(name, pairwise))]
    if p["rerank"] == "tpg":
        t1 = time.perf_counter()
        D = tpg_rerank(D)
        reranked = protocol_score(name, D, labels, p)
        reranked["seconds"] = round(time.perf_counter() - t1, 2)
        reranked["method"] = "tpg"
        reranked["params"] = dict(RERANK_DEFAULTS)
        rec["reranked"] = reranked
        rows.insert(0, ("Shape-tree + TPG re-ranking (shapetree)", _headline(name, reranked)))
        rec["measure"] = (
            "re-ranked: tensor product graph diffusion over the whole distance matrix "
            "(not a pairwise measure); the pairwise score is under 'pairwise'"
        )
        chosen = reranked
    else:
        rec["measure"] = "pairwise: each distance depends only on the two shapes"
        chosen = pairwise
    rec.update({k: v for k, v in chosen.items() if k not in ("seconds", "method", "params")})
    table = format_table(name, rows=rows)
    if verbose:
        print(table)
        print(
            f"{len(labels)} shapes, {stats.get('pairs', 0)} ordered pairs "
            f"({stats.get('pairs_computed', 0)} computed now), matrix {seconds_matrix:.1f} s"
        )
    pictures: list[str] = []
    if out_dir is not None:
        from shapetree.retrieval._figures import plot_bullseye_per_class, plot_retrieval_grid

        out = Path(out_dir)
        pictures.append(
            Path(
                plot_retrieval_grid(
                    D,
                    labels,
                    ds.curves,
                    out / f"{name}_retrieval.png",
                    n_top=p["n_show"],
                    title=f"{name}: queries (left) and nearest shapes, wrong class in red"
                    + (" (TPG re-ranked)" if p["rerank"] == "tpg" else " (pairwise)"),
                )
            ).name
        )
        if name == "mpeg7":
            pictures.append(
                Path(
                    plot_bullseye_per_class(
                        pairwise["bullseye_per_class"],
                        out / f"{name}_bullseye_per_class.png",
                        overall=pairwise["bullseye"],
                        second=rec["reranked"]["bullseye_per_class"] if "reranked" in rec else None,
                        second_overall=rec["reranked"]["bullseye"] if "reranked" in rec else None,
                        labels=("pairwise", "TPG re-ranked"),
                        title="MPEG-7 bull's-eye per class (bars: pairwise)",
                    )
                ).name
            )
    rec.update(
        {
            "params": {k: p[k] for k in EVAL_PARAMS},
            "n_shapes": int(len(labels)),
            "n_classes": len(set(labels.tolist())),
            "pairs": stats.get("pairs"),
            "pairs_computed": stats.get("pairs_computed"),
            "blocks_from_cache": stats.get("blocks_cached"),
            "seconds_matrix": round(seconds_matrix, 2),
            "seconds": round(time.perf_counter() - t_start, 2),
            "command": command or _default_command(name, json_path, out_dir, params),
            "machine": machine_info(),
            "date": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
            "paper": PAPER_TABLES[name]["rows"][0][1],
            "paper_table": PAPER_TABLES[name]["rows"],
            "table": table,
            "pictures": pictures,  # file names inside out_dir
        }
    )
    if json_path is not None:
        _write_json(Path(json_path), rec)
    return rec


def protocol_score(
    name: str, D: np.ndarray, labels: np.ndarray, p: dict[str, Any]
) -> dict[str, Any]:
    """The protocol's score of one distance matrix, as JSON-ready values.

    ``p`` needs ``k`` (mpeg7) or ``n_train``, ``n_splits``, ``seed`` (swedish_leaf); the
    keys returned are those of :func:`evaluate`'s record (``ranks``, ``bullseye``, ...).
    """
    if name == "kimia99":
        ranks = kimia_ranks(D, labels)
        return {"ranks": [int(x) for x in ranks], "ranks_sum": int(ranks.sum())}
    if name == "mpeg7":
        return {
            "bullseye": round(bullseye(D, labels, k=p["k"]), 4),
            "bullseye_per_class": {
                c: round(v, 2) for c, v in bullseye_per_class(D, labels, k=p["k"]).items()
            },
        }
    mean, std, accs = nn_accuracy_splits(
        D, labels, p["n_train"], p["n_splits"], p["seed"], return_splits=True
    )
    return {
        "accuracy_mean": round(mean, 4),
        "accuracy_std": round(std, 4),
        "accuracy_splits": [round(float(a), 4) for a in accs],
    }


_HEADLINE = {"kimia99": "ranks", "mpeg7": "bullseye", "swedish_leaf": "accuracy_mean"}


def _headline(name: str, score: dict[str, Any]) -> Any:
    return score[_HEADLINE[name]]


def _default_command(name: str, json_path: Any, out_dir: Any, params: dict[str, Any]) -> str:
    parts = ["shapetree", "evaluate", name]
    for k, v in params.items():
        if v is None:
            continue
        flag = "--" + k.replace("_", "-")
        if isinstance(v, bool):
            parts.append(flag if v else "--no-" + k.replace("_", "-"))
        elif isinstance(v, list | tuple):
            parts += [flag, ",".join(map(str, v))]
        else:
            parts += [flag, str(v)]
    if json_path is not None:
        parts += ["--json", str(json_path)]
    if out_dir is not None:
        parts += ["--out-dir", str(out_dir)]
    return " ".join(parts)


def _write_json(path: Path, data: dict[str, Any]) -> None:
    import json
    import tempfile

    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    with os.fdopen(fd, "w") as fh:
        json.dump(data, fh, indent=2)
        fh.write("\n")
    os.chmod(tmp, 0o644)
    os.replace(tmp, path)
