"""Appearance consistency across a collection: one model searched over many photos.

Every term of the ranking score (:class:`~shapetree.detection.DetectParams`) judges a
detection by its own image alone, so a stitched outline on a tree trunk and one on a
giraffe can score alike. Across a collection searched with one model, though, the
detections the detector is surest of are mostly the object, and the object tends to look
alike from photo to photo (a giraffe's coat, a swan's white, a bottle's glass). This
module measures that, as the *appearance agreement* of each detection:

1. :func:`interior_histogram`: the colour histogram of the pixels inside the outline the
   detection places in the image, farther than ``margin`` (2 px) from it, over
   :func:`colour_bins` (CIE Lab, 8 x 8 x 8 bins; L in [0, 100], a and b in [-60, 60],
   the ends clipped).
2. The *reference set*: the best detection of each image by its own ranking score, the
   ``reference`` (10) best of them over the collection. Which detections are confident is
   the detector's own call; no label is used.
3. :func:`appearance_agreement`: the mean histogram intersection (in ``[0, 1]``) of a
   detection with the reference set, less any member from the detection's own image.

:func:`collection_scores` adds ``appearance_check * agreement`` to each detection's own
score. That is a transductive re-ranking: a detection's collection score depends on the
other photos of the collection (never on their labels), while its own ``score`` does not,
so the same image and model always give the same ``score``. Where fewer than two images
have a detection there is nothing to compare with and the collection score is the score.

On ETHZ (``benchmarks/ethz_appearance.py``) the colour agreement, paired with the shape
context and both weights chosen on four classes and scored on the fifth, picked the
weight 0.4 in score units (0.25 score standard deviations per standard deviation of the
agreement, beside the context's 0.25) in four of the five folds of the Pb detections.
Alone it is off by default (``appearance_check = 0``): with the project's own edge map it
did not win. The agreement is one of the terms of the collection re-scorer
(:mod:`shapetree.detection._rescore`), which is on by default.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence

import numpy as np
from numpy.typing import ArrayLike
from scipy import ndimage

from shapetree._errors import ShapeTreeError

#: number of colour bins of :func:`colour_bins` (8 per Lab channel)
N_COLOURS = 512


def colour_bins(image: ArrayLike) -> np.ndarray:
    """The Lab colour bin of every pixel.

    Parameters
    ----------
    image : array_like, shape (H, W) or (H, W, 3|4)
        Grey or RGB(A) image, floats in [0, 1].

    Returns
    -------
    ndarray of int, shape (H, W)
        ``(L_bin * 8 + a_bin) * 8 + b_bin`` in ``[0, 512)``: 8 bins of L* over [0, 100]
        and of a*, b* over [-60, 60] each (values beyond clipped to the end bins).
    """
    from skimage.color import rgb2lab

    img = np.asarray(image, dtype=np.float64)
    if img.ndim == 2:
        img = np.stack([img] * 3, -1)
    if img.ndim != 3 or img.shape[2] < 3:
        raise ShapeTreeError(f"colour_bins needs an (H, W) or (H, W, 3) image, got {img.shape}")
    lab = rgb2lab(np.clip(img[..., :3], 0.0, 1.0))
    q = [
        np.clip((lab[..., 0] / 100 * 8).astype(int), 0, 7),
        np.clip(((lab[..., 1] + 60) / 120 * 8).astype(int), 0, 7),
        np.clip(((lab[..., 2] + 60) / 120 * 8).astype(int), 0, 7),
    ]
    return (q[0] * 8 + q[1]) * 8 + q[2]


def histogram(bins: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Normalised histogram (sums to 1; all zeros for an empty mask) of ``bins[mask]``."""
    h = np.bincount(bins[mask], minlength=N_COLOURS).astype(np.float64)
    return h / max(h.sum(), 1.0)


def interior_mask(shape: tuple[int, int], points: ArrayLike, margin: float = 2.0) -> np.ndarray:
    """The pixels inside a placed outline, farther than ``margin`` from it.

    Parameters
    ----------
    shape : (int, int)
        Image height and width (px).
    points : array_like, shape (m, 2)
        The outline in px, ``(x, y)`` (a detection's ``image_points``), closed implicitly.
    margin : float
        Pixels within this distance of the outline are left out (2 px), so the edge
        itself and what lies just outside it do not count. When fewer than 10 pixels
        remain the whole interior is used.

    Returns
    -------
    ndarray of bool, shape (H, W)
        All False when the outline encloses no pixel of the image.
    """
    from skimage.draw import polygon as draw_polygon

    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 3:
        raise ShapeTreeError(f"an outline needs (m >= 3, 2) points, got {pts.shape}")
    if not np.isfinite(pts).all():
        raise ShapeTreeError("the outline has NaN or infinite points")
    h, w = shape
    rr, cc = draw_polygon(pts[:, 1], pts[:, 0], shape=(h, w))
    fig = np.zeros((h, w), bool)
    fig[rr, cc] = True
    core = ndimage.distance_transform_edt(fig) > margin
    return core if core.sum() >= 10 else fig


