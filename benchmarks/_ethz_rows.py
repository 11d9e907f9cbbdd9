"""What the ETHZ ranking experiments that read ``ethz_template.py --rows`` share.

Each such script (``ethz_class_norm.py``, ``ethz_hard_rows.py``, ``ethz_within_image.py``,
``ethz_upright.py``, ``ethz_self_training.py``, ``ethz_misses.py``,
``ethz_detector_params.py``) reads the rows of every kept detection, scores rankings of
them held out, and writes one JSON record: this module holds that frame, so that each
script is only its own question. The held-out choice of a term set and the final fit are
``ethz_template.best_set`` and ``ethz_template.fit_all``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import ethz_verify as V  # noqa: E402
from _common import RESULTS, default_data, machine, write_json  # noqa: E402
from ethz_collection_terms import SHIPPED  # noqa: E402
from ethz_template import CANDIDATES  # noqa: E402
from ethz_template import TERMS as TEMPLATE_TERMS  # noqa: E402

from shapetree.detection._ethz_eval import _images, ethz_root  # noqa: E402

#: the twelve terms of the shipped re-scorer
RESCORER_TERMS = SHIPPED + TEMPLATE_TERMS


def parser(doc: str) -> argparse.ArgumentParser:
    """``--rows`` (required), ``--data`` and ``--json``, described by the script's doc."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    ap.add_argument("--rows", required=True, help="rows written by ethz_template.py --rows")
    ap.add_argument("--data", default=default_data())
    ap.add_argument("--json", default=None)
    return ap


@dataclass
class Rows:
    """The rows of one run, their scorer and label (IoU >= 0.2 with a ground-truth box)."""

    rows: list[dict]
    sc: V._Scorer
    label: np.ndarray
    t0: float = field(default_factory=time.perf_counter)

    @classmethod
    def read(cls, path: str | Path, data: str | None = None) -> Rows:
        root = ethz_root(data)
        rows = json.loads(Path(path).read_text())
        sc = V._Scorer(root, rows, len(_images(root)))
        return cls(rows, sc, sc.col("iou") >= 0.2)

    def matrix(self, terms: tuple[str, ...] = RESCORER_TERMS) -> np.ndarray:
        """The rows x terms matrix of ``terms`` (default the twelve shipped)."""
        return np.stack([self.sc.col(t) for t in terms], 1)

    def candidates(self) -> dict[str, np.ndarray]:
        """The matrix of each of ``ethz_template.py``'s candidate term sets."""
        return {n: self.matrix(SHIPPED + e) for n, e in CANDIDATES.items()}


def held_record(held: dict, chosen: dict | None = None) -> dict:
    """A held-out record: per-fold ``chosen`` and both rules' DR per class with the mean."""
    out = {} if chosen is None else {"chosen": chosen}
    out["loco_overlap_20"] = V._with_mean(held, 0)
    out["loco_overlap_50"] = V._with_mean(held, 1)
    return out


def held_line(name: str, rec: dict) -> str:
    """One printed line of a held-out record."""
    return (
        f"{name} held out {rec['loco_overlap_20']['mean']:.4f} / "
        f"{rec['loco_overlap_50']['mean']:.4f} {rec['loco_overlap_20']}"
    )


def finish(out: dict, args: argparse.Namespace, t0: float, script: str, default: str) -> None:
    """Time, machine and command into ``out``; written to ``--json`` or ``results/default``."""
    out["seconds"] = round(time.perf_counter() - t0, 1)
    out["machine"] = machine()
    out["command"] = f"python3 benchmarks/{script} " + " ".join(sys.argv[1:])
    write_json(Path(args.json) if args.json else RESULTS / default, out)
