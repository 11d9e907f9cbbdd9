"""Soft edge maps: the project's detectors and the ETHZ Pb-map loader.

The paper (§4) used the Berkeley Pb boundary detector.  For ETHZ the dataset
ships Pb maps (``*_edges.tif``), read with :func:`load_edges`.  For any other
image :func:`edge_map` computes a project-made substitute: by default
(``method="own"``) a boundary detector on Pb's own cues, see
:mod:`shapetree.detection._boundary`; with ``method="gradient"`` the older
multi-scale colour gradient:

1. convert RGB to CIE-Lab (greyscale images use their single channel, scaled
   to the L range 0..100);
2. at each scale ``sigma`` compute Gaussian-derivative gradients of every
   channel, scale-normalised (multiplied by ``sigma``) so scales compare;
3. keep, per pixel, the channel and scale with the largest magnitude
   (``max`` over channels, then over scales) and its gradient direction;
4. thin with non-maximum suppression across the gradient direction
   (bilinear interpolation of the two neighbours at distance 1 px);
5. normalise: divide by the ``norm_percentile`` percentile of the surviving
   (non-zero) magnitudes and clip to ``[0, 1]``; values below
   ``floor`` (after normalisation) are set to 0.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

from shapetree._errors import ImageError

__all__ = ["EDGE_METHODS", "WEIGHTED_METHODS", "edge_map", "load_edges", "load_image"]

#: Edge detectors of :func:`edge_map`: ``"own"`` (Pb's cues, :mod:`._boundary`, the
#: default), ``"gradient"`` (the multi-scale Lab gradient, kept for comparison) and
#: ``"pidinet"`` (a learned detector, :mod:`._pidinet`, whose weights the user points to).
EDGE_METHODS = ("own", "gradient", "pidinet")
#: The methods that need a weights file (``weights=`` / ``DetectParams.edge_weights``).
WEIGHTED_METHODS = ("pidinet",)


def load_image(path: str | os.PathLike[str]) -> NDArray[np.float64]:
    """Read an image file as float RGB in ``[0, 1]``.

    Parameters
    ----------
    path : path-like
        Any format Pillow reads.

    Returns
    -------
    ndarray, shape (H, W, 3), float64
        RGB values in ``[0, 1]``; greyscale files are replicated to 3 channels.

    Raises
    ------
    ImageError
        If the file is missing or unreadable, larger than
        :func:`shapetree.curves._image.max_image_pixels`, or the image is empty or
        smaller than 3x3 pixels.
    """
    from PIL import UnidentifiedImageError

    from shapetree.curves._image import open_image

    p = Path(path)
    try:
        with open_image(p) as im:
            arr = np.asarray(im.convert("RGB"), dtype=np.float64) / 255.0
    except FileNotFoundError as exc:
        raise ImageError(f"image file not found: {p}") from exc
    except (UnidentifiedImageError, OSError) as exc:
        raise ImageError(f"cannot read image {p}: {exc}") from exc
    if arr.size == 0:
        raise ImageError(f"image {p} is empty")
    if min(arr.shape[:2]) < 3:
        raise ImageError(
            f"image {p} is {arr.shape[1]}x{arr.shape[0]} pixels; at least 3x3 are needed"
        )
    return arr


def load_edges(path: str | os.PathLike[str]) -> NDArray[np.float64]:
    """Read a stored soft edge map (e.g. an ETHZ ``*_edges.tif`` Pb map).

    Parameters
    ----------
    path : path-like
        8-bit (or 16-bit / float) single-channel image; colour files are
        converted to greyscale.

    Returns
    -------
    ndarray, shape (H, W), float64
        Edge strength in ``[0, 1]`` (8-bit values divided by 255, other
        integer types by their maximum value, float images clipped).

    Raises
    ------
    ImageError
        If the file is missing or unreadable, or larger than
        :func:`shapetree.curves._image.max_image_pixels`.
    """
    from PIL import UnidentifiedImageError

    from shapetree.curves._image import open_image

    p = Path(path)
    try:
        with open_image(p) as im:
            if im.mode not in ("L", "I", "I;16", "F", "1"):
                im = im.convert("L")
            arr = np.asarray(im)
    except FileNotFoundError as exc:
        raise ImageError(f"edge map file not found: {p}") from exc
    except (UnidentifiedImageError, OSError) as exc:
        raise ImageError(f"cannot read edge map {p}: {exc}") from exc
    if arr.ndim != 2 or arr.size == 0:
        raise ImageError(f"edge map {p} is not a non-empty 2-D image")
    if arr.dtype == np.bool_:
        out = arr.astype(np.float64)
    elif np.issubdtype(arr.dtype, np.integer):
        out = arr.astype(np.float64) / (255.0 if arr.dtype == np.uint8 else np.iinfo(arr.dtype).max)
    else:
        out = np.clip(np.nan_to_num(arr.astype(np.float64)), 0.0, 1.0)
    return np.clip(out, 0.0, 1.0)


def _as_unit(image: ArrayLike) -> NDArray[np.float64]:
    """Validate an image and scale it to ``[0, 1]``: (H, W) or (H, W, 1|3), alpha dropped."""
    arr = np.asarray(image)
    if arr.ndim not in (2, 3) or arr.size == 0 or min(arr.shape[:2]) < 3:
        raise ImageError(
            f"image must be a non-empty (H, W) or (H, W, 3|4) array of at least 3x3, "
            f"got shape {arr.shape}"
        )
    if np.issubdtype(arr.dtype, np.integer):
        arr = arr.astype(np.float64) / (255.0 if arr.max(initial=0) <= 255 else 65535.0)
    elif arr.dtype == np.bool_:
        arr = arr.astype(np.float64)
    else:
        arr = arr.astype(np.float64)
        if not np.all(np.isfinite(arr)):
            raise ImageError("image contains NaN or infinite values")
        if arr.max(initial=0.0) > 1.0 + 1e-9:
            arr = arr / 255.0
    arr = np.clip(arr, 0.0, 1.0)
    if arr.ndim == 3 and arr.shape[2] == 4:
        arr = arr[:, :, :3]
    if arr.ndim == 3 and arr.shape[2] not in (1, 3):
        raise ImageError(f"image must have 1, 3 or 4 channels, got {arr.shape[2]}")
    return arr


def _as_channels(image: ArrayLike) -> NDArray[np.float64]:
    """Convert an image to float Lab channels, shape (H, W, C)."""
    arr = _as_unit(image)
    if arr.ndim == 2:
        return (arr * 100.0)[:, :, None]
    if arr.shape[2] == 1:
        return arr * 100.0
    from skimage.color import rgb2lab

    return rgb2lab(arr)


def _nms(mag: NDArray[np.float64], gx: NDArray[np.float64], gy: NDArray[np.float64]) -> NDArray:
    """Non-maximum suppression of ``mag`` across the direction ``(gx, gy)``."""
    h, w = mag.shape
    norm = np.hypot(gx, gy)
    norm[norm == 0] = 1.0
    ux, uy = gx / norm, gy / norm
    rr, cc = np.mgrid[0:h, 0:w].astype(np.float64)
    padded = np.pad(mag, 1, mode="edge")
    out = mag.copy()
    for sgn in (1.0, -1.0):
        r = rr + sgn * uy + 1.0
        c = cc + sgn * ux + 1.0
        nb = ndimage.map_coordinates(padded, [r, c], order=1, mode="nearest")
        out[mag < nb] = 0.0
    return out


def edge_map(
    image: ArrayLike,
    *,
    method: str = "own",
    sigmas: tuple[float, ...] = (1.0, 2.0, 4.0),
    thin: bool = True,
    norm_percentile: float = 99.0,
    floor: float = 0.02,
    weights: str | os.PathLike[str] | None = None,
) -> NDArray[np.float64]:
    """Soft edge strength map of an image: Pb-style boundary cues, or a Lab gradient.

    Parameters
    ----------
    image : array_like, shape (H, W) or (H, W, 3|4)
        Greyscale or RGB(A) image; integer types are scaled by 255 (or 65535),
        floats are taken in ``[0, 1]`` (or ``[0, 255]`` when the maximum
        exceeds 1).
    method : {"own", "gradient", "pidinet"}
        ``"own"`` (default): the project's boundary detector on Pb's cues,
        χ² differences of brightness, colour and texton histograms between
        half-discs at every orientation and two scales, combined with fixed
        weights and thinned (see :mod:`shapetree.detection._boundary`); it
        tells texture (water ripples, foliage) from object boundaries.
        ``"gradient"``: the multi-scale Lab gradient magnitude below (fast,
        but texture gives strong edges).  ``"pidinet"``: the learned PiDiNet
        detector (Su et al., ICCV 2021) run with NumPy from the weights file
        ``weights`` points to, thinned and put on the Pb scale (see
        :mod:`shapetree.detection._pidinet`).  For ETHZ the shipped Pb maps are
        read with :func:`load_edges`.
    sigmas : tuple of float
        ``"gradient"`` only: Gaussian scales in pixels (default 1, 2, 4).
        Magnitudes are multiplied by ``sigma`` (scale normalisation) before
        taking the max.
    thin : bool
        Apply non-maximum suppression across the gradient direction so edges
        are about one pixel wide (default True).
    norm_percentile : float
        ``"gradient"`` only: magnitudes are divided by this percentile (0..100)
        of the non-zero magnitudes, then clipped to 1 (default 99).  The
        ``"own"`` map has a fixed scale instead (no per-image normalisation).
    floor : float
        Normalised values below this are set to 0 (default 0.02).
    weights : path-like or None
        ``"pidinet"`` only (required there): a ``table5_*.npz`` PiDiNet weights file.
        The weights are the authors' (``hellozhuo/pidinet``), for research use only,
        and not shipped with shapetree.

    Returns
    -------
    ndarray, shape (H, W), float64
        Edge strength in ``[0, 1]``.  A constant image gives all zeros.

    Raises
    ------
    ImageError
        If the image has a bad shape or non-finite values.
    ShapeTreeError
        If ``method`` is unknown, ``sigmas`` is empty / non-positive, or the
        ``"pidinet"`` weights are missing, unreadable or not PiDiNet's.
    """
    from shapetree._errors import ShapeTreeError

    if method not in EDGE_METHODS:
        raise ShapeTreeError(f"unknown edge method {method!r}; choose one of {EDGE_METHODS}")
    if len(sigmas) == 0 or any(not (s > 0) for s in sigmas):
        raise ShapeTreeError(f"sigmas must be positive, got {sigmas!r}")
    if method == "pidinet":
        from ._pidinet import pidinet_edges

        return pidinet_edges(image, weights, thin=thin, floor=floor)
    if weights is not None:
        raise ShapeTreeError(f"weights= is for edge method 'pidinet', not {method!r}")
    chans = _as_channels(image)
    if method == "own":
        from ._boundary import boundary_map

        return boundary_map(chans, thin=thin, floor=floor)
    h, w, nc = chans.shape
    best = np.zeros((h, w))
    bgx = np.zeros((h, w))
    bgy = np.zeros((h, w))
    for s in sigmas:
        for c in range(nc):
            ch = chans[:, :, c]
            gx = ndimage.gaussian_filter(ch, s, order=(0, 1), mode="nearest") * s
            gy = ndimage.gaussian_filter(ch, s, order=(1, 0), mode="nearest") * s
            mag = np.hypot(gx, gy)
            upd = mag > best
            best[upd] = mag[upd]
            bgx[upd] = gx[upd]
            bgy[upd] = gy[upd]
    if thin:
        best = _nms(best, bgx, bgy)
    nz = best[best > 1e-9]
    if nz.size == 0:
        return np.zeros((h, w))
    scale = float(np.percentile(nz, norm_percentile))
    if scale <= 1e-9:
        return np.zeros((h, w))
    out = np.clip(best / scale, 0.0, 1.0)
    out[out < floor] = 0.0
    return out
