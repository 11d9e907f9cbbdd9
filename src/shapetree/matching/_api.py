"""Matching two shapes under a :class:`MatchConfig` (the pair-level entry point).

The curve preparation here (validation, smoothing, resampling at the target phases,
mirroring) is the one the retrieval engine uses too, so ``match(a, b, config).cost`` equals
``distance_matrix([a], [b], config)[0, 0]`` for every configuration.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from shapetree._errors import ShapeTreeError
from shapetree.curves import as_curve, resample, smooth
from shapetree.matching._config import MatchConfig, resolve_config
from shapetree.matching._match import MatchParams, MatchResult, match_cost, match_prepared
from shapetree.matching._prepare import prepare_model, prepare_target

__all__ = [
    "kernel_params",
    "match",
    "mirror_curve",
    "model_curve",
    "model_passes",
    "target_curves",
]


def mirror_curve(points: ArrayLike, *, closed: bool = True) -> np.ndarray:
    """Mirror a curve left-right.

    Parameters
    ----------
    points : array_like, shape (n, 2)
        Any curve :func:`shapetree.curves.as_curve` accepts.
    closed : bool
        Closed curves are also reversed (``out[i] = mirror(points[n - 1 - i])``) so a
        counter-clockwise curve stays counter-clockwise (matching assumes both curves have
        the same orientation). Open curves keep their order (their ends stay their ends).

    Returns
    -------
    ndarray, shape (n, 2)
    """
    p = as_curve(points, closed=closed, name="curve to mirror") * np.array([-1.0, 1.0])
    return np.ascontiguousarray(p[::-1] if closed else p)


def _base_curve(points: ArrayLike, config: MatchConfig, closed: bool, name: str) -> np.ndarray:
    a = as_curve(points, closed=closed, name=name)
    if config.smooth:
        n_keep = a.shape[0]
        a = smooth(a, config.smooth, closed=closed)  # dense, evenly spaced
        if config.n_points is None:
            a = resample(a, n_keep, closed=closed)
    return a


def _sampled(
    a: np.ndarray, n: int | None, closed: bool, phase: float, resmooth: bool
) -> np.ndarray:
    if n is not None and (phase or resmooth or a.shape[0] != n):
        a = resample(a, n, closed=closed, phase=phase)
    return np.ascontiguousarray(a, dtype=np.float64)


def model_curve(
    points: ArrayLike, config: MatchConfig, *, closed: bool = True, name: str = "model curve"
) -> np.ndarray:
    """The model's sample points under ``config``: validated, smoothed, resampled.

    Parameters
    ----------
    points : array_like, shape (k, 2)
    config : MatchConfig
    closed : bool
    name : str
        Used in error messages.

    Returns
    -------
    ndarray, shape (config.n_points, 2) (or as given when ``n_points`` is None)
    """
    a = _base_curve(points, config, closed, name)
    return _sampled(a, config.n_points, closed, 0.0, bool(config.smooth))


def target_curves(
    points: ArrayLike, config: MatchConfig, *, closed: bool = True, name: str = "target curve"
) -> list[np.ndarray]:
    """The target's samplings under ``config``, one per phase.

    Parameters
    ----------
    points : array_like, shape (k, 2)
    config : MatchConfig
    closed : bool
        Open curves keep their ends, so they have one sampling whatever ``phases`` is.
    name : str

    Returns
    -------
    list of ndarray, each shape (config.target_points, 2)
        ``out[p]`` starts ``p / phases`` of a sample spacing after the first point.
    """
    a = _base_curve(points, config, closed, name)
    n_phase = config.phases if closed else 1
    return [
        _sampled(a, config.target_points, closed, p / n_phase, bool(config.smooth))
        for p in range(n_phase)
    ]


def _check_batched(config: MatchConfig) -> None:
    """Refuse the single-pair matchers where the batched directed kernel is asked for."""
    if config.matcher != "directed" or config.replace_any:
        what = "matcher='symmetric'" if config.matcher != "directed" else "replace_any=True"
        raise ShapeTreeError(
            f"{what} is a single-pair matcher (a dynamic program over pairs of subcurves, "
            "not the shape-tree kernel the batched engine runs): use "
            "shapetree.matching.match(a, b, config) or shapetree.matching._api.pair_cost "
            "for each pair"
        )


def kernel_params(config: MatchConfig) -> MatchParams:
    """The kernel-level parameters (κ, band, segment weight, ``dif``) of a configuration.

    Raises :class:`~shapetree.ShapeTreeError` for ``matcher="symmetric"`` or
    ``replace_any=True``, which the shape-tree kernel does not run (use :func:`match` or
    :func:`pair_cost`).
    """
    _check_batched(config)
    return MatchParams(
        occlusion=config.occlusion,
        band=config.band,
        segment_weight=config.segment_weight,
        dif=config.dif,
    )


def model_passes(model_pts: np.ndarray, config: MatchConfig, *, closed: bool = True) -> list:
    """The prepared model of each pass: the sampled curve, then (with ``mirror``) its
    mirror image; ``config``'s shape-trees, midpoint rule, λ and ``dif``."""
    _check_batched(config)
    kw = dict(
        closed=closed,
        # an open curve has one shape-tree per midpoint rule (its ends are fixed)
        n_trees=config.n_trees if closed else min(config.n_trees, 2),
        split=config.split,
        weight=config.weight,
        length_power=config.length_power,
        dif=config.dif,
    )
    curves = [model_pts]
    if config.mirror:
        curves.append(mirror_curve(model_pts, closed=closed))
    return [prepare_model(c, **kw) for c in curves]


