"""``shapetree demo``: the built-in demonstration on embedded shapes."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from shapetree.cli._common import Formatter, info, nonneg_float, positive_int
from shapetree.cli._options import add_config_options, config_from_args, preset_of

DEMO_EPILOG = """\
examples:
  shapetree demo
  shapetree demo -o pictures --query A
  shapetree demo --list

What it does: the query (default: the outline of the letter G, from the DejaVu Sans font
that ships with matplotlib) is matched against randomly deformed, rotated, rescaled and
re-started copies of itself, a deformed copy of another letter and every other demo
shape (letters and shapes drawn in code: star, square, leaf, hand, ...). The table lists
them by cost; the deformed copies of the query should come first. Nothing is downloaded.

Pictures written to DIR:
  demo_match.png     the query matched to its best deformed copy, with correspondences
  demo_ranking.png   all candidates in ranked order with their costs
  demo_occlusion.png a hand matched to a hand with a finger missing (replaced parts)
  demo_tree.png      the query's shape-tree, level by level (paper Fig. 3)
  demo_deform.png    random deformations of the query (paper Fig. 4)
  demo_detection.png the detection step (paper section 4, Fig. 5): a deformed star drawn
                     broken into pieces with gaps among distractor curves on a textured
                     background, found by edge map, contours, tables and stitching; the
                     summary says whether the best detection found it (IoU >= 0.5 with
                     the known box)
