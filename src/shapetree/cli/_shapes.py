"""Commands on shapes: ``match``, ``tree`` and ``deform``."""

from __future__ import annotations

import argparse
from pathlib import Path

from shapetree.cli._common import (
    DEFAULT_POINTS,
    Formatter,
    info,
    load_shape,
    nonneg_float,
    points_int,
    positive_int,
    write_json,
)
from shapetree.cli._options import add_config_options, config_from_args, preset_of

SHAPE_HELP = (
    "an image (its silhouette's outer boundary), a point file (.csv/.txt/.npy/.json, "
    "two numbers x y per point), or demo:NAME for an embedded shape (demo:hand, demo:G, ...)"
)

MATCH_EPILOG = """\
examples:
  shapetree match demo:G demo:S
  shapetree match bone-01.png bone-07.png --n-points 100 --plot match.png
  shapetree match a.csv b.csv --open --weight 2 --json match.json
  shapetree match hand.png hand-cut.png --occlusion 0.5 --n-trees 4 --plot occl.png
  shapetree match a.png b.png --preset paper          # the method exactly as published

The cost is psi(A, B) of paper eq. (1): the least shape-tree deformation taking A onto B,
invariant to translation, rotation and scale (and, with --mirror, reflection). Closed
curves (the default) try every cyclic alignment of B. The cost is the same number that
shapetree search / distances and the Python API give for the same options.
Pictures: images are drawn upright (y down), point files y up.
"""

TREE_EPILOG = """\
examples:
  shapetree tree demo:hand -o tree.png
  shapetree tree leaf.png --n-points 64 --split best --levels 4 -o leaf-tree.png

One panel per depth (paper Fig. 3): the coarse polygon through the points known so far
(filled), the midpoints added at that depth (open circles) and, faint, the curve.
"""

DEFORM_EPILOG = """\
examples:
  shapetree deform demo:hand -o deform.png
  shapetree deform demo:square --scale 0.02 0.05 0.1 --count 6 --seed 3
  shapetree deform demo:hand demo:square demo:leaf demo:G --scale 0.04   # like Fig. 4
  shapetree deform leaf.png --n-points 80 --scale 0.04 -o leaf-deform.png

Each row adds independent Gaussian noise of standard deviation S to every node's
Bookstein coordinate and reconstructs the curve (paper Fig. 4); one row per shape and
scale.
"""


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """Register ``match``, ``tree`` and ``deform``."""
    p = sub.add_parser(
        "match",
        help="match two shapes and print the deformation cost",
        description="Deform shape A onto shape B with the least shape-tree deformation "
        "(paper section 3) and print the cost, the shape-trees' costs and any replaced parts.",
        epilog=MATCH_EPILOG,
        formatter_class=Formatter,
    )
    p.add_argument("a", metavar="A", help="the model shape; " + SHAPE_HELP)
    p.add_argument("b", metavar="B", help="the target shape (same kinds as A)")
    p.add_argument(
        "--open",
        action="store_true",
        help="treat both curves as open (endpoints map to endpoints)",
    )
    p.add_argument("--plot", metavar="PNG", help="draw the correspondence into this picture")
    p.add_argument("--json", metavar="PATH", help="write the result (cost, correspondence) as JSON")
    add_config_options(p)
    p.set_defaults(func=cmd_match)

    p = sub.add_parser(
        "tree",
        help="draw a shape's shape-tree level by level",
        description="Build the shape-tree of a curve (paper section 2) and draw it level by "
        "level, as in paper Fig. 3.",
        epilog=TREE_EPILOG,
        formatter_class=Formatter,
    )
    p.add_argument("shape", metavar="SHAPE", help=SHAPE_HELP)
    _add_points(p, default=64)
    _add_split(p)
    p.add_argument("--open", action="store_true", help="treat the curve as open")
    p.add_argument(
        "--levels",
        type=positive_int,
        default=None,
        metavar="L",
        help="draw only the first L depths (default: all)",
    )
    p.add_argument(
        "-o",
        "--output",
        metavar="PNG",
        default=None,
        help="output picture (default: <shape>-tree.png in the current folder)",
    )
    p.set_defaults(func=cmd_tree)

    p = sub.add_parser(
        "deform",
        help="draw random deformations of a shape (paper Fig. 4)",
        description="Draw a gallery of random deformations of a shape: noise on the "
        "Bookstein coordinates of its shape-tree's nodes (paper section 2.1, Fig. 4).",
        epilog=DEFORM_EPILOG,
        formatter_class=Formatter,
    )
    p.add_argument(
        "shape", metavar="SHAPE", nargs="+", help=SHAPE_HELP + "; several give several rows"
    )
    _add_points(p, default=DEFAULT_POINTS)
    p.add_argument(
        "--scale",
        type=nonneg_float,
        nargs="+",
        default=[0.02, 0.04, 0.07],
        metavar="S",
        help="noise standard deviation(s) in Bookstein units; one gallery row per value",
    )
    p.add_argument(
        "--count", type=positive_int, default=5, metavar="K", help="deformations per row"
    )
    p.add_argument("--seed", type=int, default=0, help="random seed (same seed, same picture)")
    _add_split(p)
    p.add_argument("--open", action="store_true", help="treat the curve as open")
    p.add_argument(
        "-o",
        "--output",
        metavar="PNG",
        default=None,
        help="output picture (default: <shape>-deform.png in the current folder)",
    )
    p.set_defaults(func=cmd_deform)