def interior_histogram(bins: np.ndarray, points: ArrayLike, margin: float = 2.0) -> np.ndarray:
    """Colour histogram of the pixels inside a placed outline (:func:`interior_mask`).

    Parameters
    ----------
    bins : ndarray of int, shape (H, W)
        :func:`colour_bins` of the image.
    points : array_like, shape (m, 2)
        The outline in px, ``(x, y)`` (a detection's ``image_points``), closed implicitly.
    margin : float
        See :func:`interior_mask` (2 px).

    Returns
    -------
    ndarray, shape (512,)
        Normalised histogram; all zeros when the outline encloses no pixel of the image.
    """
    return histogram(bins, interior_mask(bins.shape, points, margin))


def appearance_agreement(
    image_keys: Sequence[Hashable],
    scores: ArrayLike,
    histograms: ArrayLike,
    reference: int = 10,
) -> np.ndarray:
    """Mean histogram intersection of each detection with the collection's reference set.

    Parameters
    ----------
    image_keys : sequence, length N
        The image of each detection (any hashable: a path, a name).
    scores : array_like, shape (N,)
        Each detection's own ranking score (higher is better).
    histograms : array_like, shape (N, B)
        Each detection's normalised interior histogram (:func:`interior_histogram`).
    reference : int
        Size of the reference set (10): the best detection of each image, the
        ``reference`` best of those by score.

    Returns
    -------
    ndarray, shape (N,)
        In ``[0, 1]``: the mean of ``sum(min(h_i, h_r))`` over the reference members
        ``r`` not from detection ``i``'s image (the ``reference`` best of them); 0 where
        no other image has a detection.
    """
    keys = list(image_keys)
    s = np.asarray(scores, dtype=np.float64)
    hist = np.asarray(histograms, dtype=np.float64)
    n = len(keys)
    if s.shape != (n,) or hist.ndim != 2 or len(hist) != n:
        raise ShapeTreeError(
            f"appearance_agreement: {n} image keys, scores of shape {s.shape} and "
            f"histograms of shape {hist.shape} do not match"
        )
    if isinstance(reference, bool) or not isinstance(reference, int) or reference < 1:
        raise ShapeTreeError(f"reference must be an integer >= 1, got {reference!r}")
    if not np.isfinite(s).all() or not np.isfinite(hist).all():
        raise ShapeTreeError("appearance_agreement: NaN or infinite scores or histograms")
    best: dict[Hashable, int] = {}
    for i, k in enumerate(keys):
        if k not in best or s[i] > s[best[k]]:
            best[k] = i
    # one spare member, so that leaving out a detection's own image still leaves `reference`
    ref = sorted(best.values(), key=lambda i: -s[i])[: reference + 1]
    out = np.zeros(n)
    for i, k in enumerate(keys):
        others = [r for r in ref if keys[r] != k][:reference]
        if others:
            out[i] = float(np.minimum(hist[i][None, :], hist[others]).sum(1).mean())
    return out


def collection_scores(
    image_keys: Sequence[Hashable],
    scores: ArrayLike,
    histograms: ArrayLike,
    appearance_check: float,
    reference: int = 10,
) -> tuple[np.ndarray, np.ndarray]:
    """``score + appearance_check * agreement`` of every detection of a collection.

    Parameters are those of :func:`appearance_agreement`, plus the weight
    ``appearance_check`` (>= 0; :class:`~shapetree.detection.DetectParams`).

    Returns
    -------
    collection_score, agreement : ndarray, shape (N,)
        Where fewer than two images have a detection the agreement is 0 and the
        collection score is the score.
    """
    if not (np.isfinite(appearance_check) and appearance_check >= 0):
        raise ShapeTreeError(
            f"appearance_check must be a finite number >= 0, got {appearance_check}"
        )
    s = np.asarray(scores, dtype=np.float64)
    a = appearance_agreement(image_keys, s, histograms, reference)
    return s + appearance_check * a, a
