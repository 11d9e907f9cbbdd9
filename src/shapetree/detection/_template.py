"""The upright template check: the model as drawn, fitted to a detection's box by chamfer.

The stitching (§4) is invariant to rotation, so a detection can put the right box around
an object with the model's outline turned on its side (about half of the correct mug
detections on ETHZ do). Every check of the placed outline then judges the wrong outline.
This check looks at the *box* instead: the model as drawn (upright, or mirrored left to
right) is fitted to the edge map around the box by a small exhaustive search, and scored
by an oriented chamfer match.

Placements (486 per box): the model, as drawn or mirrored and turned by -8, 0 or 8
degrees, is stretched to the box, its aspect changed by 0.8, 1 or 1.25, scaled by 0.85,
1 or 1.15 and its centre moved by -0.1, 0 or 0.1 box sides in x and in y. A model point
at distance ``d`` from the nearest edge pixel (edge strength above the threshold), whose
normal makes an angle ``a`` with that pixel's edge normal, costs
``0.5 min(d / t, 1) + 0.5 |sin a|`` (``|sin a|`` counted as 1 when ``d >= t``), with
``t = 0.05`` times the placed template's size (the square root of the box area times the
scale); points outside the image cost 1.

- ``template`` = 1 - the least mean point cost over the placements, in ``[0, 1]``;
- ``template_support`` = at that placement, the share of model points within ``t`` of an
  edge pixel whose normal is within 30 degrees of theirs, in ``[0, 1]``;
- ``template_gain`` = the least mean cost of the same search with the model turned by 90
  or -90 degrees, less the upright one's: positive where the box holds the object upright
  rather than on its side;
- ``box_density`` = the share of edge pixels inside the box (clutter, against which a
  chamfer match means less), in ``[0, 1]``.

All four are terms of the collection re-scorer (:mod:`._rescore`). The search is compiled
(numba); ``tests/test_detection_template.py`` holds a NumPy reference it is checked
against.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

from shapetree._errors import ShapeTreeError
from shapetree.curves import resample

__all__ = [
    "TEMPLATE_TERMS",
    "TemplateFields",
    "box_density",
    "grown_fit",
    "template_fields",
    "template_model",
    "template_terms",
]

#: the terms :func:`template_terms` gives
TEMPLATE_TERMS = ("template", "template_support", "template_gain", "box_density")

#: dense samples of the model outline
N_POINTS = 80
#: chamfer distance cap, as a share of the placed template's size
TAU = 0.05
SCALES = (0.85, 1.0, 1.15)
SHIFTS = (-0.1, 0.0, 0.1)
ASPECTS = (0.8, 1.0, 1.25)
ROTATIONS = tuple(float(v) for v in np.deg2rad((-8.0, 0.0, 8.0)))
#: the widened search of :func:`grown_fit` (it includes SCALES and SHIFTS)
GROWN_SCALES = (0.85, 1.0, 1.15, 1.3, 1.5, 1.75, 2.0)
GROWN_SHIFTS = (-0.3, -0.2, -0.1, 0.0, 0.1, 0.2, 0.3)
#: the turns of the two searches: upright, and on either side
UPRIGHT = (0.0,)
ON_SIDE = (np.pi / 2, -np.pi / 2)


class TemplateFields(NamedTuple):
    """What the template check reads from one edge map (:func:`template_fields`)."""

    dt: NDArray[np.float64]
    theta: NDArray[np.float64]
    on: NDArray[np.bool_]


def template_fields(edges: ArrayLike, threshold: float) -> TemplateFields:
    """Distance to the nearest edge pixel and that pixel's edge-normal angle.

    Parameters
    ----------
    edges : array_like, shape (H, W)
        Soft edge map in ``[0, 1]``.
    threshold : float
        Pixels above it are edge pixels (``DetectParams.threshold``).

    Returns
    -------
    dt : ndarray, shape (H, W)
        Euclidean distance (px) to the nearest edge pixel (1e6 everywhere if there is none).
    theta : ndarray, shape (H, W)
        Normal angle (radians) of the nearest edge pixel: the dominant gradient direction
        of the smoothed map (structure tensor, sigma 1.5 px).
    on : ndarray, shape (H, W), bool
        The edge pixels.
    """
    e = np.asarray(edges, dtype=np.float64)
    if e.ndim != 2 or e.size == 0:
        raise ShapeTreeError(f"template_fields: an (H, W) edge map is needed, got {e.shape}")
    on = e > threshold
    es = ndimage.gaussian_filter(e, 1.5)
    gy, gx = np.gradient(es)
    jxx = ndimage.gaussian_filter(gx * gx, 1.5)
    jyy = ndimage.gaussian_filter(gy * gy, 1.5)
    jxy = ndimage.gaussian_filter(gx * gy, 1.5)
    theta = 0.5 * np.arctan2(2 * jxy, jxx - jyy)
    if not on.any():
        return TemplateFields(np.full(e.shape, 1e6), theta, on)
    dt, (ir, ic) = ndimage.distance_transform_edt(~on, return_indices=True)
    return TemplateFields(dt, theta[ir, ic], on)


def template_model(model_points: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Dense closed model outline centred on its box, and its tangents (central
    differences), shapes (N_POINTS, 2)."""
    p = resample(model_points, N_POINTS, closed=True)
    p = p - (p.min(0) + p.max(0)) / 2
    return p, np.roll(p, -1, 0) - np.roll(p, 1, 0)


