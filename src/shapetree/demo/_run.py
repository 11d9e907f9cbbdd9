"""The built-in demonstration: rank demo shapes by their matching cost to a query."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from shapetree._errors import ShapeTreeError
from shapetree.demo._shapes import demo_shape, demo_shapes
from shapetree.matching import MatchConfig
from shapetree.matching._config import resolve_config

__all__ = ["Candidate", "DemoRanking", "demo_ranking", "similarity"]


@dataclass
class Candidate:
    """One target of the demo ranking.

    Attributes
    ----------
    name : str
        Short name (``"G~1"`` for the first deformed copy of ``"G"``).
    description : str
        What the shape is.
    points : ndarray, shape (n, 2)
    same_as_query : bool
        Whether this is a deformed copy of the query.
    cost : float
        ψ(query, candidate), filled by :func:`demo_ranking`.
    """

    name: str
    description: str
    points: np.ndarray
    same_as_query: bool = False
    cost: float = float("nan")


@dataclass
class DemoRanking:
    """Result of :func:`demo_ranking`.

    Attributes
    ----------
    query_name : str
    query : ndarray, shape (n, 2)
    candidates : list of Candidate
        Sorted by increasing cost (best match first).
    params : dict
        The settings used.
    """

    query_name: str
    query: np.ndarray
    candidates: list[Candidate] = field(default_factory=list)
    params: dict = field(default_factory=dict)


def similarity(
    points: np.ndarray, *, angle: float = 0.0, scale: float = 1.0, shift=(0.0, 0.0), roll: int = 0
) -> np.ndarray:
    """Rotate (radians), scale, translate a curve and move its start point by ``roll``.

    Parameters
    ----------
    points : ndarray, shape (n, 2)
    angle, scale : float
    shift : (float, float)
    roll : int
        New first point index (closed curves: the same curve, sampled from elsewhere).

    Returns
    -------
    ndarray, shape (n, 2)
    """
    c, s = np.cos(angle), np.sin(angle)
    rot = np.array([[c, -s], [s, c]])
    out = scale * np.asarray(points, dtype=float) @ rot.T + np.asarray(shift, dtype=float)
    return np.roll(out, -int(roll), axis=0)


def _short(name: str) -> str:
    return name[len("glyph-") :] if name.startswith("glyph-") else name


def demo_ranking(
    query: str = "G",
    config: MatchConfig | str | None = None,
    *,
    n_points: int = 120,
    scale: float = 0.04,
    copies: int = 2,
    seed: int = 0,
    progress: bool = False,
) -> DemoRanking:
    """Match a demo shape against deformed copies of itself and every other demo shape.

    The targets are: ``copies`` random deformations of the query (noise ``scale`` on its
    shape-tree's Bookstein coordinates, then rotated, rescaled, shifted and started at
    another point, none of which the cost sees), one equally deformed copy of another
    letter, and all other demo shapes. Each cost is ``match(query, target, config).cost``
    (computed for all targets at once by :func:`shapetree.retrieval.distance_matrix`).

    Parameters
    ----------
    query : str, default "G"
        A demo shape name or a single character (its glyph).
    config : MatchConfig, str or None
        Matcher configuration or preset name (default: the ``general`` preset).
    n_points : int, default 120
        Points per drawn curve (the configuration then resamples them).
    scale : float, default 0.04
        Deformation noise (Bookstein units).
    copies : int, default 2
        Deformed copies of the query among the targets.
    seed : int, default 0
    progress : bool, default False
        Show a tqdm progress bar.

    Returns
    -------
    DemoRanking
        Candidates sorted by cost.
    """
    from shapetree.retrieval import distance_matrix
    from shapetree.tree import build_shape_tree, deform

    qname = f"glyph-{query}" if len(query) == 1 else query
    q = demo_shape(qname, n_points=n_points)
    if copies < 1:
        raise ShapeTreeError(f"copies must be >= 1, got {copies}")
    rng = np.random.default_rng(seed)
    shapes = demo_shapes(n_points=n_points)
    cands: list[Candidate] = []

    def deformed(pts: np.ndarray, k: int) -> np.ndarray:
        tree = build_shape_tree(pts, closed=True)
        d = deform(tree, scale, rng=rng)
        ang = rng.uniform(-0.6, 0.6)
        return similarity(
            d,
            angle=ang,
            scale=rng.uniform(0.6, 1.6),
            shift=rng.uniform(-2, 2, 2),
            roll=int(rng.integers(n_points)),
        )

    qs = _short(qname)
    for k in range(1, copies + 1):
        cands.append(
            Candidate(
                f"{qs}~{k}",
                f"{qs} deformed #{k} (rotated, rescaled, new start)",
                deformed(q, k),
                True,
            )
        )
    other = next(g for g in ("glyph-S", "glyph-G", "glyph-A") if g != qname)
    cands.append(
        Candidate(f"{_short(other)}~1", f"{_short(other)} deformed #1", deformed(shapes[other], 1))
    )
    for name, pts in shapes.items():
        if name != qname:
            kind = "glyph" if name.startswith("glyph-") else "drawn shape"
            cands.append(Candidate(_short(name), kind, pts))
    costs = distance_matrix([q], [c.points for c in cands], config, progress=progress)[0]
    for c, cost in zip(cands, costs):
        c.cost = float(cost)
    cands.sort(key=lambda c: c.cost)
    return DemoRanking(
        qname,
        q,
        cands,
        {
            "n_points": n_points,
            "scale": scale,
            "copies": copies,
            "seed": seed,
            "config": resolve_config(config).as_dict(),
        },
    )
