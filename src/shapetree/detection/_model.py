"""Detection models: curves from outline drawings or point files, sampled for stitching."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

from shapetree._errors import CurveError, ImageError, ShapeTreeError
from shapetree.curves._validate import _as_xy

__all__ = [
    "DetectionModel",
    "chain_strokes",
    "load_model",
    "make_model",
    "outline_from_image",
    "outline_strokes",
]

_IMAGE_EXT = {".png", ".tif", ".tiff", ".pgm", ".pbm", ".bmp", ".jpg", ".jpeg", ".gif", ".ppm"}


@dataclass(frozen=True)
class DetectionModel:
    """A model curve prepared for detection.

    Attributes
    ----------
    curve : ndarray, shape (n, 2)
        The model curve as given (``x, y``), without a repeated end point.
    closed : bool
        Whether the given curve is closed.  An open curve is closed with its
        end-to-start chord, on which gaps are free.
    points : ndarray, shape (m, 2)
        Closed curve (chord included for open models) resampled uniformly in
        arclength to ``m`` points: the stitching / table samples.
    gap_weight : ndarray, shape (m,)
        Gap cost weight of segment ``i`` (from ``points[i]`` to
        ``points[(i+1) % m]``): its share of the real curve's length (0 for
        segments on the artificial chord); sums to 1.
    name : str
        Label (file stem).
    """

    curve: NDArray[np.float64]
    closed: bool
    points: NDArray[np.float64]
    gap_weight: NDArray[np.float64]
    name: str = "model"


def _read_grey(path: Path) -> NDArray[np.float64]:
    """A model drawing as grey levels; the pixel limit of ``curves._image`` applies."""
    from PIL import UnidentifiedImageError

    from shapetree.curves._image import open_image

    try:
        with open_image(path) as im:
            return np.asarray(im.convert("L"), dtype=np.float64)
    except FileNotFoundError as exc:
        raise ImageError(f"model image not found: {path}") from exc
    except (UnidentifiedImageError, OSError) as exc:
        raise ImageError(f"cannot read model image {path}: {exc}") from exc


def outline_from_image(
    image: ArrayLike | str | os.PathLike[str], *, name: str = "model image"
) -> tuple[NDArray[np.float64], bool]:
    """Trace a drawn 1-px outline (dark on light, or light on dark) into a curve.

    The largest 8-connected group of ink pixels is used.  If filling its holes
    adds area, the outline is closed and the outer boundary of the filled
    region is returned (sub-pixel, from marching squares); otherwise the
    outline is open (e.g. the ETHZ giraffe) and the longest path through its
    skeleton is returned, end to end.

    Parameters
    ----------
    image : array_like, shape (H, W), or path-like
        Outline drawing (bool, or grey values; ink is the minority colour).
    name : str
        Used in error messages.

    Returns
    -------
    points : ndarray, shape (n, 2), float64
        ``(x=col, y=row)`` in pixels.  A closed curve is counter-clockwise in
        ``(x, y)`` (positive shoelace area) and does not repeat its first point.
    closed : bool

    Raises
    ------
    ImageError
        If the drawing cannot be read, has more pixels than
        :func:`shapetree.curves._image.max_image_pixels` allows (checked before
        decoding), has no ink, or the outline is too small.
    """
    comps, name = _ink_components(image, name)
    comp = comps[0]
    if comp.sum() < 8:
        raise ImageError(f"{name}: outline is too small ({int(comp.sum())} pixels)")
    filled = ndimage.binary_fill_holes(comp)
    if filled.sum() > comp.sum() * 1.2 + 10:
        from skimage.measure import find_contours

        padded = np.pad(filled.astype(np.float64), 1)
        cs = find_contours(padded, 0.5)
        c = max(cs, key=len)
        pts = c[:, ::-1] - 1.0  # (row, col) -> (x, y), undo padding
        if np.allclose(pts[0], pts[-1]):
            pts = pts[:-1]
        x, y = pts[:, 0], pts[:, 1]
        area = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
        if area < 0:
            pts = pts[::-1]
        return np.ascontiguousarray(pts), True
    return _skeleton_path(comp), False


def _skeleton_path(comp: NDArray[np.bool_]) -> NDArray[np.float64]:
    """Longest geodesic path through the skeleton of one open stroke, ``(x, y)``, smoothed."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_order, dijkstra
    from skimage.morphology import skeletonize

    sk = skeletonize(comp)
    rc = np.argwhere(sk)
    index = -np.ones(sk.shape, np.int64)
    index[rc[:, 0], rc[:, 1]] = np.arange(len(rc))
    rows, cols, wts = [], [], []
    h, w = sk.shape
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
        r2, c2 = rc[:, 0] + dr, rc[:, 1] + dc
        ok = (r2 >= 0) & (r2 < h) & (c2 >= 0) & (c2 < w)
        j = np.full(len(rc), -1)
        j[ok] = index[r2[ok], c2[ok]]
        sel = j >= 0
        rows.append(np.flatnonzero(sel))
        cols.append(j[sel])
        wts.append(np.full(sel.sum(), np.hypot(dr, dc)))
    g = coo_matrix(
        (np.concatenate(wts), (np.concatenate(rows), np.concatenate(cols))),
        shape=(len(rc), len(rc)),
    ).tocsr()
    g = g + g.T
    order = breadth_first_order(g, 0, directed=False, return_predecessors=False)
    d0 = dijkstra(g, indices=int(order[0]))
    d0[~np.isfinite(d0)] = -1
    s = int(np.argmax(d0))
    ds, pred = dijkstra(g, indices=s, return_predecessors=True)
    ds[~np.isfinite(ds)] = -1
    t = int(np.argmax(ds))
    path = [t]
    while path[-1] != s:
        path.append(int(pred[path[-1]]))
    pts = rc[np.asarray(path[::-1])][:, ::-1].astype(np.float64)
    from scipy.ndimage import gaussian_filter1d

    sm = gaussian_filter1d(pts, 1.0, axis=0, mode="nearest")
    sm[0], sm[-1] = pts[0], pts[-1]
    return np.ascontiguousarray(sm)


