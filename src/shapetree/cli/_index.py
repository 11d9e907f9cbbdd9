"""``shapetree index build / add / info``: a prepared shape database (a ``.stidx`` file).

The file and its checks are :class:`shapetree.retrieval.ShapeIndex`; ``shapetree search
QUERY DB.stidx`` and ``shapetree distances DB.stidx`` read it in place of shape folders.
"""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from shapetree._errors import ShapeTreeError
from shapetree.cli._common import Formatter, info, warn
from shapetree.cli._options import add_config_options, config_from_args
from shapetree.matching import OPTIONS, MatchConfig
from shapetree.retrieval._index import EXTENSION, ShapeIndex, is_index_path

INDEX_EPILOG = f"""\
examples:
  shapetree index build shapes/ -o shapes{EXTENSION}            # every shape of a folder
  shapetree index build shapes/ --preset paper --n-points 64 -o paper{EXTENSION}
  shapetree index add shapes{EXTENSION} more/ extra.csv          # append shapes
  shapetree index info shapes{EXTENSION}                         # what is in it
  shapetree search query.png shapes{EXTENSION} -k 5              # search it
  shapetree distances shapes{EXTENSION} -o D.npz                 # all pairs of it

A database keeps every shape's outline, its curves as the matcher samples them, the names,
the matching options, the shapetree version and a checksum of each array. It is used only
with the options, version and code it was built with; rebuild one from itself with
  shapetree index build old{EXTENSION} [--preset NAME --OPTION V ...] -o new{EXTENSION}
"""

BUILD_EPILOG = f"""\
examples:
  shapetree index build shapes/ -o shapes{EXTENSION}
  shapetree index build a.png b.csv shapes/ --preset mpeg7 -o db{EXTENSION} --skip-bad
  shapetree index build old{EXTENSION} --n-points 64 -o new{EXTENSION}   # rebuild from its outlines

SHAPE is an image (silhouette), a point file (.csv/.txt/.npy/.json), demo:NAME, a folder
(its images and point files, sorted) or a {EXTENSION} database (its outlines and names).
The matching options are fixed at build time: search and distances use them.
"""

ADD_EPILOG = f"""\
examples:
  shapetree index add shapes{EXTENSION} new-shapes/
  shapetree index add shapes{EXTENSION} a.png b.csv --skip-bad

The new shapes are sampled with the database's own options; names already in it are
skipped with a warning. The file is replaced atomically.
"""

INFO_EPILOG = f"""\
examples:
  shapetree index info shapes{EXTENSION}
  shapetree index info shapes{EXTENSION} --names

Shows the number of shapes, the samples, the matching options (as the differences from the
general preset), the shapetree version that built it and whether this one can use it.
"""


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """Register ``index`` with ``build``, ``add`` and ``info``."""
    p = sub.add_parser(
        "index",
        help=f"build, extend or describe a prepared shape database ({EXTENSION})",
        description="A prepared shape database: build one from shape files and folders, "
        "append shapes, or describe one. search and distances accept it in place of folders.",
        epilog=INDEX_EPILOG,
        formatter_class=Formatter,
    )
    isub = p.add_subparsers(dest="index_command", metavar="{build,add,info}", required=True)

    b = isub.add_parser(
        "build",
        help="read shapes and write a database",
        description="Read every shape (files, folders, demo:NAME, databases), validate and "
        "sample it with the matching options, and write them all to one checksummed file.",
        epilog=BUILD_EPILOG,
        formatter_class=Formatter,
    )
    b.add_argument("shapes", metavar="SHAPE", nargs="+", help="shape files, folders, databases")
    b.add_argument(
        "-o", "--output", metavar="DB", required=True, help=f"the database file ({EXTENSION})"
    )
    add_config_options(b)
    _add_read_options(b)
    b.set_defaults(func=cmd_build)

    a = isub.add_parser(
        "add",
        help="append shapes to a database",
        description="Read more shapes, sample them with the database's options and append "
        "them (the file is replaced atomically).",
        epilog=ADD_EPILOG,
        formatter_class=Formatter,
    )
    a.add_argument("db", metavar="DB", help=f"the database file ({EXTENSION})")
    a.add_argument("shapes", metavar="SHAPE", nargs="+", help="shape files or folders")
    _add_read_options(a)
    a.set_defaults(func=cmd_add)

    i = isub.add_parser(
        "info",
        help="describe a database",
        description="Describe a database and check it (checksums, version, options).",
        epilog=INFO_EPILOG,
        formatter_class=Formatter,
    )
    i.add_argument("db", metavar="DB", help=f"the database file ({EXTENSION})")
    i.add_argument("--names", action="store_true", help="also list every shape name")
    i.set_defaults(func=cmd_info)


def _add_read_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--skip-bad",
        action="store_true",
        help="skip unreadable shapes with a warning instead of stopping with a list of them",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bars")


def _check_output(path: str) -> Path:
    out = Path(path)
    if not is_index_path(out):
        raise ShapeTreeError(f"{out}: a shape database file name must end in {EXTENSION}")
    if out.is_dir():
        raise ShapeTreeError(f"{out}: is a directory, expected a {EXTENSION} file name")
    return out


