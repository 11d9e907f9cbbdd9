"""``shapetree evaluate``: the paper's §5 benchmarks and the ETHZ detection protocol."""

from __future__ import annotations

import argparse
import ast
import shlex
from pathlib import Path
from typing import Any

from shapetree._errors import ShapeTreeError
from shapetree.cli._common import Formatter, info, positive_int, require
from shapetree.cli._options import add_config_options, config_from_args, preset_of
from shapetree.matching import OPTIONS

EVAL_SETS = ("kimia99", "mpeg7", "swedish_leaf", "ethz")

EVALUATE_EPILOG = """\
examples:
  shapetree evaluate kimia99 --json kimia99.json --out results/
  shapetree evaluate mpeg7 --preset mpeg7 --json mpeg7.json   # the setting tuned on MPEG-7
  shapetree evaluate swedish_leaf --preset paper --n-points 100
  shapetree evaluate ethz --classes swans bottles --workers 4 --json ethz.json --out results/

kimia99 / mpeg7 / swedish_leaf run shapetree.retrieval.evaluate (all-pairs distances,
cached and resumable, then the dataset's protocol: Kimia top-10 ranks, MPEG-7 bull's-eye,
Swedish-leaf 1-NN accuracy); ethz runs shapetree.detection.evaluate_ethz (detection rate
at 0.3 / 0.4 false positives per image). Fetch the data first: shapetree datasets fetch.
Long runs show progress bars with an ETA.
"""


def _literal(text: str) -> Any:
    low = text.lower()
    if low in ("true", "yes", "on"):
        return True
    if low in ("false", "no", "off"):
        return False
    if low in ("none", "null"):
        return None
    try:
        return ast.literal_eval(text)
    except (ValueError, SyntaxError):
        return text


def key_value(text: str) -> tuple[str, Any]:
    """argparse type: ``KEY=VALUE`` with VALUE read as a Python literal when possible."""
    key, sep, value = text.partition("=")
    key = key.strip().replace("-", "_")
    if not sep or not key.isidentifier():
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {text!r}")
    return key, _literal(value.strip())


def _typed(default: Any):
    if isinstance(default, bool):
        return _literal
    if isinstance(default, int):
        return int
    if isinstance(default, float):
        return float
    return _literal


def add_parsers(sub: argparse._SubParsersAction, *, full: bool = False) -> None:
    """Register ``evaluate``.

    Parameters
    ----------
    sub : argparse subparsers
    full : bool
        Also add one option per entry of ``shapetree.retrieval.EVAL_PARAMS`` (imports the
        retrieval package, so only done when ``evaluate`` is the command being run).
    """
    p = sub.add_parser(
        "evaluate",
        help="run a benchmark protocol (retrieval on kimia99/mpeg7/swedish_leaf, or ETHZ)",
        description="Run a benchmark of the paper's section 5 on an installed dataset and "
        "print (and optionally save) the scores.",
        epilog=EVALUATE_EPILOG,
        formatter_class=Formatter,
    )
    p.add_argument("dataset", choices=EVAL_SETS, help="which benchmark")
    p.add_argument("--json", metavar="PATH", help="write the scores as JSON")
    p.add_argument("--out", metavar="DIR", help="folder for figures (and caches)")
    p.add_argument(
        "-p",
        "--param",
        type=key_value,
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="set a parameter by name (repeatable); retrieval: a matching option or a "
        "protocol option; ethz: a DetectParams field",
    )
    p.add_argument("--no-progress", action="store_true", help="hide progress bars")
    g = p.add_argument_group("options of both kinds of benchmark")
    g.add_argument(
        "--classes",
        nargs="+",
        metavar="CLASS",
        default=argparse.SUPPRESS,
        help="subset of classes (quick runs); ethz: applelogos bottles giraffes mugs swans "
        "(default: all)",
    )
    g.add_argument(
        "-k",
        type=positive_int,
        default=argparse.SUPPRESS,
        metavar="K",
        help="mpeg7: bull's-eye neighbourhood (default 40); ethz: detections kept per image "
        "(default 5)",
    )
    g.add_argument(
        "--workers",
        type=positive_int,
        default=argparse.SUPPRESS,
        metavar="W",
        help="threads (retrieval) or processes (ethz) (default 2)",
    )
    g.add_argument(
        "--cache-dir",
        dest="cache_dir",
        metavar="DIR",
        default=argparse.SUPPRESS,
        help="resumable cache (default $SHAPETREE_CACHE/distances/<set> for retrieval and "
        "$SHAPETREE_CACHE/ethz_detect for ethz; without SHAPETREE_CACHE under "
        "~/.cache/shapetree)",
    )
    g.add_argument(
        "--no-cache",
        action="store_true",
        help="retrieval: do not cache finished blocks (no resume after a kill)",
    )
    g = p.add_argument_group("ETHZ options (evaluate ethz)")
    g.add_argument(
        "--data",
        metavar="DIR",
        default=argparse.SUPPRESS,
        help="ETHZ folder (default: the installed ethz_shape dataset)",
    )
    g.add_argument(
        "--edges",
        choices=("pb", "own", "pidinet"),
        default="pb",
        help="edge source: pb = the Berkeley Pb maps shipped with the dataset, own = the "
        "project's own edge map computed from each image, pidinet = the learned PiDiNet "
        "map (needs --edge-weights); a computed map is made once per image and cached",
    )
    g.add_argument(
        "--edge-weights",
        metavar="PATH",
        default=None,
        help="--edges pidinet: a PiDiNet weights file (table5_*.npz; the authors' BSDS500 "
        "checkpoints, research use only, not shipped with shapetree)",
    )
    dynamic: list[str] = ["classes", "k", "workers", "cache_dir"]
    if full:
        from shapetree.retrieval import EVAL_PARAMS

        add_config_options(p)
        taken = {a.dest for a in p._actions}
        r = p.add_argument_group("protocol options (evaluate kimia99 / mpeg7 / swedish_leaf)")
        for key, spec in EVAL_PARAMS.items():
            if key in taken:
                continue
            typ, default, choices = spec["type"], spec["default"], spec.get("choices")
            r.add_argument(
                "--" + key.replace("_", "-"),
                dest=key,
                default=argparse.SUPPRESS,
                type=typ if isinstance(typ, type) else _typed(default),
                choices=choices,
                metavar=None if choices else "V",
                help=f"{spec['help']} (default: {default})",
            )
            dynamic.append(key)
    p.set_defaults(func=cmd_evaluate, eval_dynamic=dynamic)


