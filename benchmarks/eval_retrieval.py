"""Run one of the paper's §5.1 benchmarks and commit-ready results (Tables 1–3).

Calls :func:`shapetree.retrieval.evaluate` (the same function as ``shapetree evaluate``)
with a resumable block cache, writes ``benchmarks/results/<dataset>.json`` and the pictures
beside it, then re-reads the cached directed costs to add an ablation (mirror on/off ×
every symmetrisation) to the JSON at no extra matching cost.

Run (long runs in the background; a killed run resumes from its cache)::

    SHAPETREE_DATA=../shared/datasets nohup python benchmarks/eval_retrieval.py mpeg7 &
    python benchmarks/eval_retrieval.py kimia99 --no-cache     # timed from scratch
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS  # noqa: E402

from shapetree._bench import protocol_score  # noqa: E402
from shapetree.matching import OPTIONS, PRESETS  # noqa: E402
from shapetree.matching._config import SYMMETRIZE  # noqa: E402
from shapetree.retrieval import EVAL_PARAMS, combine, evaluate  # noqa: E402

#: The ablation's value per set: the rank row, the bull's-eye, or [mean, std] accuracy.
_HEADLINE = {
    "kimia99": lambda r: r["ranks"],
    "mpeg7": lambda r: r["bullseye"],
    "swedish_leaf": lambda r: [r["accuracy_mean"], r["accuracy_std"]],
}


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("dataset", choices=["kimia99", "mpeg7", "swedish_leaf"])
    ap.add_argument("--preset", choices=list(PRESETS), default="general")
    for k, spec in {**OPTIONS, **EVAL_PARAMS}.items():
        flag = "--" + k.replace("_", "-")
        if spec["type"] is bool:
            ap.add_argument(
                flag, action=argparse.BooleanOptionalAction, default=None, help=spec["help"]
            )
        else:
            ap.add_argument(
                flag,
                type=lambda t, typ=spec["type"]: None if t.lower() == "none" else typ(t),
                default=None,
                help=spec["help"],
                choices=spec.get("choices"),
            )
    ap.add_argument("--no-cache", action="store_true", help="no block cache (timed from scratch)")
    ap.add_argument("--json", default=None, help="default benchmarks/results/<dataset>.json")
    ap.add_argument("--out-dir", default=str(RESULTS))
    ap.add_argument("--no-ablation", action="store_true")
    args = ap.parse_args(argv)
    params = {
        k: getattr(args, k) for k in {**OPTIONS, **EVAL_PARAMS} if getattr(args, k) is not None
    }
    if args.no_cache:
        params.pop("cache_dir", None)
    else:
        params.setdefault(
            "cache_dir", str(Path.home() / ".cache" / "shapetree" / "distances" / args.dataset)
        )
    json_path = Path(args.json or RESULTS / f"{args.dataset}.json")
    command = "python benchmarks/eval_retrieval.py " + " ".join(shlex.quote(a) for a in argv)
    arrays: dict = {}
    rec = evaluate(
        args.dataset,
        args.preset,
        json_path=json_path,
        out_dir=args.out_dir,
        command=command,
        arrays=arrays,
        **params,
    )
    p = rec["params"]
    if not args.no_ablation and rec["config"]["mirror"]:
        c, labels = arrays["costs"], arrays["labels"]
        rec["ablation"] = {
            f"mirror={mir} symmetrize={s}": _HEADLINE[args.dataset](
                protocol_score(args.dataset, combine(c if mir else c[:1], s), labels, p)
            )
            for mir in (False, True)
            for s in SYMMETRIZE
        }
        json_path.write_text(json.dumps(rec, indent=2) + "\n")
        for k, v in rec["ablation"].items():
            print(f"  {k:35s} {v}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