def _add_points(p: argparse.ArgumentParser, default: int = DEFAULT_POINTS) -> None:
    p.add_argument(
        "--n-points",
        dest="points",
        type=points_int,
        default=default,
        metavar="N",
        help="resample every curve to N points, uniform in arc length (matching is O(N^4))",
    )


def _add_split(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--split",
        choices=("half", "best"),
        default="half",
        help="midpoint rule: halve each subcurve, or pick the best-approximating point",
    )


def _default_output(label: str, suffix: str) -> Path:
    stem = Path(label).stem.replace(":", "-") or "shape"
    return Path(f"{stem}-{suffix}.png")


def _fmt_range(i0: int, i1: int) -> str:
    return f"[{i0}..{i1}]"


def cmd_match(args: argparse.Namespace) -> int:
    """``shapetree match``."""
    from shapetree.matching import match
    from shapetree.plotting import plot_match
    from shapetree.plotting._save import check_figure_path

    if args.plot:
        check_figure_path(args.plot)
    config = config_from_args(args)
    closed = not args.open
    a = load_shape(args.a, n_points=None, closed=closed)
    b = load_shape(args.b, n_points=None, closed=closed)
    res = match(a.points, b.points, config, closed=closed)
    kind = "closed" if closed else "open"
    info(f"A: {args.a} ({res.a.shape[0]} points, {kind})")
    info(f"B: {args.b} ({res.b.shape[0]} points, {kind})")
    info(f"configuration: preset {preset_of(args)} ({config.describe()})")
    info(f"cost: {res.cost:.12g}")
    if res.height_cost is not None and config.symmetrize == "none":
        info(f"  psi(A, B) = {res.forward_cost:.12g}")
    if config.symmetrize != "none":
        back = "n/a" if res.backward_cost is None else f"{res.backward_cost:.12g}"
        info(f"  psi(A, B) = {res.forward_cost:.12g}, psi(B, A) = {back} ({config.symmetrize})")
    if res.height_cost is not None:
        w = config.height_weight
        info(
            f"  = psi^{1 - w:.3g} * h^{w:.3g}, psi the shape-tree cost and "
            f"h = {res.height_cost:.12g} the height-function distance"
        )
    if config.n_trees > 1:
        costs = ", ".join(f"{c:.6g}" for c in res.costs)
        rule = "the best" if config.tree_combine == "min" else "the mean of"
        info(
            f"shape-trees: cost is {rule} {config.n_trees} (costs: {costs}); "
            f"correspondence from the cheapest, #{res.tree_index}"
        )
    if res.mirrored:
        info("the mirrored A matched best")
    if res.replaced:
        info(f"replaced parts ({len(res.replaced)}):")
        for a0, a1, b0, b1 in res.replaced:
            info(f"  A{_fmt_range(a0, a1)} <-> B{_fmt_range(b0, b1)}")
    elif config.occlusion is not None:
        info("replaced parts: none")
    if args.plot:
        plot_match(
            res,
            path=args.plot,
            invert_y=(a.image_coords, b.image_coords),
            labels=(a.label, b.label),
        )
        info(f"picture: {args.plot}")
    if args.json:
        write_json(
            args.json,
            {
                "a": args.a,
                "b": args.b,
                "closed": closed,
                "preset": preset_of(args),
                "config": config.as_dict(),
                "cost": res.cost,
                "forward_cost": res.forward_cost,
                "backward_cost": res.backward_cost,
                "costs": res.costs,
                "tree_index": res.tree_index,
                "mirrored": res.mirrored,
                "phase": res.phase,
                "replaced": res.replaced,
                "a_points": res.a,
                "b_points": res.b,
                "a_to_b": res.a_to_b,
                "b_to_a": res.b_to_a,
            },
        )
        info(f"json: {args.json}")
    return 0


def cmd_tree(args: argparse.Namespace) -> int:
    """``shapetree tree``."""
    from shapetree.plotting import plot_tree
    from shapetree.plotting._save import check_figure_path
    from shapetree.tree import build_shape_tree

    shape = load_shape(args.shape, n_points=args.points, closed=not args.open)
    out = Path(args.output) if args.output else _default_output(shape.label, "tree")
    check_figure_path(out)
    tree = build_shape_tree(shape.points, closed=shape.closed, split=args.split)
    plot_tree(tree, path=out, max_levels=args.levels, invert_y=shape.image_coords)
    info(
        f"shape-tree of {args.shape}: {tree.n_points} points, {tree.n_nodes} nodes, "
        f"{tree.max_depth + 1} levels"
    )
    info(f"picture: {out}")
    return 0


def cmd_deform(args: argparse.Namespace) -> int:
    """``shapetree deform``."""
    from shapetree.plotting import plot_deformations
    from shapetree.plotting._save import check_figure_path
    from shapetree.tree import build_shape_tree

    shapes = [load_shape(s, n_points=args.points, closed=not args.open) for s in args.shape]
    out = Path(args.output) if args.output else _default_output(shapes[0].label, "deform")
    check_figure_path(out)
    trees = [build_shape_tree(s.points, closed=s.closed, split=args.split) for s in shapes]
    plot_deformations(
        trees,
        list(args.scale),
        args.count,
        args.seed,
        path=out,
        names=[s.label.removeprefix("glyph-") for s in shapes] if len(shapes) > 1 else None,
        invert_y=[s.image_coords for s in shapes],
    )
    info(
        f"{len(trees) * len(args.scale)} x {args.count} deformations of "
        f"{', '.join(args.shape)} (scales {', '.join(f'{s:g}' for s in args.scale)}, "
        f"seed {args.seed})"
    )
    info(f"picture: {out}")
    return 0
