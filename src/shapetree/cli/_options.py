"""The matching flags of ``match``, ``search``, ``distances`` and ``evaluate``.

Generated from one table, :data:`shapetree.matching.OPTIONS`, so every command that matches
has the same flags with the same names and defaults: ``--preset NAME`` picks a starting
configuration (default ``general``) and each ``--OPTION`` changes one field of it.
"""

from __future__ import annotations

import argparse
import math
from typing import Any

from shapetree.matching import OPTIONS, PRESETS, MatchConfig

_OFF = ("none", "off", "0")


def _parser(name: str, spec: dict[str, Any]):
    typ = spec["type"]
    optional = bool(spec.get("optional"))

    def parse(text: str) -> Any:
        if optional and text.strip().lower() in _OFF:
            return None
        try:
            v = typ(text)
        except ValueError:
            kind = "a whole number" if typ is int else "a number"
            raise argparse.ArgumentTypeError(f"expected {kind}, got {text!r}") from None
        if isinstance(v, float) and not math.isfinite(v):
            raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
        return v

    parse.__name__ = name  # argparse names the type in its error messages
    return parse


def flag(name: str) -> str:
    """The command-line flag of a :class:`MatchConfig` field (``n_points`` -> ``--n-points``)."""
    return "--" + name.replace("_", "-")


def add_config_options(parser: argparse.ArgumentParser) -> None:
    """Add ``--preset`` and one flag per matching option (defaults come from the preset)."""
    g = parser.add_argument_group(
        "matching (the same flags on match, search, distances and evaluate)",
        "Start from --preset (default: general) and change single options; each help line "
        "gives the general preset's value. See the README, 'Presets'.",
    )
    g.add_argument(
        "--preset",
        choices=list(PRESETS),
        default=argparse.SUPPRESS,
        help="starting configuration: general (the default of every entry point, chosen "
        "leave-one-dataset-out), paper (the method as published), fused (64 points, 3 "
        "trees, fused with the height-function distance: the most accurate held out, "
        "about 1.06x general's time per pair), or the configuration tuned on one "
        "benchmark (kimia99, mpeg7, swedish_leaf)",
    )
    general = PRESETS["general"]
    for name, spec in OPTIONS.items():
        default = getattr(general, name)
        shown = "none" if default is None else default
        text = f"{spec['help']} (general: {shown})"
        if spec["type"] is bool:
            g.add_argument(
                flag(name),
                dest=name,
                action=argparse.BooleanOptionalAction,
                default=argparse.SUPPRESS,
                help=text,
            )
            continue
        choices = spec.get("choices")
        g.add_argument(
            flag(name),
            dest=name,
            type=str if choices else _parser(name, spec),
            choices=choices,
            default=argparse.SUPPRESS,
            metavar=None if choices else spec.get("metavar", "V"),
            help=text,
        )


def config_from_args(args: argparse.Namespace) -> MatchConfig:
    """The :class:`MatchConfig` that the parsed flags describe (validated)."""
    changes = {name: getattr(args, name) for name in OPTIONS if hasattr(args, name)}
    return MatchConfig.preset(getattr(args, "preset", "general"), **changes)


def preset_of(args: argparse.Namespace) -> str:
    """Name of the preset the flags started from."""
    return getattr(args, "preset", "general")


__all__ = ["add_config_options", "config_from_args", "flag", "preset_of"]