def _ink_components(image: ArrayLike | str | os.PathLike[str], name: str):
    """Ink mask components of a drawing, largest first (list of bool masks)."""
    if isinstance(image, (str, os.PathLike)):
        name = str(image)
        arr = _read_grey(Path(image))
    else:
        arr = np.asarray(image, dtype=np.float64)
    if arr.ndim == 3:
        arr = arr[..., :3].mean(axis=2)
    if arr.ndim != 2 or arr.size == 0:
        raise ImageError(f"{name}: model image must be a 2-D image")
    lo, hi = float(arr.min()), float(arr.max())
    if hi - lo <= 0:
        raise ImageError(f"{name}: model image is blank")
    dark = arr < (lo + hi) / 2
    ink = dark if dark.sum() <= (~dark).sum() else ~dark
    lab, n = ndimage.label(ink, structure=np.ones((3, 3)))
    if n == 0:
        raise ImageError(f"{name}: model image has no outline pixels")
    sizes = ndimage.sum(np.ones_like(lab), lab, index=np.arange(1, n + 1))
    order = np.argsort(-sizes, kind="stable")
    return [lab == (1 + int(i)) for i in order], name


def outline_strokes(
    image: ArrayLike | str | os.PathLike[str],
    *,
    name: str = "model image",
    min_share: float = 0.2,
) -> tuple[list[NDArray[np.float64]], bool]:
    """All strokes of an outline drawing: one closed outline, or several open strokes.

    If the largest ink component encloses area, its outer boundary is returned
    alone (as in :func:`outline_from_image`).  Otherwise the drawing is open
    (e.g. the ETHZ giraffe: the outer outline plus a separate stroke for the
    belly and inner legs) and every open ink component with at least
    ``min_share`` of the largest one's pixels is returned as a skeleton path,
    longest component first.

    Parameters
    ----------
    image : array_like, shape (H, W), or path-like
        Outline drawing (ink is the minority colour).
    name : str
        Used in error messages.
    min_share : float
        Smaller components (specks, text) are ignored (default 0.2).

    Returns
    -------
    strokes : list of ndarray, each shape (n_i, 2)
        ``(x, y)`` px.
    closed : bool
        True for a single closed outline.

    Raises
    ------
    ImageError
        As :func:`outline_from_image`.
    """
    main, closed = outline_from_image(image, name=name)
    if closed:
        return [main], True
    comps, name = _ink_components(image, name)
    strokes = [main]
    big = comps[0].sum()
    for comp in comps[1:]:
        if comp.sum() < max(8, min_share * big):
            break
        filled = ndimage.binary_fill_holes(comp)
        if filled.sum() > comp.sum() * 1.2 + 10:
            continue  # a closed blob beside an open outline: ignored
        strokes.append(_skeleton_path(comp))
    return strokes, False


