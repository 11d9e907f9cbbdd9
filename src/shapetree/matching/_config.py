"""The matcher configuration: one validated, immutable object for every entry point.

:class:`MatchConfig` holds every option that changes the cost of a pair of shapes, with one
set of documented defaults (the ``general`` preset). :func:`shapetree.matching.match`,
:func:`shapetree.retrieval.distance_matrix`, :func:`shapetree.retrieval.directed_costs`,
:func:`shapetree.retrieval.evaluate` and the ``shapetree match / search / distances /
evaluate`` commands all take it, so the same pair costs the same wherever it is asked.
:data:`OPTIONS` describes each field once (type, help, choices); the command-line flags are
generated from it. :data:`PRESETS` names the configurations the project ships.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from shapetree._errors import ShapeTreeError

#: Table precisions of the kernel (``MatchConfig.precision``).
PRECISIONS = {"float32": np.float32, "float64": np.float64}

#: Accepted ``symmetrize`` values.
SYMMETRIZE = ("none", "min", "mean", "max", "reverse")

#: Midpoint rules of the shape-trees.
SPLIT_RULES = ("half", "best")

#: Accepted ``dif`` values (the triangle dissimilarity of eq. (1)).
DIFS = ("procrustes", "hyperbolic")

#: Accepted ``matcher`` values.
MATCHERS = ("directed", "symmetric")

#: Accepted ``tree_combine`` values (how the costs of a model's shape-trees combine).
TREE_COMBINE = ("min", "mean")


def _is_int(v: Any) -> bool:
    return isinstance(v, int | np.integer) and not isinstance(v, bool)


def _is_num(v: Any) -> bool:
    return isinstance(v, int | float | np.integer | np.floating) and not isinstance(v, bool)


@dataclass(frozen=True)
class MatchConfig:
    """Every option that changes the cost ψ of a pair of shapes.

    Build one directly, from a preset (``MatchConfig.preset("paper")``), or from another
    with :meth:`replace`. It is validated once, on construction; a bad value raises
    :class:`shapetree.ShapeTreeError` naming the option.

    Attributes
    ----------
    n_points : int or None
        Both curves are resampled to this many points, evenly in arc length, before
        matching (``None``: use the points as given). Time grows as about ``n^4``.
    weight : float
        λ factor of the model's nodes: λ of a node is ``weight * (|A'| / |A|) **
        length_power`` (only matters relative to ``occlusion``).
    length_power : float
        λ grows as the relative length of the deformed subcurve to this power (the
        paper: 1, "a weighting proportional to the length of A").
    occlusion : float or None
        Replacement factor κ (§3, occlusion): every ψ(A', B') is bounded above by
        ``κ λ_{A'} (|A'| + |B'|)`` (lengths relative to the whole curves). ``None``: no
        replacement.
    n_trees : int
        Shape-trees of the model tried (different start points); the best is kept (§3:
        "we usually compute matchings using 2 to 4 different shape-trees"). An open curve
        has at most two (its ends are fixed: one tree per midpoint rule).
    tree_combine : {"min", "mean"}
        How the costs of the ``n_trees`` shape-trees combine into ψ: ``"min"``, the best
        tree (the paper: "pick the best one"), or ``"mean"``, their average (not in the
        paper: every tree is a different hierarchy of the same model, and the average
        lets no single tree's lucky decomposition decide). Matters only with
        ``n_trees > 1``; the correspondence :func:`~shapetree.matching.match` returns
        is the cheapest tree's either way. The shape-tree kernel only
        (``matcher="directed"``, no ``replace_any``).
    split : {"half", "best"}
        Midpoint rule of the shape-trees (§2).
    mirror : bool
        Mirror invariance: also deform the mirrored model and keep the cheaper cost.
    band : float or None
        Pruned matching (not in the paper): a model subcurve may stretch by at most this
        factor relative to the ratio of the two sample counts. ``None``: exact matching
        over all target subcurves (slower by 10–30×).
    phases : int
        Target phases (not in the paper; closed curves): the target is also resampled
        ``p / phases`` of a sample spacing further along (``p = 1 .. phases - 1``) and the
        cheapest matching is kept, so a shape costs almost nothing against a rotated or
        rescaled copy of itself. Needs ``n_points``.
    target_factor : int
        The target is resampled to ``target_factor * n_points`` points, the model to
        ``n_points`` (not in the paper, which samples both alike). Needs ``n_points``.
    segment_weight : float
        Factor on the base case "model segment vs a target subcurve of several segments"
        (the paper: 1). With ``target_factor`` 2 and ``segment_weight`` 0 the model's
        points land anywhere along the target and only the model's own triangles count.
    smooth : float or None
        Gaussian smoothing of each curve before resampling, as a fraction of its length
        (e.g. 0.005 removes pixel staircases). ``None``: none.
    symmetrize : {"none", "min", "mean", "max", "reverse"}
        How the two directed costs are combined into the distance of a pair:
        ``"none"`` is ψ(A, B) (A deformed onto B), ``"reverse"`` ψ(B, A), the others
        the min / mean / max of both (twice the work).
    precision : {"float32", "float64"}
        Precision of the dynamic-programming tables: float32 runs about twice as fast;
        costs then differ from float64 by about 1e-6 relative, far below the gaps that
        rank shapes.
    dif : {"procrustes", "hyperbolic"}
        The triangle dissimilarity of eq. (1): the squared full Procrustes distance (the
        paper), or the pseudo-hyperbolic distance ``tanh^2(d / 2)`` of the Bookstein
        coordinates in the Poincaré half-plane (the paper's footnote 2;
        :func:`shapetree.geometry.hyperbolic_dif`).
    matcher : {"directed", "symmetric"}
        ``"directed"``: ψ(A, B), A's shape-tree deformed onto B (the paper). ``"symmetric"``:
        a dynamic program over pairs of subcurves that splits either curve at its middle
        sample and the other anywhere, so ψ(A, B) = ψ(B, A) exactly (the paper's footnote
        1; :mod:`shapetree.matching._subcurves`). About O(n^2 m^2 (n + m)) time and O(n^2
        m^2) memory: a single-pair option of :func:`~shapetree.matching.match` (hundreds
        of times slower than directed); needs ``split="half"``, ``target_factor=1``,
        ``segment_weight=1`` and ``symmetrize="none"``.
    replace_any : bool
        Arbitrary replacement (end of §3): any part of A together with any part of B may
        be replaced at the occlusion cost, not only the subtrees of A's shape-tree. Exact,
        O(n^3 m^3) time, single-pair (:func:`~shapetree.matching.match` only; seconds at
        n = m = 50); needs ``occlusion`` and ``split="half"``.
    height_weight : float
        Fusion with the height-function distance ``h`` (not in the paper; Wang et al.,
        Pattern Recognition Letters 2012; :mod:`shapetree.matching._height`): the distance
        of a pair is ``ψ^(1 - w) h^w`` with ``w = height_weight`` in [0, 1], ψ the
        shape-tree cost combined as ``symmetrize`` says. 0: ψ alone (the paper); 1: ``h``
        alone. Closed curves only. ``h`` is symmetric and invariant to similarity,
        start point and mirroring. Time: ``h`` at 100 points adds 0.4-0.9 times the time
        of a 64-point, 3-tree ψ (``benchmarks/bench_match.py --height-only``).
    height_points : int
        Points of each outline (evenly in arc length) the height functions are computed
        on; matters only with ``height_weight > 0``. Time grows as about ``n^3``.
    height_complexity : bool
        Divide ``h(A, B)`` by the sum of the two outlines' shape complexities (Wang et al.'s
        normalisation: a difference between simple outlines counts for more;
        :func:`shapetree.matching._height.complexity`); matters only with
        ``height_weight > 0``. Costs nothing measurable.
    """

    n_points: int | None = 50
    weight: float = 1.0
    length_power: float = 1.5
    occlusion: float | None = None
    n_trees: int = 1
    tree_combine: str = "min"
    split: str = "half"
    mirror: bool = True
    band: float | None = 3.0
    phases: int = 4
    target_factor: int = 1
    segment_weight: float = 1.0
    smooth: float | None = None
    symmetrize: str = "none"
    precision: str = "float32"
    dif: str = "procrustes"
    matcher: str = "directed"
    replace_any: bool = False
    height_weight: float = 0.0
    height_points: int = 100
    height_complexity: bool = False

    def __post_init__(self) -> None:
        n = self.n_points
        if n is not None and not (_is_int(n) and n >= 4):
            raise ShapeTreeError(f"n_points must be an integer >= 4 or None, got {n!r}")
        if not (_is_num(self.weight) and np.isfinite(self.weight) and self.weight > 0):
            raise ShapeTreeError(f"weight must be a positive number, got {self.weight!r}")
        lp = self.length_power
        if not (_is_num(lp) and np.isfinite(lp) and lp >= 0):
            raise ShapeTreeError(f"length_power must be a number >= 0, got {lp!r}")
        occ = self.occlusion
        if occ is not None and not (_is_num(occ) and np.isfinite(occ) and occ > 0):
            raise ShapeTreeError(f"occlusion must be a positive number or None, got {occ!r}")
        if not (_is_int(self.n_trees) and self.n_trees >= 1):
            raise ShapeTreeError(f"n_trees must be an integer >= 1, got {self.n_trees!r}")
        if self.tree_combine not in TREE_COMBINE:
            raise ShapeTreeError(
                f"tree_combine must be one of {TREE_COMBINE}, got {self.tree_combine!r}"
            )
        if self.split not in SPLIT_RULES:
            raise ShapeTreeError(f"split must be one of {SPLIT_RULES}, got {self.split!r}")
        if not isinstance(self.mirror, bool | np.bool_):
            raise ShapeTreeError(f"mirror must be True or False, got {self.mirror!r}")
        b = self.band
        if b is not None and not (_is_num(b) and np.isfinite(b) and b >= 1):
            raise ShapeTreeError(f"band must be a number >= 1 or None, got {b!r}")
        if not (_is_int(self.phases) and self.phases >= 1):
            raise ShapeTreeError(f"phases must be an integer >= 1, got {self.phases!r}")
        tf = self.target_factor
        if not (_is_int(tf) and tf >= 1):
            raise ShapeTreeError(f"target_factor must be an integer >= 1, got {tf!r}")
        if n is None and (self.phases > 1 or tf > 1):
            raise ShapeTreeError(
                "phases > 1 and target_factor > 1 resample the target: they need n_points"
            )
        sw = self.segment_weight
        if not (_is_num(sw) and np.isfinite(sw) and sw >= 0):
            raise ShapeTreeError(f"segment_weight must be a number >= 0, got {sw!r}")
        s = self.smooth
        if s is not None and not (_is_num(s) and np.isfinite(s) and 0 <= s < 0.5):
            raise ShapeTreeError(f"smooth must be a number in [0, 0.5) or None, got {s!r}")
        if self.symmetrize not in SYMMETRIZE:
            raise ShapeTreeError(f"symmetrize must be one of {SYMMETRIZE}, got {self.symmetrize!r}")
        if self.precision not in PRECISIONS:
            raise ShapeTreeError(
                f"precision must be one of {tuple(PRECISIONS)}, got {self.precision!r}"
            )
        if self.dif not in DIFS:
            raise ShapeTreeError(f"dif must be one of {DIFS}, got {self.dif!r}")
        if self.matcher not in MATCHERS:
            raise ShapeTreeError(f"matcher must be one of {MATCHERS}, got {self.matcher!r}")
        if not isinstance(self.replace_any, bool | np.bool_):
            raise ShapeTreeError(f"replace_any must be True or False, got {self.replace_any!r}")
        hw = self.height_weight
        if not (_is_num(hw) and np.isfinite(hw) and 0 <= hw <= 1):
            raise ShapeTreeError(f"height_weight must be a number in [0, 1], got {hw!r}")
        hn = self.height_points
        if not (_is_int(hn) and hn >= 8):
            raise ShapeTreeError(f"height_points must be an integer >= 8, got {hn!r}")
        if not isinstance(self.height_complexity, bool | np.bool_):
            raise ShapeTreeError(
                f"height_complexity must be True or False, got {self.height_complexity!r}"
            )
        if self.matcher == "symmetric":
            bad = [
                f"{k}={v!r}"
                for k, v, ok in (
                    ("split", self.split, "half"),
                    ("target_factor", tf, 1),
                    ("segment_weight", sw, 1),
                    ("symmetrize", self.symmetrize, "none"),
                )
                if v != ok
            ]
            if bad:
                raise ShapeTreeError(
                    "matcher='symmetric' needs split='half', target_factor=1, "
                    f"segment_weight=1 and symmetrize='none' (got {', '.join(bad)})"
                )
        if self.replace_any:
            if occ is None:
                raise ShapeTreeError(
                    "replace_any=True replaces parts at the occlusion cost: set occlusion"
                )
            if self.split != "half":
                raise ShapeTreeError(
                    f"replace_any=True needs split='half' (got split={self.split!r})"
                )
        if self.tree_combine != "min" and (self.matcher != "directed" or self.replace_any):
            raise ShapeTreeError(
                f"tree_combine={self.tree_combine!r} is an option of the shape-tree kernel; "
                "the pair matchers (matcher='symmetric', replace_any=True) keep the best tree"
            )
        # canonical types, so equal configurations hash and serialise alike
        fix = object.__setattr__
        fix(self, "n_points", None if n is None else int(n))
        fix(self, "weight", float(self.weight))
        fix(self, "length_power", float(lp))
        fix(self, "occlusion", None if occ is None else float(occ))
        fix(self, "n_trees", int(self.n_trees))
        fix(self, "mirror", bool(self.mirror))
        fix(self, "band", None if b is None else float(b))
        fix(self, "phases", int(self.phases))
        fix(self, "target_factor", int(tf))
        fix(self, "segment_weight", float(sw))
        fix(self, "smooth", None if not s else float(s))
        fix(self, "replace_any", bool(self.replace_any))
        fix(self, "height_weight", float(hw))
        fix(self, "height_points", int(hn))
        fix(self, "height_complexity", bool(self.height_complexity))

    # ------------------------------------------------------------ construction

    @classmethod
    def preset(cls, name: str, **changes: Any) -> MatchConfig:
        """The named preset (see :data:`PRESETS`), optionally with some options changed.

        Parameters
        ----------
        name : str
            One of :data:`PRESETS`.
        **changes
            Options to change (names of :class:`MatchConfig` fields).
        """
        if name not in PRESETS:
            raise ShapeTreeError(f"unknown preset {name!r}; choose one of {tuple(PRESETS)}")
        return PRESETS[name].replace(**changes)

    def replace(self, **changes: Any) -> MatchConfig:
        """A copy with some options changed (validated again)."""
        unknown = set(changes) - set(OPTIONS)
        if unknown:
            raise ShapeTreeError(
                f"unknown matching option(s) {sorted(unknown)}; the options are "
                f"{', '.join(OPTIONS)}"
            )
        return dataclasses.replace(self, **changes)

    def as_dict(self) -> dict[str, Any]:
        """Every option, JSON-ready."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> MatchConfig:
        """Inverse of :meth:`as_dict` (unknown keys are refused)."""
        return cls().replace(**data)

    # ------------------------------------------------------------ derived values

    @property
    def dtype(self) -> np.dtype:
        """NumPy dtype of the kernel's tables."""
        return np.dtype(PRECISIONS[self.precision])

    @property
    def target_points(self) -> int | None:
        """Points per target curve (``n_points * target_factor``)."""
        return None if self.n_points is None else self.n_points * self.target_factor

    @property
    def n_pass(self) -> int:
        """1, or 2 with ``mirror`` (plain model, mirrored model)."""
        return 2 if self.mirror else 1

    @property
    def matchings_per_pair(self) -> int:
        """Kernel runs per ordered pair (trees x mirror x phases x directions)."""
        both = 1 if self.symmetrize in ("none", "reverse") else 2
        return self.n_trees * self.n_pass * self.phases * both

    def describe(self) -> str:
        """One line naming every option that differs from the ``general`` preset."""
        base = PRESETS.get("general", MatchConfig())
        diff = [f"{k}={v}" for k, v in self.as_dict().items() if getattr(base, k) != v]
        return ", ".join(diff) if diff else "general preset"


def resolve_config(config: MatchConfig | str | None = None, **changes: Any) -> MatchConfig:
    """The configuration an entry point uses.

    Parameters
    ----------
    config : MatchConfig, str or None
        A configuration, a preset name, or ``None`` for the ``general`` preset.
    **changes
        Options to change on top of it (``None`` values are kept as ``None``, which means
        "off" for ``occlusion``, ``band``, ``smooth`` and "as given" for ``n_points``).

    Returns
    -------
    MatchConfig
    """
    if config is None:
        base = PRESETS["general"]
    elif isinstance(config, str):
        base = MatchConfig.preset(config)
    elif isinstance(config, MatchConfig):
        base = config
    else:
        raise ShapeTreeError(
            f"config must be a MatchConfig, a preset name or None, got {type(config).__name__}"
        )
    return base.replace(**changes) if changes else base


#: One entry per option: ``{name: {"type", "help", "choices"?, "optional"?}}``. ``optional``
#: options accept ``none`` (or ``0``) on the command line for "off". The CLI flags of
#: ``match``, ``search``, ``distances`` and ``evaluate`` are generated from this table.
OPTIONS: dict[str, dict[str, Any]] = {
    "n_points": {
        "metavar": "N",
        "type": int,
        "optional": True,
        "help": "resample both curves to N points, evenly in arc length (none: as given; "
        "time grows as N^4)",
    },
    "weight": {"metavar": "W", "type": float, "help": "lambda factor of the shape-tree nodes"},
    "length_power": {
        "metavar": "P",
        "type": float,
        "help": "lambda grows as (relative subcurve length)^P (the paper: 1)",
    },
    "occlusion": {
        "metavar": "K",
        "type": float,
        "optional": True,
        "help": "replacement cost factor kappa for missing or extra parts (none: off)",
    },
    "n_trees": {
        "metavar": "T",
        "type": int,
        "help": "shape-trees of the model tried (different start points); see --tree-combine",
    },
    "tree_combine": {
        "type": str,
        "choices": list(TREE_COMBINE),
        "help": "how the shape-trees' costs combine: min = the best tree (the paper), "
        "mean = their average (not in the paper)",
    },
    "split": {
        "type": str,
        "choices": list(SPLIT_RULES),
        "help": "midpoint rule: half (the middle sample) or best (the sample whose "
        "triangle best approximates the subcurve)",
    },
    "mirror": {"type": bool, "help": "also match the mirrored model and keep the cheaper cost"},
    "band": {
        "metavar": "B",
        "type": float,
        "optional": True,
        "help": "pruned matching: max stretch factor of a subcurve (none: exact, 10-30x slower)",
    },
    "phases": {
        "metavar": "P",
        "type": int,
        "help": "also match the target resampled 1/P, 2/P, ... of a sample spacing further "
        "along and keep the cheapest (1: the paper's single sampling)",
    },
    "target_factor": {
        "metavar": "F",
        "type": int,
        "help": "the target gets target_factor x n_points points (1: both alike)",
    },
    "segment_weight": {
        "metavar": "W",
        "type": float,
        "help": "weight of the base case 'model segment vs target subcurve' (the paper: 1; "
        "0 makes target detail finer than the model's sampling free)",
    },
    "smooth": {
        "metavar": "S",
        "type": float,
        "optional": True,
        "help": "Gaussian smoothing of each curve before resampling, as a fraction of its "
        "length (none: off)",
    },
    "symmetrize": {
        "type": str,
        "choices": list(SYMMETRIZE),
        "help": "distance of a pair: none = psi(A onto B), reverse = psi(B onto A), or the "
        "min / mean / max of both",
    },
    "precision": {
        "type": str,
        "choices": list(PRECISIONS),
        "help": "precision of the matching tables (float32: about 2x faster, within about "
        "1e-6 relative of float64)",
    },
    "dif": {
        "type": str,
        "choices": list(DIFS),
        "help": "triangle dissimilarity: procrustes (squared full Procrustes, the paper) or "
        "hyperbolic (pseudo-hyperbolic distance of Bookstein coordinates, footnote 2)",
    },
    "matcher": {
        "type": str,
        "choices": list(MATCHERS),
        "help": "directed (A's shape-tree onto B, the paper) or symmetric (both curves split "
        "at corresponding points, psi(A,B) = psi(B,A); single pairs only, slow)",
    },
    "replace_any": {
        "type": bool,
        "help": "let any part of A and of B be replaced at the occlusion cost, not only "
        "subtrees (exact, O(n^3 m^3): single pairs only, slow; needs --occlusion)",
    },
    "height_weight": {
        "metavar": "W",
        "type": float,
        "help": "fuse the height-function distance h (Wang et al. 2012, not in the paper): "
        "the distance is psi^(1-W) * h^W (0: psi alone, the paper; closed curves)",
    },
    "height_points": {
        "metavar": "N",
        "type": int,
        "help": "points the height functions are computed on (with --height-weight > 0)",
    },
    "height_complexity": {
        "type": bool,
        "help": "divide h by the two outlines' shape complexities (Wang et al.'s "
        "normalisation; with --height-weight > 0)",
    },
}

assert set(OPTIONS) == {f.name for f in dataclasses.fields(MatchConfig)}

#: The presets the project ships. ``general`` is the default of every entry point; see the
#: README ("Presets") for how each was chosen and what it scores.
PRESETS: dict[str, MatchConfig] = {
    # the method as the paper describes it: one sampling (50 points, the low end of the
    # paper's "between 50 and 100"), one shape-tree, no mirror, no band, no phases,
    # lambda proportional to length, psi(A, B) directed
    "paper": MatchConfig(
        n_points=50,
        length_power=1.0,
        occlusion=None,
        n_trees=1,
        tree_combine="min",
        mirror=False,
        band=None,
        phases=1,
        target_factor=1,
        segment_weight=1.0,
        symmetrize="none",
        dif="procrustes",
        matcher="directed",
        replace_any=False,
    ),
    # tuned on the set they are scored on (benchmarks/results/<set>.json); every field is
    # spelled out so a change of the general defaults never moves them. The 3-tree presets
    # average their trees (tree_combine="mean"): an option not tuned on their own sets,
    # adopted by a held-out test (benchmarks/eval_preset_tree_mean.py)
    "kimia99": MatchConfig(
        n_points=50,
        length_power=1.0,
        occlusion=None,
        n_trees=3,
        tree_combine="mean",
        mirror=True,
        band=4.0,
        phases=4,
        target_factor=1,
        segment_weight=1.0,
        symmetrize="none",
        dif="procrustes",
        matcher="directed",
        replace_any=False,
    ),
    "mpeg7": MatchConfig(
        n_points=64,
        length_power=1.0,
        occlusion=2.0,
        n_trees=3,
        tree_combine="mean",
        mirror=True,
        band=3.0,
        phases=2,
        target_factor=1,
        segment_weight=1.0,
        symmetrize="none",
        dif="procrustes",
        matcher="directed",
        replace_any=False,
    ),
    "swedish_leaf": MatchConfig(
        n_points=64,
        length_power=1.5,
        occlusion=None,
        n_trees=1,
        tree_combine="min",
        mirror=True,
        band=2.0,
        phases=1,
        target_factor=2,
        segment_weight=0.0,
        symmetrize="none",
        dif="procrustes",
        matcher="directed",
        replace_any=False,
    ),
}
# chosen leave-one-dataset-out (benchmarks/select_general.py, general_selection.json): on the
# selection subsets this is the best mean rank over all three sets, and the choice made
# without MPEG-7; without Kimia-99 the same with 2 phases won, without Swedish leaf the same
# with lambda ~ length (README, "Presets")
PRESETS["general"] = MatchConfig()
# the held-out base of the issue-15 grid (64 points, 3 averaged trees, lambda ~ length, band 3,
# one phase) fused with the height-function distance (64 points, complexity-normalised,
# w = 0.6): chosen by the best mean rank on all three selection subsets
# (benchmarks/select_fused.py, preset_fused.json); chosen on the other two sets, the fusion
# wins on each full set (README, "Presets")
PRESETS["fused"] = MatchConfig(
    n_points=64,
    length_power=1.0,
    occlusion=None,
    n_trees=3,
    tree_combine="mean",
    mirror=True,
    band=3.0,
    phases=1,
    target_factor=1,
    segment_weight=1.0,
    symmetrize="none",
    dif="procrustes",
    matcher="directed",
    replace_any=False,
    height_weight=0.6,
    height_points=64,
    height_complexity=True,
)

__all__ = [
    "DIFS",
    "MATCHERS",
    "OPTIONS",
    "PRECISIONS",
    "PRESETS",
    "SYMMETRIZE",
    "TREE_COMBINE",
    "MatchConfig",
    "resolve_config",
]
