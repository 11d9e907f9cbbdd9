"""Helpers shared by the benchmark scripts: machine description and atomic JSON output."""

from __future__ import annotations

import json
import os
import platform
import sys
from pathlib import Path

from shapetree._atomic import atomic_open

RESULTS = Path(__file__).resolve().parent / "results"


def machine() -> dict:
    """A short description of the machine the benchmark ran on."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    import numba
    import numpy

    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "python": sys.version.split()[0],
        "numpy": numpy.__version__,
        "numba": numba.__version__,
        "platform": platform.platform(),
    }


def write_json(path: Path, data: dict) -> None:
    """Write ``data`` as JSON atomically (temporary file, then rename)."""
    with atomic_open(path, "w") as fh:
        json.dump(data, fh, indent=2)
        fh.write("\n")
