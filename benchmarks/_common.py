"""Helpers shared by the benchmark scripts: machine description and atomic JSON output."""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

from shapetree._atomic import atomic_open
from shapetree._bench import machine_info

RESULTS = Path(__file__).resolve().parent / "results"
REPO = RESULTS.parents[1]


def machine() -> dict:
    """A short description of the machine the benchmark ran on (CPU, cores, load, versions)."""
    return machine_info()


def write_json(path: Path, data: dict) -> None:
    """Write ``data`` as JSON atomically (temporary file, then rename)."""
    with atomic_open(path, "w") as fh:
        json.dump(data, fh, indent=2)
        fh.write("\n")


def ethz_parser(doc: str | None, edges: bool = True) -> argparse.ArgumentParser:
    """The arguments the ETHZ ranking scripts share: ``--data`` (default
    ``$SHAPETREE_DATA``, else ``../shared/datasets``), ``--workers``, ``--json`` and,
    with ``edges``, ``--edges {pb,own}`` and ``--detections`` (a cache of eval_ethz.py)."""
    ap = argparse.ArgumentParser(description=(doc or "").splitlines()[0] if doc else None)
    default_data = os.environ.get("SHAPETREE_DATA", str(REPO.parent / "shared" / "datasets"))
    ap.add_argument("--data", default=default_data)
    if edges:
        ap.add_argument("--edges", choices=("pb", "own"), default="pb")
        ap.add_argument("--detections", required=True, help="the cached detections (eval_ethz.py)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", default=None)
    return ap