def _read_sources(
    specs: list[str], *, skip_bad: bool, progress: bool, allow_index: bool
) -> tuple[list[np.ndarray], list[str]]:
    """Outlines and names of shape specs, in order; databases give their outlines."""
    from shapetree.cli._search import expand_specs, load_shapes

    curves: list[np.ndarray] = []
    names: list[str] = []
    files: list[str] = []

    def flush() -> None:
        if files:
            c, n = load_shapes(expand_specs(files), skip_bad=skip_bad, progress=progress)
            curves.extend(c)
            names.extend(n)
            files.clear()

    for spec in specs:
        if is_index_path(spec):
            if not allow_index:
                raise ShapeTreeError(
                    f"{spec}: is a shape database; only shape files and folders can be added "
                    f"(to merge databases: shapetree index build A{EXTENSION} B{EXTENSION} -o C)"
                )
            flush()
            src = ShapeIndex._read(spec)  # outlines only: any version or options will do
            curves.extend(src.outlines)
            names.extend(src.names)
        else:
            files.append(spec)
    flush()
    return curves, names


def _unique(
    curves: list[np.ndarray], names: list[str], taken: set[str]
) -> tuple[list[np.ndarray], list[str]]:
    keep_c, keep_n, dup = [], [], []
    seen = set(taken)
    for c, n in zip(curves, names):
        if n in seen:
            dup.append(n)
            continue
        seen.add(n)
        keep_c.append(c)
        keep_n.append(n)
    if dup:
        listing = ", ".join(dup[:5]) + (f" and {len(dup) - 5} more" if len(dup) > 5 else "")
        warn(f"skipped {len(dup)} shape(s) already in the database: {listing}")
    return keep_c, keep_n


def cmd_build(args: argparse.Namespace) -> int:
    """``shapetree index build``."""
    out = _check_output(args.output)
    progress = not args.no_progress
    config = config_from_args(args)
    curves, names = _read_sources(
        args.shapes, skip_bad=args.skip_bad, progress=progress, allow_index=True
    )
    curves, names = _unique(curves, names, set())
    if not curves:
        raise ShapeTreeError("no shapes to put in the database")
    index = ShapeIndex.build(curves, names, config, progress=progress)
    index.save(out)
    info(f"{len(index)} shapes -> {out}")
    info(f"configuration: {config.describe()}")
    return 0


@contextlib.contextmanager
def _locked(db: Path) -> Iterator[None]:
    """Hold an exclusive lock on ``DB.lock`` (POSIX ``flock``) while a database is read,
    extended and rewritten, so that two ``index add`` runs on one database queue up
    instead of one silently dropping the other's shapes. Where ``fcntl`` is missing
    (Windows) no lock is taken."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows
        yield
        return
    lock = db.with_name(db.name + ".lock")
    with open(lock, "a") as fh:
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh.fileno(), fcntl.LOCK_UN)


def cmd_add(args: argparse.Namespace) -> int:
    """``shapetree index add``."""
    db = _check_output(args.db)
    progress = not args.no_progress
    ShapeIndex.load(db)  # refuse a bad database before reading the shapes
    curves, names = _read_sources(
        args.shapes, skip_bad=args.skip_bad, progress=progress, allow_index=False
    )
    with _locked(db):
        index = ShapeIndex.load(db)  # again, under the lock: another run may have added
        curves, names = _unique(curves, names, set(index.names))
        before = len(index)
        if curves:
            index.add(curves, names, progress=progress)
            index.save(db)
    info(f"added {len(index) - before} shapes; {len(index)} in {db}")
    return 0


def cmd_info(args: argparse.Namespace) -> int:
    """``shapetree index info``."""
    index = ShapeIndex._read(args.db)  # checksums verified; compatibility reported
    info(index.info())
    if args.names:
        for k, n in enumerate(index.names):
            info(f"{k:>6}  {n}")
    return 0


def index_config(args: argparse.Namespace, index: ShapeIndex) -> MatchConfig:
    """The configuration for ``search`` / ``distances`` on a database: the database's own;
    matching flags given must agree with it (a :class:`ShapeTreeError` otherwise)."""
    changes = {name: getattr(args, name) for name in OPTIONS if hasattr(args, name)}
    if hasattr(args, "preset"):
        cfg = MatchConfig.preset(args.preset, **changes)
    else:
        cfg = index.config.replace(**changes)
    index.check_config(cfg)
    return index.config


def load_index_arg(specs: list[str], args: argparse.Namespace) -> ShapeIndex | None:
    """The database among a command's shape arguments (alone), or None when there is none."""
    dbs = [s for s in specs if is_index_path(s)]
    if not dbs:
        return None
    if len(specs) != 1:
        raise ShapeTreeError(
            f"a shape database ({dbs[0]}) must be given alone; add the other shapes to it "
            f"first: shapetree index add {dbs[0]} SHAPE..."
        )
    index = ShapeIndex.load(dbs[0])
    index_config(args, index)
    return index


__all__ = ["add_parsers", "cmd_add", "cmd_build", "cmd_info", "index_config", "load_index_arg"]
