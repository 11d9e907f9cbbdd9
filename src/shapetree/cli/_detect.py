"""``shapetree detect``: find a model shape in users' photos (paper §4)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from shapetree._errors import ShapeTreeError
from shapetree.cli._common import Formatter, info, positive_int, require
from shapetree.cli._evaluate import key_value

DETECT_EPILOG = """\
examples:
  shapetree detect swan.svg photos/                     # every image of a folder
  shapetree detect mug.png kitchen1.jpg kitchen2.jpg -o found/
  shapetree detect bottle.csv shelf/ --jsonl bottles.jsonl   # JSON lines (resumable)
  shapetree detect bottle.csv shelf/ --jsonl - > out.jsonl   # JSON lines on stdout
  shapetree detect models/Swans.tif big.jpg -o swan.png --json swan.json   # one picture
  shapetree detect mug.png kitchen.jpg --edges kitchen_edges.tif -k 3
  shapetree detect bottle.png shelf.jpg --param tau=16 --param gap_cost=0.4
  shapetree detect swan.svg photos/ --edges pidinet --edge-weights table5_pidinet.npz

MODEL is a silhouette or outline drawing (image), an SVG file (its first <path>, or a
<polygon>/<polyline>: the usual way to draw a model) or a point file (.csv/.txt/.npy/
.json). IMAGES are files and folders (a folder's images in natural order; --recursive for
sub-folders). For each image the four stages of section 4 run (edge map, contours,
contour-vs-model tables, stitching) and DIR receives NAME.json (the detections: score,
cost, box, coverage, where each model point lands) and NAME.png (image, edges, contours,
detections: Fig. 5). A box is the whole object's where the upright model, fitted to the
edges around the match and widened up to twice its box, fits better than inside it (the
record's match_bbox then keeps the match's box; --param box_refine=None turns this off).
The stitching prefers pieces that stand as the model is drawn (each contour turned from
the model pays upright_cost * its model share * (1 - cos turn)); for objects at any
angle use --param upright_cost=0, the paper's rotation-invariant matching.
A run is resumable: an image whose record is there with the same model, parameters, edge
source and image file is skipped (--force recomputes). A bad image
(unreadable, empty, too large) is reported on stderr, gets an error record, and the batch
goes on; the exit status is then 1.

