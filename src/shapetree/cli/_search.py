"""``shapetree search`` and ``shapetree distances``: retrieval on the user's own shapes."""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path
from typing import Any

import numpy as np

from shapetree._atomic import atomic_open
from shapetree._errors import ShapeTreeError
from shapetree.cli._common import (
    DEMO_PREFIX,
    Formatter,
    info,
    load_shape,
    positive_int,
    warn,
    write_json,
)
from shapetree.cli._evaluate import _default_distance_cache
from shapetree.cli._options import add_config_options, config_from_args, preset_of

SEARCH_EPILOG = """\
examples:
  shapetree search query.png shapes/                 # 10 nearest shapes of a folder
  shapetree search query.png shapes/ -k 5 --plot top5.png --json top5.json
  shapetree search demo:G demo:S demo:hand demo:G    # any mix of files and demo shapes
  shapetree search query.png shapes.stidx            # a database (shapetree index build)

The distance of a database shape x is the same number `shapetree match QUERY x` prints
with the same options: by default (--preset general) psi(query deformed onto x), the lesser
of the query and its mirror image. Folders are read for images (png, gif, bmp, tif, jpg,
pgm...) and point files (csv, txt, npy, json). A database (.stidx, given alone) brings its
own matching options: flags that disagree with them are an error.
"""

DISTANCES_EPILOG = """\
examples:
  shapetree distances shapes/ -o D.npz               # all pairs, resumable
  shapetree distances shapes/ -o D.npz --csv D.csv --symmetrize mean
  shapetree distances shapes/ -o D.npz --preset paper --n-points 64
  shapetree distances shapes.stidx -o D.npz          # a database (shapetree index build)
  shapetree distances shapes/ -o NN.npz --neighbours 10  # each shape's 10 nearest, exactly
  shapetree distances shapes/ -o D.npz --dask local:4     # 4 worker processes (Dask)
  shapetree distances shapes/ -o D.npz --dask tcp://10.0.0.5:8786  # a running cluster
  shapetree distances shapes/ -o NN.npz --neighbours 10 --dask local:4  # both

The .npz holds D (n x n, row = query), names (n file names) and config (JSON text):
  z = numpy.load("D.npz"); D, names = z["D"], z["names"]
With --neighbours K it holds instead indices and distances (n x K, nearest first, ties by
index), found by the exact pruned search (the same numbers as the full matrix's K smallest
per row), and the CSV has one line per (shape, rank, neighbour, distance).
Finished row blocks are cached (default $SHAPETREE_CACHE/distances/custom), so a run that
is interrupted resumes where it stopped when started again with the same shapes and options.
"""

#: Extensions read from a folder: images and point files.
_POINT_EXTENSIONS = (".csv", ".txt", ".npy", ".json")


def _natural_key(path: Path) -> list[Any]:
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", path.name)]


def expand_specs(specs: list[str]) -> list[str]:
    """Files, ``demo:NAME`` shapes, and folders (their image and point files, sorted).

    Parameters
    ----------
    specs : list of str

    Returns
    -------
    list of str
        One entry per shape.

    Raises
    ------
    ShapeTreeError
        A path that does not exist, or a folder without any shape file.
    """
    from shapetree.curves._image import IMAGE_EXTENSIONS

    exts = set(IMAGE_EXTENSIONS) | set(_POINT_EXTENSIONS)
    out: list[str] = []
    for spec in specs:
        if spec.startswith(DEMO_PREFIX):
            out.append(spec)
            continue
        p = Path(spec)
        if p.is_dir():
            files = sorted(
                (f for f in p.iterdir() if f.is_file() and f.suffix.lower() in exts),
                key=_natural_key,
            )
            if not files:
                raise ShapeTreeError(
                    f"{p}: folder has no shape files (images or {', '.join(_POINT_EXTENSIONS)})"
                )
            out += [str(f) for f in files]
        elif p.exists():
            out.append(spec)
        else:
            raise ShapeTreeError(f"{spec}: no such file or folder")
    return out


def read_outline(spec: str) -> np.ndarray:
    """One closed outline as traced or stored (the matcher configuration samples it)."""
    shape = load_shape(spec, n_points=None, closed=True)
    if not shape.closed:
        raise ShapeTreeError(f"{spec}: is an open curve; search compares closed outlines")
    return shape.points


def load_shapes(
    specs: list[str], *, skip_bad: bool, progress: bool
) -> tuple[list[np.ndarray], list[str]]:
    """Read every shape as a closed curve; report every bad file, not just the first.

    Returns
    -------
    curves : list of ndarray, each shape (k_i, 2)
        The outlines as read.
    names : list of str
        The spec of each curve that was read.
    """
    from tqdm.auto import tqdm

    curves: list[np.ndarray] = []
    names: list[str] = []
    bad: list[str] = []
    for spec in tqdm(specs, desc="reading shapes", unit="shape", disable=not progress):
        try:
            curves.append(read_outline(spec))
        except (ShapeTreeError, OSError) as exc:
            bad.append(" ".join(str(exc).split()))
            continue
        names.append(spec)
    if bad:
        listing = "; ".join(bad[:5]) + (f"; and {len(bad) - 5} more" if len(bad) > 5 else "")
        if not skip_bad:
            raise ShapeTreeError(
                f"{len(bad)} of {len(specs)} shapes could not be read ({listing}); "
                "fix or remove them, or pass --skip-bad"
            )
        warn(f"skipped {len(bad)} unreadable shape(s): {listing}")
    return curves, names