"""


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """Register ``demo``."""
    p = sub.add_parser(
        "demo",
        help="run the built-in demo (matching, ranking, pictures) on embedded shapes",
        description="Run the built-in demonstration on shapes made by shapetree itself: rank "
        "shapes by their matching cost to a query and draw the match, the ranking, an "
        "occluded match, the shape-tree and random deformations.",
        epilog=DEMO_EPILOG,
        formatter_class=Formatter,
    )
    p.add_argument(
        "-o",
        "--output",
        metavar="DIR",
        default="shapetree-demo",
        help="folder for the pictures (created if needed)",
    )
    p.add_argument(
        "--query",
        default="G",
        metavar="NAME",
        help="query shape: a single character (its glyph) or a demo shape name",
    )
    add_config_options(p)
    p.add_argument(
        "--scale",
        type=nonneg_float,
        default=0.04,
        metavar="S",
        help="deformation noise of the query's copies (Bookstein units)",
    )
    p.add_argument(
        "--copies",
        type=positive_int,
        default=2,
        metavar="K",
        help="deformed copies of the query among the candidates",
    )
    p.add_argument("--seed", type=int, default=0, help="random seed")
    p.add_argument(
        "--detect-shape",
        default="star",
        metavar="NAME",
        help="demo shape hidden in the cluttered scene of the detection step",
    )
    p.add_argument("--no-detect", action="store_true", help="skip the detection step")
    p.add_argument("--list", action="store_true", help="list the demo shapes and exit")
    p.add_argument("--no-progress", action="store_true", help="hide progress bars")
    p.set_defaults(func=cmd_demo)


def cmd_demo(args: argparse.Namespace) -> int:
    """``shapetree demo``."""
    from shapetree.demo import demo_ranking, demo_shape, demo_shape_names

    if args.list:
        info("demo shapes (use as demo:NAME in match/tree/deform; demo:X is the glyph X):")
        for name in demo_shape_names():
            info(f"  {name}")
        return 0
    from shapetree.matching import match
    from shapetree.plotting import plot_deformations, plot_match, plot_ranking, plot_tree
    from shapetree.tree import build_shape_tree

    out = Path(args.output)
    if out.exists() and not out.is_dir():
        from shapetree._errors import ShapeTreeError

        raise ShapeTreeError(f"{out}: exists and is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    config = config_from_args(args)
    rank = demo_ranking(
        args.query,
        config,
        scale=args.scale,
        copies=args.copies,
        seed=args.seed,
        progress=not args.no_progress,
    )
    qshort = rank.query_name.removeprefix("glyph-")
    info(
        f"query: {qshort} ({rank.query_name}); {len(rank.candidates)} candidates; "
        f"matcher: preset {preset_of(args)} ({config.describe()})"
    )
    info("")
    info(f"{'rank':>4}  {'cost':>9}  {'shape':<9} description")
    for i, c in enumerate(rank.candidates, start=1):
        mark = "  <- deformed copy of the query" if c.same_as_query else ""
        info(f"{i:>4}  {c.cost:>9.5f}  {c.name:<9} {c.description}{mark}")
    n_same = sum(c.same_as_query for c in rank.candidates)
    top = all(c.same_as_query for c in rank.candidates[:n_same])
    info("")
    info(
        f"the {n_same} deformed cop{'ies' if n_same > 1 else 'y'} of {qshort} "
        + ("rank first." if top else "do NOT all rank first.")
    )

    pictures: list[tuple[str, Path]] = []
    best = next(c for c in rank.candidates if c.same_as_query)
    res = match(rank.query, best.points, config)
    p = plot_match(
        res,
        path=out / "demo_match.png",
        labels=(qshort, best.name),
        title=f"{qshort} deformed onto {best.name}:  ψ = {res.cost:.4g}",
    )
    pictures.append(("match with correspondences", out / "demo_match.png"))
    del p
    plot_ranking(
        rank.query,
        [(c.name, c.points, c.cost, c.same_as_query) for c in rank.candidates],
        path=out / "demo_ranking.png",
        query_label=f"query {qshort}",
    )
    pictures.append(("ranking", out / "demo_ranking.png"))
    hand, cut = (
        demo_shape("hand", n_points=120),
        demo_shape("hand-cut", n_points=120),
    )
    occ = match(hand, cut, config, occlusion=1.0)
    plot_match(
        occ,
        path=out / "demo_occlusion.png",
        labels=("hand", "hand-cut"),
        title=f"occlusion (κ = 1): a missing finger is replaced, ψ = {occ.cost:.4g}",
    )
    pictures.append(("match with a replaced part", out / "demo_occlusion.png"))
    tree = build_shape_tree(demo_shape(rank.query_name, n_points=64), closed=True)
    plot_tree(tree, path=out / "demo_tree.png")
    pictures.append(("shape-tree", out / "demo_tree.png"))
    plot_deformations(
        build_shape_tree(rank.query, closed=True),
        [args.scale / 2, args.scale, 2 * args.scale],
        5,
        args.seed,
        path=out / "demo_deform.png",
    )
    pictures.append(("deformations", out / "demo_deform.png"))
    if not args.no_detect:
        _detection_step(args, out, pictures)
    info("")
    info("pictures:")
    for what, path in pictures:
        info(f"  {path}  ({what})")
    info(f"done in {time.perf_counter() - t0:.1f} s")
    return 0


def _detection_step(args: argparse.Namespace, out: Path, pictures: list[tuple[str, Path]]) -> bool:
    """Find a broken, deformed demo shape in a cluttered scene drawn by the project."""
    from shapetree.demo._scene import box_iou, detection_scene
    from shapetree.detection import detect_detailed, make_model
    from shapetree.plotting import plot_detections

    scene = detection_scene(args.detect_shape, seed=args.seed)
    run = detect_detailed(make_model(scene.model, closed=True, name=scene.name), scene.image, k=3)
    best = run.detections[0] if run.detections else None
    iou = box_iou(best.bbox, scene.box) if best is not None else 0.0
    found = iou >= 0.5
    plot_detections(
        run,
        scene.image,
        title=f"detection: a deformed {scene.name} with gaps among distractors "
        f"(IoU {iou:.2f} with the true box)",
        path=out / "demo_detection.png",
    )
    pictures.append(("detection in a cluttered scene (Fig. 5)", out / "demo_detection.png"))
    info("")
    info(
        f"detection: a deformed {scene.name} drawn with gaps among distractor curves and "
        f"texture, {len(run.contours)} contours traced; best detection IoU {iou:.2f} with "
        f"the true box: " + ("found (IoU >= 0.5)." if found else "NOT found (IoU < 0.5).")
    )
    return found