With two or more images the collection stage ranks all their detections together, by
the re-scorer's collection score: the score plus fixed weights of the shape-context
agreement, outline check, frame term, coverage, the detection's margin and lead within its
image, the colour agreement of the inside of its outline with the most confident
detections of the other images, and the upright template check of its box (weights
fitted on ETHZ with Pb maps; see the README). Overlapping matches in one image are
suppressed in score order (--param score_pool=0: cheapest first, the paper's order). It
is written to DIR/ranking.json (or JSONL_STEM.ranking.json); each image's own record and
scores do not change. It uses the other photos, never labels. --param
collection_rescore=False turns it off (or, with --param appearance_check=W, ranks by score
+ W * colour agreement alone).

--edges: own (default) is the project's boundary detector on Pb's cues (brightness, colour
and texture half-disc differences); gradient the plain colour gradient; pidinet the learned
PiDiNet detector (Su et al., ICCV 2021), run with NumPy from the weights file given with
--edge-weights (a table5_*.npz copy of the authors' BSDS500 checkpoints, hellozhuo/pidinet:
research use only, not shipped with shapetree); a file is a stored soft edge map (one image
only). With one image and -o NAME.png (or --json FILE) the old single-picture form is
used.
"""

_PICTURE_EXT = (".png", ".pdf", ".svg", ".jpg", ".jpeg", ".tif", ".tiff", ".eps", ".ps", ".webp")


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """Register ``detect``."""
    p = sub.add_parser(
        "detect",
        help="find a model shape in photos (paper section 4): files and folders",
        description="Detect a model shape in images: edge map, contours, matching every "
        "contour to every model subcurve, and stitching (paper section 4, Fig. 5); one "
        "JSON record and one picture per image, with a progress bar; resumable.",
        epilog=DETECT_EPILOG,
        formatter_class=Formatter,
    )
    p.add_argument(
        "model", metavar="MODEL", help="model: silhouette/outline image, SVG or point file"
    )
    p.add_argument("images", metavar="IMAGES", nargs="+", help="image files and folders")
    p.add_argument(
        "-o",
        "--output",
        metavar="DIR",
        default=None,
        help="folder for NAME.json and NAME.png per image (default ./shapetree-detect); "
        "with one image, a picture file name (.png, .pdf, .svg) writes just that picture",
    )
    p.add_argument(
        "--jsonl",
        metavar="FILE",
        default=None,
        help="write the records as JSON lines to FILE ('-': stdout) instead of NAME.json "
        "files; pictures only with -o DIR",
    )
    p.add_argument("--json", metavar="PATH", help="one image: write its detections as JSON")
    p.add_argument(
        "--edges",
        metavar="SOURCE",
        default="own",
        help="own (Pb-style cues), gradient, pidinet (learned; needs --edge-weights), or a "
        "stored soft edge map file (one image)",
    )
    p.add_argument(
        "--edge-weights",
        metavar="PATH",
        default=None,
        help="--edges pidinet: the PiDiNet weights (.npz; research use only, not shipped)",
    )
    p.add_argument("-k", type=positive_int, default=5, metavar="K", help="detections per image")
    p.add_argument(
        "-p",
        "--param",
        type=key_value,
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="set a detection parameter (a DetectParams field), repeatable",
    )
    p.add_argument("--no-pictures", action="store_true", help="write the records only")
    p.add_argument("--force", action="store_true", help="recompute existing records")
    p.add_argument("-r", "--recursive", action="store_true", help="look into sub-folders")
    p.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    p.set_defaults(func=cmd_detect)


def _single_picture_form(args: argparse.Namespace) -> bool:
    if len(args.images) != 1 or args.jsonl is not None:
        return False
    if args.json:
        return True
    out = args.output
    return out is not None and Path(out).suffix.lower() in _PICTURE_EXT and not Path(out).is_dir()


def _method_or_file(edges: str) -> tuple[str | None, str | None]:
    from shapetree.detection._edges import EDGE_METHODS

    return (edges, None) if edges in EDGE_METHODS else (None, edges)


def _print_table(dets: list[Any], say) -> None:
    say(f"{'rank':>4}  {'score':>9}  {'cost':>9}  {'coverage':>8}  box (x1, y1, x2, y2)")
    for i, d in enumerate(dets, start=1):
        box = ", ".join(f"{v:.0f}" for v in d.bbox)
        say(f"{i:>4}  {d.score:>9.4f}  {d.cost:>9.4f}  {d.coverage:>8.2f}  ({box})")


def _cmd_single(args: argparse.Namespace, params: dict[str, Any]) -> int:
    """One image, one picture file and/or one JSON file (``detect_to_files``)."""
    detect_to_files = require("shapetree.detection", "detect_to_files", "detection")
    if args.output:
        from shapetree.plotting._save import check_figure_path

        check_figure_path(args.output)
    method, edge_file = _method_or_file(args.edges)
    if method is not None:
        params = {**params, "edge_method": method}
    try:
        dets = detect_to_files(
            args.model,
            args.images[0],
            edges_path=edge_file,
            out_png=args.output,
            out_json=args.json,
            k=args.k,
            **params,
        )
    except TypeError as exc:
        raise ShapeTreeError(f"bad detection parameter: {exc}") from None
    info(f"{len(dets)} detection(s) of {args.model} in {args.images[0]}")
    if dets:
        _print_table(dets, info)
        info(
            "ranked by score = -cost - outline_check * outline_dif"
            " + frame_prior * log(sqrt(box share of the image))"
            " + context_check * context_agreement"
        )
    if args.output:
        info(f"picture: {args.output}")
    if args.json:
        info(f"json: {args.json}")
    return 0


def cmd_detect(args: argparse.Namespace) -> int:
    """``shapetree detect``."""
    params = dict(args.param)
    if args.edge_weights is not None:
        params["edge_weights"] = args.edge_weights
        method, _ = _method_or_file(args.edges)
        if method is not None:
            params["edge_method"] = method
    if _single_picture_form(args):
        return _cmd_single(args, params)
    from shapetree.detection import DetectParams
    from shapetree.detection._photos import collect_images, detect_images

    try:
        p = DetectParams(**params)
    except TypeError as exc:
        raise ShapeTreeError(f"bad detection parameter: {exc}") from None
    to_stdout = args.jsonl == "-"
    say = (lambda m: print(m, file=sys.stderr, flush=True)) if to_stdout else info
    images = collect_images(args.images, recursive=args.recursive)
    out_dir: str | None = args.output
    if args.jsonl is None and out_dir is None:
        out_dir = "shapetree-detect"
    if out_dir is not None and Path(out_dir).suffix.lower() in _PICTURE_EXT:
        raise ShapeTreeError(
            f"-o {out_dir}: a picture name needs exactly one image; with {len(images)} "
            "give a folder"
        )
    summary = detect_images(
        args.model,
        images,
        out_dir=out_dir,
        jsonl=sys.stdout if to_stdout else args.jsonl,
        pictures=not args.no_pictures,
        edges=args.edges,
        k=args.k,
        params=p,
        force=args.force,
        progress=not args.no_progress,
    )
    if not to_stdout:
        for rec in summary.records:
            dets = rec.get("detections") or []
            if rec.get("status") != "ok":
                say(f"  {rec['image']}: error: {rec.get('error')}")
            elif dets:
                b = ", ".join(f"{v:.0f}" for v in dets[0]["bbox"])
                say(
                    f"  {rec['image']}: {len(dets)} detection(s), best score "
                    f"{dets[0]['score']:.4f} at ({b})"
                )
            else:
                say(f"  {rec['image']}: no detection")
    found = sum(1 for r in summary.records if r.get("status") == "ok" and r.get("detections"))
    say(
        f"{len(images)} image(s): {summary.done} searched now, {summary.skipped} already "
        f"done, {summary.failed} failed; {found} with a detection ({summary.seconds:.1f} s)"
    )
    if summary.ranking:
        n = len({d["image"] for d in summary.ranking})
        how = "re-scorer" if p.collection_rescore else "score + W * colour agreement"
        say(
            f"collection ranking of {len(summary.ranking)} detection(s) in {n} images "
            f"(collection score: {how}):"
        )
        for d in summary.ranking[:5]:
            say(
                f"  {d['collection_score']:9.4f}  {d['image']} #{d['rank']} "
                f"(score {d['score']:.4f}, colour agreement {d['appearance']:.3f})"
            )
        if summary.ranking_path is not None:
            say(f"ranking: {summary.ranking_path}")
    if out_dir is not None:
        say(f"output: {out_dir}")
    if args.jsonl is not None and not to_stdout:
        say(f"json lines: {args.jsonl}")
    return 1 if summary.failed else 0
