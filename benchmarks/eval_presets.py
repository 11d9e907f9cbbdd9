"""Score presets on the full benchmark sets, pairwise: the README's "Presets" table.

Each run is exactly ``shapetree evaluate NAME --preset PRESET`` (the same function,
:func:`shapetree.retrieval.evaluate`), with a resumable block cache; the record of each run
goes to ``benchmarks/results/presets/<preset>_<set>.json`` and the table to
``benchmarks/results/presets.json`` (merged with earlier runs, so sets and presets can be
run one at a time).

Run (long runs in the background; a killed run resumes from its cache)::

    SHAPETREE_DATA=../shared/datasets python benchmarks/eval_presets.py mpeg7:general kimia99:paper
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, write_json  # noqa: E402

from shapetree._bench import headline  # noqa: E402
from shapetree._cache import cache_root  # noqa: E402
from shapetree.matching import OPTIONS, PRESETS  # noqa: E402
from shapetree.retrieval import evaluate  # noqa: E402

SETS = ("kimia99", "swedish_leaf", "mpeg7")


def _parse(spec: str) -> tuple[str, str, dict]:
    """``SET:PRESET[+OPTION=VALUE...]`` -> (set, preset, changes)."""
    name, _, rest = spec.partition(":")
    preset, *changes = rest.split("+")
    opts = {}
    for ch in changes:
        key, _, value = ch.partition("=")
        typ = OPTIONS[key]["type"]
        opts[key] = None if value.lower() == "none" else typ(value)
    if name not in SETS or preset not in PRESETS:
        raise SystemExit(f"bad run {spec!r}: expected SET:PRESET[+OPTION=VALUE...]")
    return name, preset, opts


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument(
        "runs",
        nargs="+",
        metavar="SET:PRESET[+OPTION=VALUE...]",
        help="e.g. mpeg7:general kimia99:paper swedish_leaf:general+length_power=1.0",
    )
    ap.add_argument("--cache-dir", default=str(cache_root() / "distances" / "presets"))
    args = ap.parse_args(argv)
    table_path = RESULTS / "presets.json"
    table = json.loads(table_path.read_text()) if table_path.exists() else {"runs": {}}
    for spec in args.runs:
        name, preset, opts = _parse(spec)
        flags = "".join(f" --{k.replace('_', '-')} {v}" for k, v in opts.items())
        command = f"shapetree evaluate {name} --preset {preset}{flags}"
        label = spec.replace("/", "_").replace(":", "_")
        rec = evaluate(
            name,
            preset,
            json_path=RESULTS / "presets" / f"{label}.json",
            cache_dir=args.cache_dir,
            command=command + f" --cache-dir {args.cache_dir}",
            progress=True,
            **opts,
        )
        table["runs"][spec] = {
            "preset": preset,
            "changes": opts,
            "dataset": name,
            "command": command,
            "score": headline(name, rec),
            "accuracy_std": rec.get("accuracy_std"),
            "seconds_matrix": rec["seconds_matrix"],
            "config": rec["config"],
            "measure": rec["measure"],
        }
        write_json(table_path, table)
        print(f"{spec:45s} {headline(name, rec)}  ({rec['seconds_matrix']} s)", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