def chain_strokes(
    strokes: list[NDArray[np.float64]],
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Join open strokes into one closed loop by short artificial chords.

    Starting from the first stroke, the stroke with the endpoint nearest to
    the current end is appended next (reversed if needed).

    Returns
    -------
    points : ndarray, shape (n, 2)
        The loop (no repeated first point).
    free : ndarray, shape (n,), bool
        ``free[i]`` is True when segment ``points[i] -> points[(i+1) % n]`` is
        an artificial chord (between strokes, or the closing one).
    """
    rest = [np.asarray(s, dtype=np.float64) for s in strokes[1:]]
    parts = [np.asarray(strokes[0], dtype=np.float64)]
    while rest:
        end = parts[-1][-1]
        d = [min(np.hypot(*(r[0] - end)), np.hypot(*(r[-1] - end))) for r in rest]
        r = rest.pop(int(np.argmin(d)))
        parts.append(r if np.hypot(*(r[0] - end)) <= np.hypot(*(r[-1] - end)) else r[::-1])
    pts = np.vstack(parts)
    free = np.zeros(len(pts), bool)
    free[np.cumsum([len(q) for q in parts]) - 1] = True
    return pts, free


def _resample_closed(pts: NDArray[np.float64], m: int) -> tuple[NDArray, NDArray]:
    """Uniform resampling of a closed polygon; also returns the sample arclength positions."""
    closed = np.vstack([pts, pts[:1]])
    seg = np.hypot(*np.diff(closed, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    t = np.linspace(0.0, cum[-1], m, endpoint=False)
    out = np.column_stack([np.interp(t, cum, closed[:, 0]), np.interp(t, cum, closed[:, 1])])
    return out, t


def make_model(
    curve: ArrayLike,
    *,
    closed: bool = True,
    m: int = 30,
    name: str = "model",
    free: ArrayLike | None = None,
) -> DetectionModel:
    """Prepare a model curve for detection.

    Parameters
    ----------
    curve : array_like, shape (n, 2)
        Model curve ``(x, y)`` (any units; only its shape matters), or any
        other form :func:`shapetree.curves.as_curve` accepts: an OpenCV contour
        ``(n, 1, 2)``, a shapely ``Polygon`` (its exterior) or ``LinearRing``
        (without the repeated closing point), a ``LineString``.  Points are
        kept as given (duplicates too, so ``free`` lines up with them).
    closed : bool
        Whether the curve is closed.  An open curve is closed by the chord from
        its last point back to its first, and gaps on that chord cost nothing.
        ``False`` refuses rings (a ``Polygon`` or ``LinearRing`` is closed).
    m : int
        Number of samples for the contour tables and stitching (default 30).
    name : str
        Label.
    free : array_like of bool, shape (n,), or None
        Artificial segments: ``free[i]`` marks the segment from point ``i``
        to point ``i + 1`` (the last one: back to point 0) as not part of the
        drawing (e.g. chords joining strokes, see :func:`chain_strokes`); gaps
        there cost nothing.  The closing chord of an open curve is always free.

    Returns
    -------
    DetectionModel

    Raises
    ------
    ShapeTreeError
        If the curve is none of the accepted forms (a :class:`~shapetree.CurveError`
        listing them), holds NaN/inf, has fewer than 3 points or zero length,
        or ``m < 6``.
    """
    pts = _as_xy(curve, f"{name}: model curve", closed=closed)
    if len(pts) < 3:
        raise CurveError(f"{name}: model curve needs at least 3 points, got {len(pts)}")
    if m < 6:
        raise ShapeTreeError(f"m must be >= 6, got {m}")
    fr = np.zeros(len(pts), bool) if free is None else np.asarray(free, dtype=bool).copy()
    if fr.shape != (len(pts),):
        raise ShapeTreeError(f"{name}: free must have one flag per curve point")
    if closed and np.allclose(pts[0], pts[-1]):
        pts, fr = pts[:-1], fr[:-1]
    if not closed:
        fr[-1] = True
    seg = np.hypot(*np.diff(np.vstack([pts, pts[:1]]), axis=0).T)
    total = seg.sum()
    real = np.where(fr, 0.0, seg)
    if total <= 0 or real.sum() <= 0:
        raise ShapeTreeError(f"{name}: model curve has zero length")
    samples, t = _resample_closed(pts, m)
    # share of each sample segment [t_i, t_i+1] that lies on the real (drawn) part
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    rcum = np.concatenate([[0.0], np.cumsum(real)])
    r_at = np.interp(np.append(t, total), cum, rcum)
    gw = np.diff(r_at) / rcum[-1]
    return DetectionModel(
        curve=pts, closed=bool(closed), points=samples, gap_weight=gw / gw.sum(), name=name
    )


def load_model(
    source: str | os.PathLike[str] | ArrayLike,
    *,
    m: int = 30,
    closed: bool | None = None,
    all_strokes: bool = False,
) -> DetectionModel:
    """Load a detection model from an outline drawing, a point file or an array.

    Parameters
    ----------
    source : path-like or array_like, shape (n, 2)
        An image file (``.png``, ``.tif``, ``.pgm``, ...) holding a drawn
        outline or a filled silhouette (see :func:`outline_from_image` and
        ``all_strokes``), an SVG file (the first ``<path>``, ``<polygon>`` or
        ``<polyline>``; see :mod:`shapetree.detection._svg`), a point
        file readable by :func:`shapetree.curves.load_points`, or the points
        themselves, in any form :func:`make_model` accepts (an OpenCV contour
        ``(n, 1, 2)``, a shapely ``Polygon``, ...).
    m : int
        Number of stitching samples (default 30).
    closed : bool or None
        Override closedness (default: detected for drawings, True otherwise).
    all_strokes : bool
        For an open drawing made of several strokes (like the ETHZ giraffe:
        outer outline + a belly / inner-legs stroke), keep all of them, joined
        by free chords (see :func:`outline_strokes`, :func:`chain_strokes`).
        Default False: the longest stroke only, closed by a free chord (on
        the ETHZ giraffes the extra stroke lowered the detection rate).

    Returns
    -------
    DetectionModel
    """
    if isinstance(source, DetectionModel):
        return source
    if isinstance(source, (str, os.PathLike)):
        p = Path(source)
        if p.suffix.lower() == ".svg":
            from ._svg import read_svg_outline

            pts, is_closed = read_svg_outline(p)
        elif p.suffix.lower() in _IMAGE_EXT:
            strokes, is_closed = outline_strokes(p)
            if all_strokes and len(strokes) > 1 and closed is not True:
                pts, free = chain_strokes(strokes)
                return make_model(pts, closed=False, m=m, name=p.stem, free=free)
            pts = strokes[0]
        else:
            from shapetree.curves import load_points

            pts, is_closed = np.asarray(load_points(p), dtype=np.float64), True
        name = p.stem
    else:
        pts, is_closed, name = source, True, "model"  # read by make_model
    if closed is not None:
        is_closed = bool(closed)
    return make_model(pts, closed=is_closed, m=m, name=name)
