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
    "pair_cost",
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
            "shapetree.matching.match(a, b, config) or shapetree.matching._api.pair_cost(a, "
            "b, config) for each pair ('shapetree match A B' on the command line)"
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
        tree_combine=config.tree_combine,
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


def _pair_dp(
    a: np.ndarray,
    b: np.ndarray,
    config: MatchConfig,
    closed: bool,
    *,
    correspondence: bool,
    names: tuple[str, str],
) -> MatchResult:
    """The pair-of-subcurves matchers (:mod:`._subcurves`): ``matcher="symmetric"`` and/or
    ``replace_any``; the cheapest over the mirror passes and phases.

    Directed (``replace_any`` alone): A sampled once (and mirrored), B at every phase, as
    :func:`_directed`. Symmetric: the set of sampled pairs is closed under exchanging the
    curves, ``(mirror^σ(A_p), B_0)`` and ``(A_0, mirror^σ(B_p))`` for every phase ``p`` and
    pass ``σ``, so the minimum is symmetric too.
    """
    from shapetree.matching._subcurves import pair_curve, pair_tables, pair_top, pair_traceback

    sym = config.matcher == "symmetric"
    if not closed and config.n_trees > 1:
        raise ShapeTreeError(
            "the pair matchers (symmetric, replace_any) have one shape-tree rule for open "
            "curves (split='half'): use n_trees=1"
        )
    n_pass = 2 if config.mirror else 1
    if sym:
        sa = target_curves(a, config, closed=closed, name=names[0])
        sb = target_curves(b, config, closed=closed, name=names[1])
        pairs = []
        for p in range(len(sa)):
            for sig in range(n_pass):
                pairs.append(((p, sig, 0, 0), (sa[p], sig), (sb[0], 0)))
                if p or sig:
                    pairs.append(((0, 0, p, sig), (sa[0], 0), (sb[p], sig)))
    else:
        a0 = model_curve(a, config, closed=closed, name=names[0])
        sb = target_curves(b, config, closed=closed, name=names[1])
        pairs = [
            ((0, sig, p, 0), (a0, sig), (sb[p], 0)) for p in range(len(sb)) for sig in range(n_pass)
        ]
    cache: dict = {}

    def prep(pts: np.ndarray, sig: int):
        key = (id(pts), sig)
        if key not in cache:
            q = mirror_curve(pts, closed=closed) if sig else pts
            cache[key] = (
                q,
                pair_curve(
                    q,
                    closed=closed,
                    weight=config.weight,
                    length_power=config.length_power,
                    dif=config.dif,
                ),
            )
        return cache[key]

    kw = dict(
        symmetric=sym,
        replace_any=config.replace_any,
        dif=config.dif,
        occlusion=config.occlusion,
        segment_weight=config.segment_weight,
        band=config.band,
    )
    best = None
    for label, (pa, siga), (pb, sigb) in pairs:
        (qa, ca), (qb, cb) = prep(pa, siga), prep(pb, sigb)
        S, H, ok = pair_tables(ca, cb, **kw)
        cost, top = pair_top(S, ca, cb, symmetric=sym, n_trees=config.n_trees)
        if best is None or cost < best[0]:
            best = (cost, label, qa, qb, ca, cb, top, (S, H, ok) if correspondence else None)
    assert best is not None
    cost, (pha, siga, phb, sigb), qa, qb, ca, cb, top, tabs = best
    if correspondence and tabs is not None and np.isfinite(cost):
        S, H, ok = tabs
        a_to_b, b_to_a, replaced = pair_traceback(
            S,
            H,
            ok,
            ca,
            cb,
            top,
            symmetric=sym,
            dif=config.dif,
            occlusion=config.occlusion,
            segment_weight=config.segment_weight,
        )
    else:
        a_to_b, b_to_a, replaced = (
            np.full(qa.shape[0], np.nan),
            np.full(qb.shape[0], np.nan),
            [],
        )
    res = MatchResult(
        cost=max(float(cost), 0.0),
        a=qa,
        b=qb,
        closed=closed,
        a_to_b=a_to_b,
        b_to_a=b_to_a,
        replaced=replaced,
        tree_index=int(top[1]) if top[0] != "open" else 0,
        costs=np.array([cost]),
        phase=phb,
    )
    if siga:
        orig = prep(pa, 0)[0]
        res = _unmirror(res, orig, closed)
    res.mirrored = bool(siga or sigb)
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
    if config.matcher != "directed" or config.replace_any:
        return _pair_dp(a, b, config, closed, correspondence=correspondence, names=names)
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
        (``match(a, b, n_points=100, occlusion=0.5)``). ``matcher="symmetric"`` and
        ``replace_any=True`` run the slower dynamic programs over pairs of subcurves
        (:mod:`shapetree.matching._subcurves`); with them ``res.a`` / ``res.b`` are the
        samplings that were matched (under the symmetric matcher either may be a
        phase-shifted or, with ``res.mirrored``, B's mirrored copy).

    Returns
    -------
    MatchResult
        ``cost`` is the configured distance of the pair (ψ(a, b), or the combination of
        both directions that ``symmetrize`` asks for, fused with the height-function
        distance ``res.height_cost`` when ``height_weight > 0``), the same number
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
    return _configured(a, b, cfg, closed, correspondence=True)


def pair_cost(
    a: ArrayLike,
    b: ArrayLike,
    config: MatchConfig | str | None = None,
    *,
    closed: bool = True,
    **options: Any,
) -> float:
    """``match(a, b, config).cost`` without the correspondence, for every configuration.

    The one-pair entry point for the options the batched engine does not run
    (``matcher="symmetric"``, ``replace_any=True``: dynamic programs over pairs of
    subcurves, :mod:`._subcurves`); for the directed shape-tree matcher it is the same
    number as :func:`shapetree.retrieval.distance_matrix` gives.

    Parameters
    ----------
    a, b : array_like, shapes (n, 2) and (m, 2)
    config : MatchConfig, str or None
    closed : bool
    **options
        :class:`MatchConfig` fields changed on top of ``config``.

    Returns
    -------
    float
    """
    cfg = resolve_config(config, **options)
    return _configured(a, b, cfg, closed, correspondence=False).cost


def height_outline(points: ArrayLike, config: MatchConfig, *, name: str) -> np.ndarray:
    """The outline the height functions are computed on: validated and smoothed as the
    shape-tree's curves (:func:`model_curve`), not resampled (closed curves only)."""
    return _base_curve(points, config, True, name)


def fuse_height(psi: ArrayLike, h: ArrayLike, weight: float) -> np.ndarray:
    """The distance ``ψ^(1 - w) h^w`` of :attr:`MatchConfig.height_weight` (``w = 0``: ψ;
    ``w = 1``: ``h``, as ``0^0 = 1``; negative rounding errors of ψ count as 0)."""
    psi = np.maximum(np.asarray(psi, dtype=np.float64), 0.0)
    return psi ** (1.0 - weight) * np.asarray(h, dtype=np.float64) ** weight


def _configured(
    a: ArrayLike, b: ArrayLike, cfg: MatchConfig, closed: bool, *, correspondence: bool
) -> MatchResult:
    if cfg.height_weight > 0 and not closed:
        raise ShapeTreeError(
            "height_weight > 0 fuses the height-function distance, which is defined for "
            "closed curves only: use closed=True or height_weight=0"
        )
    res = _shape_tree(a, b, cfg, closed, correspondence=correspondence)
    if cfg.height_weight > 0:
        from shapetree.matching._height import HeightParams, height_descriptors, height_distance

        hp = HeightParams.of(cfg.height_points, cfg.height_complexity)
        da = height_descriptors(height_outline(a, cfg, name="curve A"), hp)
        db = height_descriptors(height_outline(b, cfg, name="curve B"), hp)
        res.height_cost = height_distance(da, db, hp)
        res.cost = float(fuse_height(res.cost, res.height_cost, cfg.height_weight))
    return res


def _shape_tree(
    a: ArrayLike, b: ArrayLike, cfg: MatchConfig, closed: bool, *, correspondence: bool
) -> MatchResult:
    sym = cfg.symmetrize
    if cfg.matcher == "symmetric":  # symmetric by construction (symmetrize is "none")
        res = _directed(
            a, b, cfg, closed, correspondence=correspondence, names=("curve A", "curve B")
        )
        res.forward_cost = res.backward_cost = res.cost
        return res
    if sym == "reverse":
        back = _directed(b, a, cfg, closed, correspondence=False, names=("curve B", "curve A"))
        res = _directed(
            a, b, cfg, closed, correspondence=correspondence, names=("curve A", "curve B")
        )
        res.forward_cost, res.backward_cost = res.cost, back.cost
        res.cost = back.cost
        return res
    res = _directed(a, b, cfg, closed, correspondence=correspondence, names=("curve A", "curve B"))
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