def _print_scores(scores: Any, indent: str = "") -> None:
    if not isinstance(scores, dict):
        info(f"{indent}{scores}")
        return
    for key, value in scores.items():
        if isinstance(value, dict):
            info(f"{indent}{key}:")
            _print_scores(value, indent + "  ")
        elif isinstance(value, list | tuple) and len(value) > 12:
            info(f"{indent}{key}: [{len(value)} values]")
        else:
            info(f"{indent}{key}: {value}")


def _detect_params(pairs: list[tuple[str, Any]]) -> Any:
    if not pairs:
        return None
    cls = require("shapetree.detection", "DetectParams", "detection parameters")
    try:
        return cls(**dict(pairs))
    except TypeError as exc:
        raise ShapeTreeError(f"bad detection parameter: {exc}") from None


def _default_distance_cache(dataset: str) -> Path:
    """Where ``shapetree evaluate`` keeps its resumable distance blocks by default."""
    from shapetree._cache import cache_root

    return cache_root() / "distances" / dataset


def cmd_evaluate(args: argparse.Namespace) -> int:
    """``shapetree evaluate``."""
    progress = not args.no_progress
    if args.dataset == "ethz":
        evaluate_ethz = require("shapetree.detection", "evaluate_ethz", "the ETHZ evaluation")
        kwargs: dict[str, Any] = {}
        for name in ("k", "workers", "classes", "cache_dir"):
            if hasattr(args, name):
                kwargs[name] = getattr(args, name)
        params = _detect_params(args.param)
        if params is not None:
            kwargs["params"] = params
        scores = evaluate_ethz(
            getattr(args, "data", None),
            json_path=args.json,
            out_dir=args.out,
            progress=progress,
            edges=args.edges,
            edge_weights=args.edge_weights,
            **kwargs,
        )
    else:
        evaluate = require("shapetree.retrieval", "evaluate", f"evaluating {args.dataset}")
        params = dict(args.param)
        for key in args.eval_dynamic:
            if hasattr(args, key):
                params[key] = getattr(args, key)
        config_from_args(args)  # validates the matching flags (one clear error)
        params.update({k: getattr(args, k) for k in OPTIONS if hasattr(args, k)})
        if getattr(args, "no_cache", False):
            params["cache_dir"] = None
        elif params.get("cache_dir") is None:
            params["cache_dir"] = str(_default_distance_cache(args.dataset))
        command = " ".join(["shapetree", *(shlex.quote(a) for a in args.argv)])
        try:
            evaluate(
                args.dataset,
                preset_of(args),
                json_path=args.json,
                out_dir=args.out,
                progress=progress,
                verbose=True,  # prints the paper's table with our row on top
                command=command,
                **params,
            )
        except TypeError as exc:
            raise ShapeTreeError(f"bad evaluation parameter: {exc}") from None
        scores = None
    if scores is not None:
        info(f"{args.dataset}:")
        _print_scores(scores, "  ")
    if args.json:
        info(f"json: {args.json}")
    if args.out:
        info(f"figures: {args.out}")
    return 0
