"""Benchmark plumbing shared by :func:`shapetree.retrieval.evaluate` and ``benchmarks/``:
the paper's published tables, the protocol scores as JSON-ready values, machine facts.

Private: not part of the public API.
"""

from __future__ import annotations

import os
import platform
import sys
from pathlib import Path
from typing import Any

import numpy as np

from shapetree._errors import ShapeTreeError

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


def protocol_score(
    name: str, D: np.ndarray, labels: np.ndarray, p: dict[str, Any]
) -> dict[str, Any]:
    """The protocol's score of one distance matrix, as JSON-ready values.

    ``p`` needs ``k`` (mpeg7) or ``n_train``, ``n_splits``, ``seed`` (swedish_leaf); the
    keys returned are those of :func:`evaluate`'s record (``ranks``, ``bullseye``, ...).
    """
    from shapetree.retrieval._protocols import (
        bullseye,
        bullseye_per_class,
        kimia_ranks,
        nn_accuracy_splits,
    )

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


def headline(name: str, score: dict[str, Any]) -> Any:
    """The headline value of a protocol score (ranks, bull's-eye or mean accuracy)."""
    return score[_HEADLINE[name]]
