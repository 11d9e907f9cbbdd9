"""Helpers shared by the benchmark scripts: machine description and atomic JSON output."""

from __future__ import annotations

import json
from pathlib import Path

from shapetree._atomic import atomic_open
from shapetree._bench import machine_info

RESULTS = Path(__file__).resolve().parent / "results"


def machine() -> dict:
    """A short description of the machine the benchmark ran on (CPU, cores, load, versions)."""
    return machine_info()


def write_json(path: Path, data: dict) -> None:
    """Write ``data`` as JSON atomically (temporary file, then rename)."""
    with atomic_open(path, "w") as fh:
        json.dump(data, fh, indent=2)
        fh.write("\n")