def _unmirror(res: MatchResult, original: np.ndarray, closed: bool) -> MatchResult:
    """Express a matching of the mirrored model in the original model's indices."""
    n = original.shape[0]
    if closed:
        a_to_b = res.a_to_b[::-1].copy()
        b_to_a = np.mod(n - 1 - res.b_to_a, n)
        replaced = sorted(
            ((n - 1 - a1) % n, (n - 1 - a0) % n, b0, b1) for a0, a1, b0, b1 in res.replaced
        )
    else:
        a_to_b, b_to_a, replaced = res.a_to_b, res.b_to_a, res.replaced
    res.a, res.a_to_b, res.b_to_a, res.replaced = original, a_to_b, b_to_a, replaced
    res.mirrored = True
    return res


def _directed(
    a: np.ndarray,
    b: np.ndarray,
    config: MatchConfig,
    closed: bool,
    *,
    correspondence: bool,
    names: tuple[str, str],
) -> MatchResult:
    """ψ(A, B) under ``config``: the cheapest over mirror passes, phases and shape-trees."""
    model_pts = model_curve(a, config, closed=closed, name=names[0])
    targets = target_curves(b, config, closed=closed, name=names[1])
    passes = list(enumerate(model_passes(model_pts, config, closed=closed)))
    params = kernel_params(config)
    best: tuple[float, int, bool, Any] | None = None
    for phase, pts in enumerate(targets):
        t = prepare_target(pts, closed=closed, length_power=config.length_power, dtype=config.dtype)
        for mirrored, model in passes:
            c = match_cost(model, t, params)
            if best is None or c < best[0]:
                best = (c, phase, bool(mirrored), (model, t))
    assert best is not None
    cost, phase, mirrored, (model, t) = best
    if correspondence:
        res = match_prepared(model, t, params)
    else:
        m = t.n_points
        res = MatchResult(
            cost=cost,
            a=model.points,
            b=t.points,
            closed=closed,
            a_to_b=np.full(model.points.shape[0], np.nan),
            b_to_a=np.full(m, np.nan),
        )
    res.cost = cost  # the value every entry point reports (match_cost's exact path)
    res.phase = phase
    if mirrored:
        res = _unmirror(res, model_pts, closed)
    return res


def match(
    a: ArrayLike,
    b: ArrayLike,
    config: MatchConfig | str | None = None,
    *,
    closed: bool = True,
    **options: Any,
) -> MatchResult:
    """Deform curve ``a`` onto curve ``b`` with the least shape-tree deformation (eq. 1).

    Parameters
    ----------
    a, b : array_like, shapes (n, 2) and (m, 2)
        The curves: ``(x, y)`` arrays (closed curves without a repeated first point),
        OpenCV contours ``(n, 1, 2)``, or shapely polygons (their exterior).
    config : MatchConfig, str or None
        The matcher configuration, a preset name (``"paper"``, ``"general"``, ...), or
        ``None`` for the ``general`` preset (:data:`shapetree.matching.PRESETS`).
    closed : bool
        Open curves: endpoints map to endpoints. Closed curves: every cyclic alignment of
        ``b`` is tried.
    **options
        Any :class:`MatchConfig` field, changed on top of ``config``
        (``match(a, b, n_points=100, occlusion=0.5)``).

    Returns
    -------
    MatchResult
        ``cost`` is the configured distance of the pair (ψ(a, b), or the combination of
        both directions that ``symmetrize`` asks for), the same number
        :func:`shapetree.retrieval.distance_matrix` gives. The correspondence
        (``a_to_b``, ``b_to_a``, ``replaced``) is that of the cheapest a → b matching, in
        the indices of ``res.a`` (the model's samples, not mirrored) and ``res.b`` (the
        target's samples at phase ``res.phase``); ``res.mirrored`` says whether the
        mirrored model won. ``forward_cost`` is ψ(a, b) and ``backward_cost`` ψ(b, a)
        when it was computed.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    >>> circle = np.c_[np.cos(t), np.sin(t)]
    >>> bool(match(circle, 3 * circle, "paper").cost < 1e-9)
    True
    """
    cfg = resolve_config(config, **options)
    sym = cfg.symmetrize
    if sym == "reverse":
        back = _directed(b, a, cfg, closed, correspondence=False, names=("curve B", "curve A"))
        res = _directed(a, b, cfg, closed, correspondence=True, names=("curve A", "curve B"))
        res.forward_cost, res.backward_cost = res.cost, back.cost
        res.cost = back.cost
        return res
    res = _directed(a, b, cfg, closed, correspondence=True, names=("curve A", "curve B"))
    res.forward_cost = res.cost
    if sym == "none":
        return res
    back = _directed(b, a, cfg, closed, correspondence=False, names=("curve B", "curve A"))
    res.backward_cost = back.cost
    f, r = res.forward_cost, back.cost
    res.cost = min(f, r) if sym == "min" else max(f, r) if sym == "max" else 0.5 * (f + r)
    return res


def directed_cost(a: ArrayLike, b: ArrayLike, config: MatchConfig, *, closed: bool = True) -> float:
    """ψ(a, b) under ``config`` without the correspondence."""
    return _directed(a, b, config, closed, correspondence=False, names=("curve A", "curve B")).cost
