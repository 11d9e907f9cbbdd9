"""Verification of a kept detection: shape-context agreement of the placed outline.

The stitched cost of §4 is not comparable from one image to the next: a cluttered picture
offers many contours that chain into something cheap. The verification term asks a
second, holistic question of each kept detection, bounded and with the same meaning in
every image: *does the outline the detection places in the image have the model's
layout?*

For a set of points ``p_1 .. p_n`` the shape context of ``p_i`` (Belongie, Malik &
Puzicha, PAMI 2002) is the histogram of where the other points lie relative to it, in
``N_RADIAL`` log-spaced distance bins (from ``R_INNER`` to ``R_OUTER`` times the mean
pairwise distance, so the histogram is scale-invariant; points nearer or farther fall
outside) and ``N_ANGULAR`` direction bins, normalised to sum 1. The **context agreement**
of the model samples ``M`` and their placement ``P`` in the image (row ``i`` of one
corresponds to row ``i`` of the other) is the mean over ``i`` of the histogram
intersection ``sum_b min(h_i^M[b], h_i^P[b])``, in ``[0, 1]``: 1 when ``P`` is a
translated and scaled copy of ``M``.

It is deliberately **not rotation-invariant**: directions are measured in the image
frame, so a placement that lays the model on its side (a giraffe draped along a table
edge) agrees less than an upright one. Photographed objects are mostly upright, and the
matching itself is rotation-invariant, so this is the one place the pipeline sees the
orientation.

:class:`~shapetree.detection.DetectParams` ``context_check`` weighs it into the ranking
score (``+ context_check * agreement``). Of the candidate terms measured on ETHZ by
``benchmarks/ethz_verify.py`` (edge support, orientation agreement, chamfer distance,
unexplained edges inside and around, colour figure/ground contrast, the worst-matching
part, the §3 shape-tree distance of the placed outline and its contrast against generic
shapes, within-image margins, a logistic regression on all of them) it is the only one
that raised the detection rate chosen leave-one-class-out.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from shapetree._errors import ShapeTreeError

__all__ = [
    "N_ANGULAR",
    "N_RADIAL",
    "R_INNER",
    "R_OUTER",
    "context_agreement",
    "shape_contexts",
]

#: Distance bins of a shape context (log-spaced).
N_RADIAL = 5
#: Direction bins of a shape context.
N_ANGULAR = 12
#: Distance range of the bins, in units of the mean pairwise distance (Belongie et al.).
R_INNER = 0.125
R_OUTER = 2.0


def _points(points: ArrayLike, name: str) -> NDArray[np.float64]:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ShapeTreeError(f"{name} must be an (n, 2) array of points, got shape {p.shape}")
    if len(p) < 3:
        raise ShapeTreeError(f"{name} needs at least 3 points, got {len(p)}")
    if not np.all(np.isfinite(p)):
        raise ShapeTreeError(f"{name} contains NaN or infinite coordinates")
    return p


def shape_contexts(points: ArrayLike) -> NDArray[np.float64]:
    """Log-polar shape context of every point of a set.

    Parameters
    ----------
    points : array_like, shape (n, 2)
        Points (px or any unit; the bins scale with the mean pairwise distance).

    Returns
    -------
    ndarray, shape (n, N_RADIAL * N_ANGULAR)
        Row ``i``: the share of the other points in each (distance, direction) bin seen
        from point ``i``, distance bin major; points outside ``[R_INNER, R_OUTER)``
        mean distances are not counted; each row is divided by its count (it sums to 1,
        or is all 0 when no other point is in range).

    Raises
    ------
    ShapeTreeError
        Not an ``(n, 2)`` array with ``n >= 3`` finite points, or all points coincide.
    """
    p = _points(points, "points")
    n = len(p)
    d = p[None, :, :] - p[:, None, :]  # d[i, j] = p_j - p_i
    r = np.hypot(d[..., 0], d[..., 1])
    off = ~np.eye(n, dtype=bool)
    mean = float(r[off].mean())
    if not mean > 0:
        raise ShapeTreeError("points all coincide: a shape context needs a spread of points")
    edges = np.exp(np.linspace(np.log(R_INNER), np.log(R_OUTER), N_RADIAL + 1))
    with np.errstate(divide="ignore"):
        rb = np.searchsorted(edges, r / mean, side="right") - 1
    ang = np.arctan2(d[..., 1], d[..., 0])  # (-pi, pi]
    ab = np.floor((ang + np.pi) / (2.0 * np.pi) * N_ANGULAR).astype(np.int64) % N_ANGULAR
    ok = off & (rb >= 0) & (rb < N_RADIAL)
    rows = np.broadcast_to(np.arange(n)[:, None], (n, n))[ok]
    bins = (rb * N_ANGULAR + ab)[ok]
    h = np.zeros((n, N_RADIAL * N_ANGULAR))
    np.add.at(h, (rows, bins), 1.0)
    return h / np.maximum(h.sum(axis=1, keepdims=True), 1.0)


def _shape_contexts_reference(points: ArrayLike) -> list[list[float]]:
    """Plain-Python loops of :func:`shape_contexts` (the test oracle)."""
    import math

    p = [(float(x), float(y)) for x, y in np.asarray(points, dtype=np.float64)]
    n = len(p)
    dist = [[math.hypot(p[j][0] - p[i][0], p[j][1] - p[i][1]) for j in range(n)] for i in range(n)]
    mean = sum(dist[i][j] for i in range(n) for j in range(n) if i != j) / (n * (n - 1))
    step = (math.log(R_OUTER) - math.log(R_INNER)) / N_RADIAL
    out = []
    for i in range(n):
        row = [0.0] * (N_RADIAL * N_ANGULAR)
        for j in range(n):
            if j == i or dist[i][j] == 0:
                continue
            k = math.floor((math.log(dist[i][j] / mean) - math.log(R_INNER)) / step)
            if not 0 <= k < N_RADIAL:
                continue
            ang = math.atan2(p[j][1] - p[i][1], p[j][0] - p[i][0])
            a = math.floor((ang + math.pi) / (2 * math.pi) * N_ANGULAR) % N_ANGULAR
            row[k * N_ANGULAR + a] += 1.0
        total = sum(row)
        out.append([v / total for v in row] if total else row)
    return out


def context_agreement(model_points: ArrayLike, image_points: ArrayLike) -> float:
    """Shape-context agreement of a model's samples and their placement, in ``[0, 1]``.

    Parameters
    ----------
    model_points : array_like, shape (n, 2)
        The model's samples.
    image_points : array_like, shape (n, 2)
        Where a detection places each of them in the image (px); row ``i`` corresponds
        to row ``i`` of ``model_points``.

    Returns
    -------
    float
        Mean over the points of the intersection of their shape contexts
        (:func:`shape_contexts`) in the two sets: 1 for a translated and scaled copy,
        symmetric in its arguments, not invariant to rotation or reflection.

    Raises
    ------
    ShapeTreeError
        Bad arrays (see :func:`shape_contexts`) or different numbers of points.
    """
    a = _points(model_points, "model_points")
    b = _points(image_points, "image_points")
    if a.shape != b.shape:
        raise ShapeTreeError(
            f"model_points and image_points must correspond row by row, got {len(a)} and "
            f"{len(b)} points"
        )
    ha, hb = shape_contexts(a), shape_contexts(b)
    return float(np.mean(np.minimum(ha, hb).sum(axis=1)))
