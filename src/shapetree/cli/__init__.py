"""The ``shapetree`` command line.

Commands: ``match``, ``tree``, ``deform``, ``search``, ``distances``, ``index``, ``demo``,
``datasets``, ``evaluate``, ``detect``
(``shapetree COMMAND --help`` for each). Errors in the input (:class:`ShapeTreeError`,
:class:`OSError`) are reported as one line ``shapetree: error: <message>`` on stderr with
exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from shapetree import __version__
from shapetree._errors import ShapeTreeError

__all__ = ["build_parser", "main"]

EPILOG = """\
examples:
  shapetree demo                                  # built-in demo, pictures in shapetree-demo/
  shapetree match demo:G demo:S --plot match.png  # match two shapes, draw the correspondence
  shapetree match a.png b.png --occlusion 0.5     # allow replaced (occluded) parts
  shapetree tree demo:hand -o tree.png            # the shape-tree, level by level (Fig. 3)
  shapetree deform demo:hand -o deform.png        # random deformations (Fig. 4)
  shapetree search query.png shapes/ -k 5         # nearest shapes in a folder
  shapetree distances shapes/ -o D.npz            # all-pairs matrix, resumable
  shapetree index build shapes/ -o shapes.stidx   # a prepared database (search/distances read it)
  shapetree datasets fetch mpeg7                  # download a benchmark
  shapetree evaluate mpeg7 --json mpeg7.json      # bull's-eye score
  shapetree detect model.png image.jpg -o det.png # find a shape in clutter (section 4)

Shapes are images (silhouettes), point files (.csv/.txt/.npy/.json) or demo:NAME.
"""


def _wants_evaluate(argv: Sequence[str]) -> bool:
    for tok in argv:
        if not tok.startswith("-"):
            return tok == "evaluate"
    return False


def build_parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """Build the argument parser.

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments about to be parsed; when the command is ``evaluate``, that
        command's options include one per retrieval parameter (``EVAL_PARAMS``).

    Returns
    -------
    argparse.ArgumentParser
    """
    from shapetree.cli import _datasets, _demo, _detect, _evaluate, _index, _search, _shapes
    from shapetree.cli._common import Formatter

    parser = argparse.ArgumentParser(
        prog="shapetree",
        description="Hierarchical matching of deformable shapes (Felzenszwalb & Schwartz, "
        "CVPR 2007): shape-trees, elastic matching, retrieval and detection.",
        epilog=EPILOG,
        formatter_class=Formatter,
    )
    parser.add_argument("--version", action="version", version=f"shapetree {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    _shapes.add_parsers(sub)
    _demo.add_parsers(sub)
    _search.add_parsers(sub)
    _index.add_parsers(sub)
    _datasets.add_parsers(sub)
    _evaluate.add_parsers(sub, full=argv is not None and _wants_evaluate(argv))
    _detect.add_parsers(sub)
    return parser


def _error(message: object) -> int:
    text = " ".join(str(message).split()) or "unknown error"
    print(f"shapetree: error: {text}", file=sys.stderr, flush=True)
    return 2


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``shapetree`` command.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments without the program name (default ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit status: 0 on success, 2 on bad input (message on stderr), 130 when
        interrupted.
    """
    import warnings

    # shapetree's own pixel limit refuses such images with one line; Pillow's warning is noise
    warnings.filterwarnings("ignore", message=r"Image size \(\d+ pixels\) exceeds limit")
    args_list = list(sys.argv[1:] if argv is None else argv)
    try:
        parser = build_parser(args_list)
        args = parser.parse_args(args_list)
        args.argv = args_list
        return int(args.func(args) or 0)
    except SystemExit as exc:  # argparse: --help, --version, usage errors
        code = exc.code
        return code if isinstance(code, int) else (0 if code is None else _error(code))
    except (ShapeTreeError, OSError) as exc:
        if isinstance(exc, OSError) and exc.filename and str(exc.filename) not in str(exc):
            return _error(f"{exc.filename}: {exc}")
        return _error(exc)
    except KeyboardInterrupt:
        print("shapetree: interrupted", file=sys.stderr, flush=True)
        return 130
