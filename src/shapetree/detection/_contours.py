"""Linking thinned edge pixels into long smooth open contours (paper §4, stage 2).

The paper used the min-cover salient-curve tracer of Felzenszwalb & McAllester.
This module uses a simpler, deterministic tracer:

1. **hysteresis**: keep pixels with strength >= ``low`` that are 8-connected
   to a pixel with strength >= ``threshold``;
2. **thinning**: skeletonise the kept pixels to one-pixel-wide curves;
3. **junctions**: a pixel whose 8-neighbourhood, read around the circle,
   has >= 3 separate runs of edge pixels (crossing number >= 3) is a
   junction.  Junction pixels are removed, each remaining 8-connected piece
   is walked end to end (closed loops are opened at an arbitrary pixel and
   cut in two at the pixel farthest from it), and a junction pixel touching
   a chain end is appended to that end, so chains meeting at a junction share
   an endpoint;
4. **smoothing**: pixel coordinates are smoothed along the chain with a
   Gaussian of ``smooth`` pixels (ends are kept);
5. **sharp turns**: the chain is resampled at 1 px; the turning angle at
   arclength ``s`` is the angle between the chords ``s-w -> s`` and
   ``s -> s+w`` (``w = turn_window`` px); wherever it exceeds ``max_turn``
   the chain is cut at the local maximum of the turning angle;
6. **length**: pieces shorter than ``min_length`` px are dropped;
7. **resampling**: each piece is resampled uniformly in arclength, with
   ``n_points`` points if given, else with a spacing of about ``spacing`` px
   (``max(2, round(length / spacing) + 1)`` points, both ends kept).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

from shapetree._errors import ImageError, ShapeTreeError
from shapetree.curves import resample

__all__ = ["trace_contours", "polyline_length", "TracedContour"]

# 8-neighbourhood in circular order: N, NE, E, SE, S, SW, W, NW  (dr, dc)
_CIRC = ((-1, 0), (-1, 1), (0, 1), (1, 1), (1, 0), (1, -1), (0, -1), (-1, -1))


@dataclass(frozen=True)
class TracedContour:
    """One traced contour before resampling.

    Attributes
    ----------
    points : ndarray, shape (n, 2)
        Polyline ``(x=col, y=row)`` in pixels, resampled at 1 px.
    strength : float
        Mean edge strength of the contour's pixels, in ``[0, 1]``.
    """

    points: NDArray[np.float64]
    strength: float


def polyline_length(points: NDArray[np.float64]) -> float:
    """Length of an open polyline.

    Parameters
    ----------
    points : ndarray, shape (n, 2)

    Returns
    -------
    float
        Sum of segment lengths (same units as ``points``).
    """
    if len(points) < 2:
        return 0.0
    return float(np.sum(np.hypot(*np.diff(points, axis=0).T)))


def _neighbour_tables(mask: NDArray[np.bool_]) -> tuple[NDArray, NDArray]:
    """Per pixel: number of 8-neighbours and crossing number (runs around the circle)."""
    p = np.pad(mask, 1)
    h, w = mask.shape
    nb = [p[1 + dr : 1 + dr + h, 1 + dc : 1 + dc + w] for dr, dc in _CIRC]
    count = np.sum(nb, axis=0)
    cross = np.zeros((h, w), dtype=np.int32)
    for i in range(8):
        cross += (~nb[i]) & nb[(i + 1) % 8]
    return count, cross


def _walk_components(mask: NDArray[np.bool_]) -> list[list[tuple[int, int]]]:
    """Walk each 8-connected piece of a junction-free skeleton into pixel chains."""
    h, w = mask.shape
    count, _ = _neighbour_tables(mask)
    visited = np.zeros_like(mask)
    chains: list[list[tuple[int, int]]] = []
    order4 = ((-1, 0), (0, 1), (1, 0), (0, -1), (-1, 1), (1, 1), (1, -1), (-1, -1))

    def walk(r0: int, c0: int) -> list[tuple[int, int]]:
        chain = [(r0, c0)]
        visited[r0, c0] = True
        r, c = r0, c0
        while True:
            nxt = None
            for dr, dc in order4:
                rr, cc = r + dr, c + dc
                if 0 <= rr < h and 0 <= cc < w and mask[rr, cc] and not visited[rr, cc]:
                    nxt = (rr, cc)
                    break
            if nxt is None:
                return chain
            r, c = nxt
            visited[r, c] = True
            chain.append(nxt)

    # open chains from endpoints first (pixels with at most one neighbour)
    ends = np.argwhere(mask & (count <= 1))
    for r, c in ends:
        if not visited[r, c]:
            chains.append(walk(int(r), int(c)))
    # whatever is left: loops (or leftovers of small side branches)
    for r, c in np.argwhere(mask):
        if not visited[r, c]:
            ch = walk(int(r), int(c))
            if len(ch) >= 4 and max(abs(ch[-1][0] - ch[0][0]), abs(ch[-1][1] - ch[0][1])) <= 1:
                # closed loop: cut at the pixel farthest from the start
                a = np.asarray(ch, dtype=np.float64)
                k = int(np.argmax(np.hypot(*(a - a[0]).T)))
                chains.append(ch[: k + 1])
                chains.append(ch[k:] + [ch[0]])
            else:
                chains.append(ch)
    return chains


def _split_sharp(pts: NDArray[np.float64], max_turn: float, window: float) -> list[NDArray]:
    """Cut a 1-px-resampled polyline at local maxima of the turning angle above ``max_turn``."""
    n = len(pts)
    w = max(1, int(round(window)))
    if n < 2 * w + 3:
        return [pts]
    idx = np.arange(w, n - w)
    d1 = pts[idx] - pts[idx - w]
    d2 = pts[idx + w] - pts[idx]
    a1 = np.arctan2(d1[:, 1], d1[:, 0])
    a2 = np.arctan2(d2[:, 1], d2[:, 0])
    turn = np.abs((a2 - a1 + np.pi) % (2 * np.pi) - np.pi)
    above = turn > max_turn
    if not above.any():
        return [pts]
    lab, nlab = ndimage.label(above)
    cuts = []
    for k in range(1, nlab + 1):
        sel = np.flatnonzero(lab == k)
        cuts.append(int(idx[sel[np.argmax(turn[sel])]]))
    pieces = []
    start = 0
    for c in cuts:
        pieces.append(pts[start : c + 1])
        start = c
    pieces.append(pts[start:])
    return pieces


def trace_contours_detailed(
    edges: ArrayLike,
    *,
    threshold: float = 0.15,
    low: float | None = None,
    min_length: float = 15.0,
    max_turn: float = np.deg2rad(60.0),
    turn_window: float = 5.0,
    smooth: float = 1.0,
) -> list[TracedContour]:
    """Trace contours and keep their 1-px polylines and mean strengths.

    Same parameters as :func:`trace_contours` (without the resampling ones).

    Returns
    -------
    list of TracedContour
        Sorted by decreasing ``length * strength``.
    """
    e = np.asarray(edges, dtype=np.float64)
    if e.ndim != 2 or e.size == 0:
        raise ImageError(f"edge map must be a non-empty 2-D array, got shape {e.shape}")
    if not np.all(np.isfinite(e)):
        raise ImageError("edge map contains NaN or infinite values")
    if not (0.0 <= threshold <= 1.0):
        raise ShapeTreeError(f"threshold must be in [0, 1], got {threshold}")
    lo = threshold / 2.5 if low is None else float(low)
    if lo > threshold:
        raise ShapeTreeError(f"low ({lo}) must not exceed threshold ({threshold})")
    if min_length < 0 or max_turn <= 0 or turn_window <= 0:
        raise ShapeTreeError("min_length must be >= 0, max_turn and turn_window > 0")
    from skimage.filters import apply_hysteresis_threshold
    from skimage.morphology import skeletonize

    strong = apply_hysteresis_threshold(e, max(lo, 1e-12), max(threshold, 1e-12))
    if not strong.any():
        return []
    skel = skeletonize(strong)
    _, cross = _neighbour_tables(skel)
    junction = skel & (cross >= 3)
    body = skel & ~junction
    chains = _walk_components(body)
    h, w = e.shape
    out: list[TracedContour] = []
    for ch in chains:
        # attach a touching junction pixel to each end
        ends = []
        for end in (ch[0], ch[-1]):
            r, c = end
            found = None
            for dr, dc in _CIRC:
                rr, cc = r + dr, c + dc
                if 0 <= rr < h and 0 <= cc < w and junction[rr, cc]:
                    found = (rr, cc)
                    if dr == 0 or dc == 0:
                        break
            ends.append(found)
        pix = list(ch)
        if ends[0] is not None:
            pix.insert(0, ends[0])
        if ends[1] is not None and (len(ch) > 1 or ends[1] != ends[0]):
            pix.append(ends[1])
        if len(pix) < 2:
            continue
        a = np.asarray(pix, dtype=np.float64)
        strength = float(np.mean(e[a[:, 0].astype(int), a[:, 1].astype(int)]))
        xy = a[:, ::-1].copy()  # (x=col, y=row)
        if smooth > 0 and len(xy) >= 5:
            sm = ndimage.gaussian_filter1d(xy, smooth, axis=0, mode="nearest")
            sm[0], sm[-1] = xy[0], xy[-1]
            xy = sm
        length = polyline_length(xy)
        if length < max(min_length, 1.0):
            continue
        dense = resample(xy, max(2, int(np.ceil(length)) + 1), closed=False)
        parts = [dense]
        if np.hypot(*(dense[-1] - dense[0])) < 1.5 and len(dense) >= 4:
            # a loop closed through a junction pixel: cut at the farthest point
            k = int(np.argmax(np.hypot(*(dense - dense[0]).T)))
            parts = [dense[: k + 1], dense[k:]]
        for part in parts:
            for piece in _split_sharp(part, max_turn, turn_window):
                if polyline_length(piece) >= max(min_length, 1.0):
                    out.append(TracedContour(points=piece, strength=strength))
    out.sort(key=lambda t: -polyline_length(t.points) * t.strength)
    return out


def trace_contours(
    edges: ArrayLike,
    *,
    threshold: float = 0.15,
    low: float | None = None,
    min_length: float = 15.0,
    max_turn: float = np.deg2rad(60.0),
    turn_window: float = 5.0,
    smooth: float = 1.0,
    spacing: float = 5.0,
    n_points: int | None = None,
) -> list[NDArray[np.float64]]:
    """Link edge pixels into long smooth open contours.

    Parameters
    ----------
    edges : array_like, shape (H, W)
        Soft edge map with values in ``[0, 1]`` (e.g. :func:`edge_map` or
        :func:`load_edges`).
    threshold : float
        High hysteresis threshold on edge strength (default 0.15): a contour
        must contain at least one pixel at least this strong.
    low : float or None
        Low hysteresis threshold; pixels weaker than this are never used
        (default ``threshold / 2.5``).
    min_length : float
        Contours shorter than this many pixels (arclength) are dropped
        (default 15).
    max_turn : float
        Radians; chains are cut where the turning angle between the chords of
        length ``turn_window`` before and after a point exceeds this
        (default 60 degrees).
    turn_window : float
        Chord length in pixels used to measure the turning angle (default 5).
    smooth : float
        Gaussian smoothing (pixels along the chain) of the pixel coordinates
        before measuring turns and resampling; 0 disables (default 1).
    spacing : float
        Target distance in pixels between consecutive output points
        (default 5); ignored when ``n_points`` is given.
    n_points : int or None
        If given, every contour is resampled to exactly this many points.

    Returns
    -------
    list of ndarray, each shape (k, 2), float64
        Open polylines ``(x=col, y=row)`` in pixel units, uniformly spaced in
        arclength, sorted by decreasing ``length * mean strength``.
        Junctions and sharp turns are contour ends, so two contours meeting
        at a junction share (up to a pixel) an endpoint.

    Raises
    ------
    ImageError
        If ``edges`` is not a finite 2-D array.
    ShapeTreeError
        If a parameter is out of range.
    """
    if n_points is not None and n_points < 2:
        raise ShapeTreeError(f"n_points must be >= 2, got {n_points}")
    if n_points is None and not spacing > 0:
        raise ShapeTreeError(f"spacing must be > 0, got {spacing}")
    traced = trace_contours_detailed(
        edges,
        threshold=threshold,
        low=low,
        min_length=min_length,
        max_turn=max_turn,
        turn_window=turn_window,
        smooth=smooth,
    )
    out = []
    for t in traced:
        length = polyline_length(t.points)
        n = n_points if n_points is not None else max(2, int(round(length / spacing)) + 1)
        out.append(resample(t.points, n, closed=False))
    return out
