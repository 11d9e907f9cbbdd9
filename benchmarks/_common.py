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


#: What :func:`reference_ms` times.
REFERENCE_WORKLOAD = (
    "the section 3 closed-curve DP (shapetree.matching.match_cost) of two fixed 50-point "
    "curves, prepared once (default shape-tree and options), median of 301 calls in one "
    "process after 30 warm-up calls"
)


def reference_ms(repeats: int = 301) -> float:
    """Milliseconds per call of :data:`REFERENCE_WORKLOAD`: a yardstick of the machine's
    speed, timed in the same run as a benchmark so that its times can be given in units of
    it (absolute times drift by up to 2x between machines and days)."""
    import time

    import numpy as np

    from shapetree.matching import match_cost, prepare_model, prepare_target

    t = np.linspace(0.0, 2.0 * np.pi, 50, endpoint=False)
    r = 1.0 + 0.3 * np.cos(3.0 * t)
    a = np.c_[r * np.cos(t), r * np.sin(t)]
    b = np.c_[1.4 * np.cos(t) + 0.1 * np.cos(4.0 * t), 0.8 * np.sin(t) + 0.2 * np.sin(2.0 * t)]
    model, target = prepare_model(a), prepare_target(b)
    for _ in range(30):  # compile or load the kernels, then warm the caches
        match_cost(model, target)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        match_cost(model, target)
        times.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(times))


def machine() -> dict:
    """A short description of the machine the benchmark ran on (CPU, cores, load, versions)."""
    return machine_info()


def write_json(path: Path, data: dict) -> None:
    """Write ``data`` as JSON atomically (temporary file, then rename)."""
    with atomic_open(path, "w") as fh:
        json.dump(data, fh, indent=2)
        fh.write("\n")


def default_data() -> str:
    """The datasets folder of the benchmarks: ``$SHAPETREE_DATA``, else ``../shared/datasets``
    beside the repository."""
    return os.environ.get("SHAPETREE_DATA", str(REPO.parent / "shared" / "datasets"))


def ethz_parser(doc: str | None, edges: bool = True) -> argparse.ArgumentParser:
    """The arguments the ETHZ ranking scripts share: ``--data`` (default
    ``$SHAPETREE_DATA``, else ``../shared/datasets``), ``--workers``, ``--json`` and,
    with ``edges``, ``--edges {pb,own}`` and ``--detections`` (a cache of eval_ethz.py)."""
    ap = argparse.ArgumentParser(description=(doc or "").splitlines()[0] if doc else None)
    ap.add_argument("--data", default=default_data())
    if edges:
        ap.add_argument("--edges", choices=("pb", "own"), default="pb")
        ap.add_argument("--detections", required=True, help="the cached detections (eval_ethz.py)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", default=None)
    return ap


def add_param_option(ap: argparse.ArgumentParser, help: str) -> None:
    """``--param/-p KEY=VALUE`` (repeatable): a DetectParams field other than its default,
    parsed as the CLI parses it (``shapetree.cli._evaluate.key_value``)."""
    from shapetree.cli._evaluate import key_value

    ap.add_argument(
        "--param", "-p", action="append", default=[], type=key_value, metavar="KEY=VALUE", help=help
    )