def _variants(
    model: tuple[NDArray[np.float64], NDArray[np.float64]],
    turns: Sequence[float],
    box: tuple[float, float],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Every (mirror, turn, rotation, aspect) variant of the model stretched to a box of
    ``(width, height)`` px and centred on 0: points (V, K, 2), normal angles (V, K)."""
    p, tang = model
    pts, nrm = [], []
    for mirror in (False, True):
        f = np.array([-1.0, 1.0]) if mirror else np.ones(2)
        for turn in turns:
            for r in ROTATIONS:
                a = turn + r
                rot = np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
                q, tq = (p * f) @ rot, (tang * f) @ rot
                ext = np.maximum(q.max(0) - q.min(0), 1e-9)
                for g in ASPECTS:
                    k = np.asarray(box) / ext * np.array([np.sqrt(g), 1 / np.sqrt(g)])
                    pts.append(q * k)
                    t = tq * k
                    nrm.append(np.arctan2(t[:, 1], t[:, 0]) + np.pi / 2)
    return np.array(pts), np.array(nrm)


@numba.njit(cache=True, nogil=True)
def _search(dt, theta, vp, vn, cx, cy, side, scales, shifts, tau):  # pragma: no cover
    h, w = dt.shape
    nv, nk = vn.shape
    best, best_sup = np.inf, 0.0
    arg_v, arg_sc, arg_x, arg_y = 0, 1.0, cx, cy
    for sc in scales:
        t = tau * sc * side
        for dx in shifts:
            ox = cx + dx * side
            for dy in shifts:
                oy = cy + dy * side
                for v in range(nv):
                    total = 0.0
                    sup = 0
                    for k in range(nk):
                        c = int(np.rint(vp[v, k, 0] * sc + ox))
                        r = int(np.rint(vp[v, k, 1] * sc + oy))
                        if c < 0 or c >= w or r < 0 or r >= h:
                            total += 1.0
                            continue
                        d = dt[r, c]
                        if d < t:
                            s = abs(np.sin(vn[v, k] - theta[r, c]))
                            total += 0.5 * d / t + 0.5 * s
                            if s < 0.5:
                                sup += 1
                        else:
                            total += 1.0
                    mean = total / nk
                    if mean < best:
                        best, best_sup = mean, sup / nk
                        arg_v, arg_sc, arg_x, arg_y = v, sc, ox, oy
    return best, best_sup, arg_v, arg_sc, arg_x, arg_y


def _place(
    fields: TemplateFields,
    model,
    bbox: Sequence[float],
    turns,
    scales: Sequence[float] = SCALES,
    shifts: Sequence[float] = SHIFTS,
) -> tuple[float, float, tuple[float, float, float, float]]:
    """The search with ``turns`` over ``scales`` and ``shifts`` (shares of the box side):
    the least mean point cost, the share of model points at that placement within ``t``
    of an edge whose normal is within 30 degrees, and the placed model's box."""
    dt, theta, _ = fields
    x1, y1, x2, y2 = (float(v) for v in bbox)
    bw, bh = max(x2 - x1, 1.0), max(y2 - y1, 1.0)
    vp, vn = _variants(model, turns, (bw, bh))
    best, support, v, sc, ox, oy = _search(
        dt,
        theta,
        vp,
        vn,
        (x1 + x2) / 2,
        (y1 + y2) / 2,
        float(np.sqrt(bw * bh)),
        np.asarray(scales, dtype=np.float64),
        np.asarray(shifts, dtype=np.float64),
        TAU,
    )
    q = vp[v] * sc + np.array([ox, oy])
    lo, hi = q.min(0), q.max(0)
    return float(best), float(support), (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))


