"""``shapetree detect``: find a model shape in images (paper §4)."""

from __future__ import annotations

import argparse

from shapetree._errors import ShapeTreeError
from shapetree.cli._common import Formatter, info, positive_int, require
from shapetree.cli._evaluate import key_value

DETECT_EPILOG = """\
examples:
  shapetree detect models/Swans.tif swans/big.jpg -o swan.png --json swan.json
  shapetree detect mug.png kitchen.jpg --edges kitchen_edges.tif -k 3
  shapetree detect bottle.png shelf.jpg --param tau=16 --param gap_cost=0.4

MODEL is an outline drawing or silhouette image, or a point file; IMAGE is searched for it
(paper section 4: edge map, contours, contour-vs-model tables, stitching). With --edges a
stored soft edge map is used instead of the built-in gradient edges.
"""


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """Register ``detect``."""
    p = sub.add_parser(
        "detect",
        help="find a model shape in a cluttered image (paper section 4)",
        description="Detect a model shape in an image: edge map, contours, matching every "
        "contour to every model subcurve, and stitching (paper section 4, Fig. 5); print "
        "the best detections and draw them.",
        epilog=DETECT_EPILOG,
        formatter_class=Formatter,
    )
    p.add_argument("model", metavar="MODEL", help="model outline: image or point file")
    p.add_argument("image", metavar="IMAGE", help="image to search")
    p.add_argument("--edges", metavar="MAP", help="stored soft edge map (grey image)")
    p.add_argument("-o", "--output", metavar="PNG", help="picture of the detections (Fig. 5)")
    p.add_argument("--json", metavar="PATH", help="write the detections as JSON")
    p.add_argument("-k", type=positive_int, default=5, metavar="K", help="number of detections")
    p.add_argument(
        "-p",
        "--param",
        type=key_value,
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="set a detection parameter (a DetectParams field), repeatable",
    )
    p.set_defaults(func=cmd_detect)


def cmd_detect(args: argparse.Namespace) -> int:
    """``shapetree detect``."""
    detect_to_files = require("shapetree.detection", "detect_to_files", "detection")
    if args.output:
        from shapetree.plotting._save import check_figure_path

        check_figure_path(args.output)
    try:
        dets = detect_to_files(
            args.model,
            args.image,
            edges_path=args.edges,
            out_png=args.output,
            out_json=args.json,
            k=args.k,
            **dict(args.param),
        )
    except TypeError as exc:
        raise ShapeTreeError(f"bad detection parameter: {exc}") from None
    info(f"{len(dets)} detection(s) of {args.model} in {args.image}")
    if dets:
        info(f"{'rank':>4}  {'score':>9}  {'cost':>9}  {'coverage':>8}  box (x1, y1, x2, y2)")
        for i, d in enumerate(dets, start=1):
            box = ", ".join(f"{v:.0f}" for v in d.bbox)
            info(f"{i:>4}  {d.score:>9.4f}  {d.cost:>9.4f}  {d.coverage:>8.2f}  ({box})")
        info(
            "ranked by score = -cost - outline_check * outline_dif"
            " + frame_prior * log(sqrt(box share of the image))"
        )
    if args.output:
        info(f"picture: {args.output}")
    if args.json:
        info(f"json: {args.json}")
    return 0