def _add_run_options(p: argparse.ArgumentParser) -> None:
    add_config_options(p)
    p.add_argument("--workers", type=positive_int, default=2, metavar="W", help="threads")
    p.add_argument(
        "--skip-bad",
        action="store_true",
        help="skip unreadable shapes with a warning instead of stopping with a list of them",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bars")


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """Register ``search`` and ``distances``."""
    p = sub.add_parser(
        "search",
        help="rank a collection of shapes by similarity to a query shape",
        description="Rank database shapes (files, folders, demo:NAME) by the shape-tree "
        "deformation cost of the query onto each, and print the nearest ones.",
        epilog=SEARCH_EPILOG,
        formatter_class=Formatter,
    )
    p.add_argument("query", metavar="QUERY", help="query shape: image, point file or demo:NAME")
    p.add_argument(
        "database", metavar="SHAPE", nargs="+", help="shape files or folders, or a .stidx database"
    )
    p.add_argument("-k", type=positive_int, default=10, metavar="K", help="results shown")
    p.add_argument("--plot", metavar="PNG", help="draw the query and its K nearest shapes")
    p.add_argument("--json", metavar="PATH", help="write the full ranking as JSON")
    _add_run_options(p)
    p.set_defaults(func=cmd_search)

    p = sub.add_parser(
        "distances",
        help="all-pairs shape-tree distances of a collection (resumable), to .npz/.csv",
        description="Compute the matrix of shape-tree distances between all shapes given "
        "(files, folders, demo:NAME) on all cores, with a progress bar and a resumable cache.",
        epilog=DISTANCES_EPILOG,
        formatter_class=Formatter,
    )
    p.add_argument(
        "shapes", metavar="SHAPE", nargs="+", help="shape files or folders, or one .stidx database"
    )
    p.add_argument("-o", "--output", metavar="NPZ", required=True, help="output .npz file")
    p.add_argument("--csv", metavar="PATH", help="also write the matrix as CSV with names")
    p.add_argument(
        "--cache",
        metavar="DIR",
        default=None,
        help="resumable block cache (default: $SHAPETREE_CACHE/distances/custom)",
    )
    p.add_argument("--no-cache", action="store_true", help="do not cache finished blocks")
    p.add_argument(
        "--neighbours",
        type=positive_int,
        metavar="K",
        default=None,
        help="only each shape's K nearest, exactly, by the pruned search (a lower bound "
        "skips the pairs that cannot be among them); needs --n-points",
    )
    p.add_argument(
        "--dask",
        metavar="ADDRESS",
        default=None,
        help="run the row blocks (with --neighbours: the blocks of queries of the pruned "
        "search) on a dask.distributed cluster: a scheduler address (tcp://host:8786) or "
        "local:N (N worker processes on this machine); the same cache and bitwise the same "
        "numbers as the threads (pip install 'shapetree[dask]')",
    )
    _add_run_options(p)
    p.set_defaults(func=cmd_distances)


def _load_args(specs: list[str], args: argparse.Namespace) -> tuple[list[np.ndarray], list[str]]:
    return load_shapes(expand_specs(specs), skip_bad=args.skip_bad, progress=not args.no_progress)


def cmd_search(args: argparse.Namespace) -> int:
    """``shapetree search``."""
    from shapetree.matching._api import model_curve
    from shapetree.plotting._save import check_figure_path
    from shapetree.retrieval import search

    if args.plot:
        check_figure_path(args.plot)
    from shapetree.cli._index import load_index_arg

    progress = not args.no_progress
    index = load_index_arg(args.database, args)
    config = index.config if index is not None else config_from_args(args)
    source = f"preset {preset_of(args)}" if index is None else f"of {args.database[0]}"
    query_points = read_outline(args.query)
    if index is not None:
        curves, names, database = index.outlines, index.names, index
    else:
        curves, names = _load_args(args.database, args)
        database = curves
    order, dist = search(query_points, database, config, progress=progress, workers=args.workers)
    d = np.empty(len(order))
    d[order] = dist
    k = min(args.k, len(order))
    info(f"query {args.query}: {k} nearest of {len(names)} shapes (smaller = more similar)")
    info(f"configuration: {source} ({config.describe()})")
    info(f"{'rank':>4}  {'distance':>9}  shape")
    for r, j in enumerate(order[:k], start=1):
        info(f"{r:>4}  {d[j]:9.5f}  {Path(names[j]).name}")
    if args.json:
        path = write_json(
            args.json,
            {
                "query": args.query,
                "preset": preset_of(args) if index is None else None,
                "database": args.database[0] if index is not None else None,
                "config": config.as_dict(),
                "ranking": [
                    {"rank": r, "shape": names[j], "distance": float(d[j])}
                    for r, j in enumerate(order, start=1)
                ],
            },
        )
        info(f"json: {path}")
    if args.plot:
        from shapetree.plotting._retrieval import save_search as plot_search

        path = plot_search(
            model_curve(query_points, config),
            [index.models[j] if index else model_curve(curves[j], config) for j in order[:k]],
            [f"{Path(names[j]).name}\n{d[j]:.4f}" for j in order[:k]],
            args.plot,
            title=f"{Path(args.query).name}: nearest shapes",
        )
        info(f"picture: {path}")
    return 0


def cmd_distances(args: argparse.Namespace) -> int:
    """``shapetree distances``."""
    from shapetree.retrieval import distance_matrix

    out = Path(args.output)
    if out.suffix.lower() != ".npz":
        raise ShapeTreeError(f"{out}: the output must be a .npz file")
    if out.is_dir():
        raise ShapeTreeError(f"{out}: is a directory, expected a .npz file name")
    if args.csv and Path(args.csv).is_dir():
        raise ShapeTreeError(f"{args.csv}: is a directory, expected a .csv file name")
    from shapetree.cli._index import load_index_arg

    progress = not args.no_progress
    index = load_index_arg(args.shapes, args)
    if index is not None:
        curves, names = index, index.names
    else:
        curves, names = _load_args(args.shapes, args)
    if len(curves) < 2:
        raise ShapeTreeError(f"need at least 2 shapes, got {len(curves)}")
    cache = (
        None
        if args.no_cache
        else Path(args.cache)
        if args.cache
        else _default_distance_cache("custom")
    )
    config = index.config if index is not None else config_from_args(args)
    meta = {"preset": preset_of(args) if index is None else None, "config": config.as_dict()}
    if index is not None:
        meta["database"] = args.shapes[0]
    if args.neighbours is not None:
        return _write_neighbours(args, curves, names, config, cache, meta, out)
    d = distance_matrix(
        curves,
        None,
        config,
        progress=progress,
        cache_dir=cache,
        workers=args.workers,
        scheduler=args.dask,
    )
    d = np.maximum(d, 0.0)
    with atomic_open(out, "wb") as fh:
        np.savez(fh, D=d, names=np.array(names), config=np.array(json.dumps(meta)))
    info(f"{len(names)} shapes, {len(names) ** 2} ordered pairs -> {out}")
    if args.csv:
        csv = Path(args.csv)
        with atomic_open(csv, "w") as fh:
            fh.write("," + ",".join(_csv_field(Path(n).name) for n in names) + "\n")
            for n, row in zip(names, d):
                fh.write(_csv_field(Path(n).name) + "," + ",".join(f"{v:.8g}" for v in row) + "\n")
        info(f"csv: {csv}")
    return 0


def _write_neighbours(
    args: argparse.Namespace,
    curves: Any,
    names: list[str],
    config: Any,
    cache: Path | None,
    meta: dict,
    out: Path,
) -> int:
    """``shapetree distances --neighbours K``: each shape's K nearest, exactly."""
    from shapetree.retrieval import knn

    if config.n_points is None:
        raise ShapeTreeError("--neighbours needs every shape resampled to one size: set --n-points")
    stats: dict = {}
    idx, dist = knn(
        curves,
        curves,
        config,
        k=args.neighbours,
        workers=args.workers,
        cache_dir=cache,
        progress=not args.no_progress,
        stats=stats,
        scheduler=args.dask,
    )
    meta["neighbours"] = {"k": int(idx.shape[1]), "skipped": round(stats["skipped"], 4)}
    with atomic_open(out, "wb") as fh:
        np.savez(
            fh,
            indices=idx,
            distances=dist,
            names=np.array(names),
            config=np.array(json.dumps(meta)),
        )
    n = len(names)
    info(
        f"{n} shapes, their {idx.shape[1]} nearest each -> {out}: {stats['full']} of "
        f"{n * n} ordered pairs matched in full ({100 * stats['skipped']:.1f}% skipped by "
        "the lower bound)"
    )
    if args.csv:
        csv = Path(args.csv)
        with atomic_open(csv, "w") as fh:
            fh.write("shape,rank,neighbour,distance\n")
            for i in range(n):
                a = _csv_field(Path(names[i]).name)
                for r in range(idx.shape[1]):
                    b = _csv_field(Path(names[idx[i, r]]).name)
                    fh.write(f"{a},{r + 1},{b},{dist[i, r]:.8g}\n")
        info(f"csv: {csv}")
    return 0


def _csv_field(text: str) -> str:
    if any(c in text for c in ',"\n'):
        return '"' + text.replace('"', '""') + '"'
    return text


__all__ = ["add_parsers", "cmd_distances", "cmd_search", "expand_specs", "load_shapes"]