def _best(fields: TemplateFields, model, bbox: Sequence[float], turns) -> tuple[float, float]:
    """Least mean point cost of the search with ``turns``, and the share of model points
    at that placement within ``t`` of an edge whose normal is within 30 degrees."""
    best, support, _ = _place(fields, model, bbox, turns)
    return best, support


def grown_fit(
    fields: TemplateFields,
    model: tuple[NDArray[np.float64], NDArray[np.float64]],
    bbox: Sequence[float],
) -> tuple[float, tuple[float, float, float, float]]:
    """The upright template search widened around a detection's box: its least mean
    point cost and the box of that placement (``DetectParams.box_refine``).

    The same placements as ``template`` (the model as drawn or mirrored, turned by -8, 0
    or 8 degrees, its aspect 0.8, 1 or 1.25), scaled by each of :data:`GROWN_SCALES` and
    moved by each of :data:`GROWN_SHIFTS` box sides in x and in y: the object may be up
    to twice the box (a detection that matched a giraffe's neck and back, the legs left to
    gaps). Its cost is never above ``1 - template`` (the search holds the template's own).

    Parameters
    ----------
    fields : tuple of ndarray
        :func:`template_fields` of the image's edge map.
    model : tuple of ndarray
        :func:`template_model` of the model's samples.
    bbox : sequence of 4 floats
        ``(x1, y1, x2, y2)`` of the detection (px).

    Returns
    -------
    cost : float
        Least mean point cost, in ``[0, 1]``.
    box : tuple of 4 floats
        ``(x1, y1, x2, y2)`` of the placed template (px; may reach past the image).
    """
    if len(bbox) != 4 or not np.isfinite(np.asarray(bbox, dtype=float)).all():
        raise ShapeTreeError(f"grown_fit: bbox must be 4 finite numbers, got {bbox!r}")
    cost, _, box = _place(fields, model, bbox, UPRIGHT, GROWN_SCALES, GROWN_SHIFTS)
    return cost, box


def template_terms(
    fields: TemplateFields,
    model: tuple[NDArray[np.float64], NDArray[np.float64]],
    bbox: Sequence[float],
) -> dict[str, float]:
    """The four template terms of one detection box (module docstring).

    Parameters
    ----------
    fields : tuple of ndarray
        :func:`template_fields` of the image's edge map.
    model : tuple of ndarray
        :func:`template_model` of the model's samples.
    bbox : sequence of 4 floats
        ``(x1, y1, x2, y2)`` of the detection (px).

    Returns
    -------
    dict
        ``template`` in ``[0, 1]`` (higher: the upright model fits the box's edges
        better), ``template_support`` in ``[0, 1]``, ``template_gain`` in ``[-1, 1]`` and
        ``box_density`` in ``[0, 1]``.
    """
    if len(bbox) != 4 or not np.isfinite(np.asarray(bbox, dtype=float)).all():
        raise ShapeTreeError(f"template_terms: bbox must be 4 finite numbers, got {bbox!r}")
    up, support = _best(fields, model, bbox, UPRIGHT)
    side, _ = _best(fields, model, bbox, ON_SIDE)
    return {
        "template": 1.0 - up,
        "template_support": support,
        "template_gain": side - up,
        "box_density": box_density(fields.on, bbox),
    }


def box_density(on: NDArray[np.bool_], bbox: Sequence[float]) -> float:
    """Share of edge pixels ``on`` inside the box (clipped to the image; 0 if empty)."""
    h, w = on.shape
    x1, y1, x2, y2 = (
        int(np.clip(round(float(v)), 0, lim)) for v, lim in zip(bbox, (w, h, w, h), strict=True)
    )
    if x2 <= x1 or y2 <= y1:
        return 0.0
    return float(np.mean(on[y1:y2, x1:x2]))
