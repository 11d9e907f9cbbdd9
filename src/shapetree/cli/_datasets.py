"""``shapetree datasets``: list and fetch benchmark datasets."""

from __future__ import annotations

import argparse

from shapetree.cli._common import Formatter, info, positive_float, require

DATASETS_EPILOG = """\
examples:
  shapetree datasets
  shapetree datasets fetch mpeg7
  shapetree datasets fetch kimia99 --insecure
  shapetree datasets fetch swedish_leaf --url file:///tmp/leaves.zip --sha256 HEX --force

Datasets live under $SHAPETREE_DATA (default ~/.cache/shapetree/datasets); they are never
shipped with shapetree. Downloads are verified by checksum when one is known and
installed atomically.
"""

FETCH_EPILOG = """\
examples:
  shapetree datasets fetch mpeg7
  shapetree datasets fetch ethz_shape --dest /data/shapes
  shapetree datasets fetch kimia99 --insecure     # no published checksum
"""

NAMES = ("mpeg7", "kimia99", "swedish_leaf", "ethz_shape")


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """Register ``datasets`` (with ``list`` and ``fetch``)."""
    p = sub.add_parser(
        "datasets",
        help="list the benchmark datasets, or fetch one",
        description="List the benchmark datasets and whether they are installed "
        "(no sub-command or 'list'), or download and install one ('fetch').",
        epilog=DATASETS_EPILOG,
        formatter_class=Formatter,
    )
    p.set_defaults(func=cmd_list)
    dsub = p.add_subparsers(dest="datasets_command", metavar="{list,fetch}")
    pl = dsub.add_parser(
        "list",
        help="show which datasets are installed",
        formatter_class=Formatter,
        description="Show each dataset, whether it is installed, its image count and path.",
    )
    pl.set_defaults(func=cmd_list)
    pf = dsub.add_parser(
        "fetch",
        help="download, verify and install a dataset",
        description="Download a dataset archive, verify its checksum, and install it "
        "atomically under the data folder (shows a progress bar).",
        epilog=FETCH_EPILOG,
        formatter_class=Formatter,
    )
    pf.add_argument("name", metavar="NAME", choices=NAMES, help="one of: " + ", ".join(NAMES))
    pf.add_argument("--dest", metavar="DIR", help="data root (default: $SHAPETREE_DATA)")
    pf.add_argument("--url", help="archive address (http(s):// or file://) instead of the default")
    pf.add_argument("--sha256", metavar="HEX", help="expected SHA-256 of the archive")
    pf.add_argument(
        "--insecure",
        action="store_true",
        help="accept a download whose checksum is unknown (prints its SHA-256)",
    )
    pf.add_argument("--force", action="store_true", help="replace an installed copy")
    pf.add_argument(
        "--timeout",
        type=positive_float,
        default=60.0,
        metavar="SEC",
        help="network timeout in seconds",
    )
    pf.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    pf.set_defaults(func=cmd_fetch)


def cmd_list(args: argparse.Namespace) -> int:
    """``shapetree datasets [list]``."""
    fmt = require("shapetree.datasets", "format_available", "listing datasets")
    info(fmt())
    return 0


def cmd_fetch(args: argparse.Namespace) -> int:
    """``shapetree datasets fetch``."""
    fetch = require("shapetree.datasets", "fetch", "fetching datasets")
    path = fetch(
        args.name,
        dest=args.dest,
        url=args.url,
        sha256=args.sha256,
        progress=not args.no_progress,
        insecure=args.insecure,
        force=args.force,
        timeout=args.timeout,
    )
    info(f"installed {args.name} in {path}")
    return 0
