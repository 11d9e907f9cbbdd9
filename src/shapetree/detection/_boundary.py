"""The project's own soft boundary detector on Pb's cues (``edge_map(method="own")``).

Martin, Fowlkes & Malik's Pb (PAMI 2004) tells a boundary from texture by comparing the
*distributions* of brightness, colour and texture on the two halves of a disc centred on
each pixel: inside a texture both halves hold the same mixture, so the difference is
small however strong the local gradient; across a boundary they differ.  This module
computes those cues with NumPy / SciPy / scikit-image only, no learned weights:

1. **Channels.** CIE-Lab ``L``, ``a``, ``b`` (greyscale images: ``L`` only), each soft-
   binned into ``N_COLOUR_BINS`` bins (linear interpolation between bin centres, so a
   smooth ramp does not make a step at a bin border); and a **texton** label per pixel:
   the responses of a small filter bank on ``L`` (Gaussian first and second derivatives
   at ``TEXTON_SIGMAS``, a centre-surround difference of Gaussians), contrast-normalised
   (``log(1 + |r| / 0.03) / |r|``, as Malik et al.), clustered into ``N_TEXTONS``
   textons by k-means (:func:`scipy.cluster.vq.kmeans2`, fixed seed, on a fixed-seed
   sample of pixels) and labelled by the nearest texton.
2. **Half-disc χ².** For a bin indicator image ``I_b`` and a Gaussian disc of scale
   ``σ``, ``S_b = G_σ * I_b`` is the disc's histogram and ``D_b(θ) = σ √(2π) (cos θ ∂x +
   sin θ ∂y)(G_σ * I_b)`` is the difference of its two half-disc histograms across the
   line of normal ``θ`` (the steerable first-order form of the half-disc difference:
   exactly 1 for a straight step between two pure bins through the centre, so the two
   halves' histograms are ``S_b ± D_b / 2``).  Their χ² distance is
   ``χ²(θ) = ½ Σ_b (g_b - h_b)² / (g_b + h_b) = Σ_b D_b(θ)² / (4 S_b)``, in ``[0, 1]``,
   which is a quadratic form ``a cos² θ + 2 b cos θ sin θ + c sin² θ`` in the orientation.
3. **Combination.** The forms of every channel and scale (``L`` at ``SCALES``, ``a`` and
   ``b`` at ``COLOUR_SCALES``, texture at ``TEXTURE_SCALES``) are added with the
   fixed weights ``WEIGHTS`` (Pb's "sum the oriented cues, then take the best
   orientation"); the maximum over *all* orientations is the form's largest eigenvalue,
   its normal the eigenvector (no sampling of 8 angles needed).
4. **Thinning and scale.** Non-maximum suppression across the normal (as the gradient
   method), then a fixed affine map to ``[0, 1]``: ``p = clip((E - E_OFFSET) / E_RANGE,
   0, 1)``, no per-image normalisation (a picture of texture does not get strong edges
   just because it has no boundary); values under ``floor`` set to 0.  The two constants
   were first set so that on 20 ETHZ images (4 per class) the share of pixels above 0.05,
   0.15, 0.3 and 0.5 is, in the median, the share of the shipped Pb maps (thinned
   energies 0.19, 0.26, 0.33, 0.46 there; 0.155 / 0.61), so the contour tracer's
   thresholds, chosen on Pb, mean the same on this map.  When every image came to be
   processed at ``WORK_SIDE`` (below; earlier, images were only reduced, never
   enlarged), they were carried over (``benchmarks/own_edge_calibration.py``): the new
   constants give the new energies the pixel shares the earlier ones gave the earlier
   energies on 20 ETHZ images, so the change of scale is the only change; when the
   colour cues moved from 2 and 4 px to ``COLOUR_SCALES`` they were carried over again
   the same way (0.1922 / 0.7069 to 0.1932 / 0.6955; the script, which carries from the
   matched energies rounded to 4 decimals, prints 0.6954).  The weights
   and scales were chosen (under the earlier scale rule) on 15 other ETHZ images by the
   F-measure (2 px tolerance) of the thresholded map against the Pb map (brightness
   alone 0.81, the gradient method 0.73, the weights below 0.84), with
   the texture weight kept high enough that a boundary between two textures of the
   same brightness histogram (vertical against horizontal stripes) is an edge; no
   ground-truth boxes were used.  The colour cues' scales were later moved from 2 and 4
   px to 4 and 8 px (nearer Pb's colour disc, twice its brightness disc) by the same
   criterion: among 11 colour weightings, the best F-measure against Pb on 20 other ETHZ
   images (0.858 to 0.864) that keeps the texture-only cap above 0.2
   (``benchmarks/own_edge_colour.py``).  A boundary that only one cue sees is capped by
   that cue's weight: at most ``(w - E_OFFSET) / E_RANGE``, i.e. 0.30 for brightness
   alone in a colour image (0.73 in a greyscale one, where ``L`` carries the colour
   weights too),
   0.15 for texture alone, 0.15 for a colour change in both ``a`` and ``b``, and nothing
   for a change in ``a`` or ``b`` alone at equal brightness.

Every filter is separable (:func:`scipy.ndimage.gaussian_filter1d` on stacks of bin
images, float32).

**Scale.** Every image is resampled so that its longer side is ``WORK_SIDE`` px for the
cues (reduced or enlarged, bilinear), and the map is brought back to the image (a
reduced image's energy interpolated, an enlarged one's thinned and then pooled by its
maximum in each image pixel, see :func:`_pooled`), so the
half-disc scales are fixed fractions of the image (``σ = 2 px`` is 1/320 of the longer
side), as Pb's disc radii are fractions of the image diagonal.  With fixed pixel scales,
a small image (ETHZ has images from 170 x 255 px) would get discs several times larger
relative to its objects: a giraffe's legs then fall inside one disc and lose their
boundary.
"""

from __future__ import annotations

import warnings

import numba
import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from shapetree._numba_cache import install as _install_cache_locators

_install_cache_locators()  # before the first njit (see shapetree._numba_cache)

__all__ = [
    "boundary_map",
    "boundary_energy",
    "textons",
    "soft_bins",
    "thinned_energy",
    "working_scale",
    "halfdisc_chi2_reference",
    "WEIGHTS",
    "SCALES",
    "COLOUR_SCALES",
    "TEXTURE_SCALES",
]

#: Bins of each colour channel (soft binning).
N_COLOUR_BINS = 12
#: Smoothing of the colour histograms across bins (bins; Pb smooths its histograms too).
BIN_SMOOTH = 1.0
#: Textons per image.
N_TEXTONS = 16
#: Scales of the filter bank (px).
TEXTON_SIGMAS = (1.0, 2.0)
#: Half-disc scales ``σ`` of the Gaussian discs (px, at the processing resolution).
SCALES = (2.0, 4.0)
#: Scales above this run on coarser grids (see :func:`_cue_forms`).
BASE_SIGMA = 2.0
#: Gaussian filters are cut at this many standard deviations.
TRUNCATE = 3.0
#: Half-disc scales of the texture cue (larger: a texton histogram needs more pixels).
TEXTURE_SCALES = (8.0, 16.0)
#: Half-disc scales of the colour cues ``a`` and ``b`` (px, at the processing resolution).
COLOUR_SCALES = (4.0, 8.0)
#: Fixed weights of the cues (brightness, colour a, colour b, texture), each summed over
#: the scales (divided by their number).
WEIGHTS = {"L": 0.4, "a": 0.15, "b": 0.15, "texture": 0.3}
#: ``p = clip((E - E_OFFSET) / E_RANGE, 0, 1)`` (see the module docstring, step 4).
E_OFFSET = 0.1932
E_RANGE = 0.6955
#: Longer image side at which the cues are computed (px); every image is resampled to it.
WORK_SIDE = 640
_KMEANS_SAMPLE = 6000
_EPS = 1e-4


def soft_bins(x: NDArray[np.floating], lo: float, hi: float, n: int) -> NDArray[np.float32]:
    """Soft-binned indicator images of a channel.

    Parameters
    ----------
    x : ndarray, shape (H, W)
        Channel values (clipped to ``[lo, hi]``).
    lo, hi : float
        Value range; the ``n`` bin centres are spread evenly over it.
    n : int
        Number of bins.

    Returns
    -------
    ndarray, shape (n, H, W), float32
        Each pixel's weight split linearly between its two nearest bin centres (the
        weights of a pixel sum to 1).
    """
    t = (np.clip(x, lo, hi) - lo) / max(hi - lo, 1e-12) * (n - 1)
    i0 = np.minimum(np.floor(t).astype(np.int64), n - 2)
    f = (t - i0).astype(np.float32)
    out = np.zeros((n, *x.shape), np.float32)
    rows, cols = np.indices(x.shape)
    out[i0, rows, cols] = 1.0 - f
    out[i0 + 1, rows, cols] += f
    return out


def textons(lum: NDArray[np.floating], *, k: int = N_TEXTONS, seed: int = 0) -> NDArray[np.int64]:
    """Texton label of each pixel (filter bank on ``lum``, k-means with a fixed seed).

    Parameters
    ----------
    lum : ndarray, shape (H, W)
        Brightness (any scale; the responses are contrast-normalised).
    k : int
        Number of textons.
    seed : int
        Seed of the pixel sample and of k-means.

    Returns
    -------
    ndarray, shape (H, W), int64
        Labels in ``0 .. k-1``.
    """
    from scipy.cluster.vq import kmeans2

    lum = np.asarray(lum, np.float32) / max(float(np.ptp(lum)), 1e-6)
    feats = []
    for s in TEXTON_SIGMAS:
        for order in ((0, 1), (1, 0), (0, 2), (2, 0), (1, 1)):
            feats.append(
                ndimage.gaussian_filter(lum, s, order=order, mode="reflect", truncate=TRUNCATE)
                * s ** sum(order)
            )
        feats.append(
            ndimage.gaussian_filter(lum, s, mode="reflect", truncate=TRUNCATE)
            - ndimage.gaussian_filter(lum, 2.0 * s, mode="reflect", truncate=TRUNCATE)
        )
    f = np.stack(feats, axis=-1).reshape(-1, len(feats))
    norm = np.linalg.norm(f, axis=1, keepdims=True)
    f = f * (np.log1p(norm / 0.03) / np.maximum(norm, 1e-9))
    rng = np.random.default_rng(seed)
    n = f.shape[0]
    sample = f[rng.choice(n, size=min(n, _KMEANS_SAMPLE), replace=False)].astype(np.float64)
    distinct = np.unique(np.round(sample, 4), axis=0)
    k = int(min(k, len(distinct)))
    if k <= 1:  # a flat image: one texton
        return np.zeros(lum.shape, np.int64)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "one of the clusters is empty": harmless here
        centres, _ = kmeans2(sample, k, iter=15, minit="++", seed=seed)
    # nearest centre via |f|^2 - 2 f.c + |c|^2 (blocked to bound memory)
    labels = np.empty(n, np.int64)
    c = centres.astype(np.float32)
    cn = (c * c).sum(axis=1)
    for s in range(0, n, 1 << 16):
        blk = f[s : s + (1 << 16)]
        labels[s : s + len(blk)] = np.argmin(cn[None, :] - 2.0 * blk @ c.T, axis=1)
    return labels.reshape(lum.shape)


def _forms(ind: NDArray[np.float32], sigma: float) -> tuple[NDArray, NDArray, NDArray]:
    """``(a, b, c)`` of ``χ²(θ) = a cos² + 2 b cos sin + c sin²`` for bin images ``ind``.

    Each cue's χ² is clipped to 1 (its exact range) through the form's trace.
    """
    ty = ndimage.gaussian_filter1d(ind, sigma, axis=1, mode="reflect", truncate=TRUNCATE)
    s = ndimage.gaussian_filter1d(ty, sigma, axis=2, mode="reflect", truncate=TRUNCATE)
    k = np.float32(sigma * np.sqrt(2.0 * np.pi))
    dx = ndimage.gaussian_filter1d(ty, sigma, axis=2, order=1, mode="reflect", truncate=TRUNCATE)
    del ty
    dy = ndimage.gaussian_filter1d(ind, sigma, axis=1, order=1, mode="reflect", truncate=TRUNCATE)
    dy = ndimage.gaussian_filter1d(dy, sigma, axis=2, mode="reflect", truncate=TRUNCATE)
    inv = (k * k / 4.0) / np.maximum(s, np.float32(_EPS))
    dxi = dx * inv
    a = np.einsum("bij,bij->ij", dxi, dx)
    b = np.einsum("bij,bij->ij", dxi, dy)
    c = np.einsum("bij,bij->ij", dy * inv, dy)
    return a, b, c


def _pool(ind: NDArray[np.float32], f: int) -> NDArray[np.float32]:
    """Block means ``f x f`` of bin images (the histograms at a coarser grid; the image is
    padded by its edge values to whole blocks).

    The sums run over strided views: each row of a block first (its ``f`` values in
    sequence, or for ``f = 8`` pairwise in the order of NumPy's 8-way unrolled sum), then
    the rows in sequence, then a division by ``f²``. That is the order of NumPy's
    ``mean(axis=(2, 4))`` of the blocked array, which this replaces (the same float32
    values, bit for bit with NumPy 2.4, at a fifth of the time); other ``f`` use that
    ``mean``.
    """
    if f == 1:
        return ind
    n, h, w = ind.shape
    hh, ww = -(-h // f) * f, -(-w // f) * f
    pad = np.pad(ind, ((0, 0), (0, hh - h), (0, ww - w)), mode="edge")
    if f not in (2, 4, 8):
        return pad.reshape(n, hh // f, f, ww // f, f).mean(axis=(2, 4))
    acc = None
    for i in range(f):
        xs = [pad[:, i::f, j::f] for j in range(f)]
        if f == 8:
            row = ((xs[0] + xs[1]) + (xs[2] + xs[3])) + ((xs[4] + xs[5]) + (xs[6] + xs[7]))
        else:
            row = xs[0] + xs[1]
            for x in xs[2:]:
                row += x
        if acc is None:
            acc = row
        else:
            acc += row
    return acc / np.float32(f * f)


def _up_axis(n_out: int, f: int, n_in: int) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Bilinear weights along one axis: output pixel centres ``(i + 0.5) / f - 0.5`` in
    input pixels, clamped to the input (``mode="nearest"``); the lower and upper input
    index and their weights."""
    x = np.clip((np.arange(n_out) + 0.5) / f - 0.5, 0.0, n_in - 1.0)
    i0 = np.minimum(np.floor(x).astype(np.int64), n_in - 1)
    t = x - i0
    return i0, np.minimum(i0 + 1, n_in - 1), 1.0 - t, t


@numba.njit(cache=True, nogil=True)
def _up_kernel(x, r0, r1, wr0, wr1, c0, c1, wc0, wc1, out):
    for i in range(out.shape[0]):
        for j in range(out.shape[1]):
            t = (np.float64(x[r0[i], c0[j]]) * wr0[i]) * wc0[j]
            t += (np.float64(x[r0[i], c1[j]]) * wr0[i]) * wc1[j]
            t += (np.float64(x[r1[i], c0[j]]) * wr1[i]) * wc0[j]
            t += (np.float64(x[r1[i], c1[j]]) * wr1[i]) * wc1[j]
            out[i, j] = t


def _up(x: NDArray, f: int, shape: tuple[int, int]) -> NDArray:
    """Bilinear upsampling by ``f`` of a coarse-grid map to ``shape`` (pixel centres).

    The values of ``scipy.ndimage.map_coordinates(x, grid, order=1, mode="nearest")`` at
    the output pixel centres (the four corner terms summed in double precision in its
    order, then cast to ``x``'s dtype; bit for bit with SciPy 1.17), computed on the
    separable grid without the per-point coordinate arrays.
    """
    if f == 1:
        return x
    out = np.empty(shape, x.dtype)
    _up_kernel(x, *_up_axis(shape[0], f, x.shape[0]), *_up_axis(shape[1], f, x.shape[1]), out)
    return out


def _cue_forms(ind: NDArray[np.float32], scales: tuple[float, ...]):
    """A cue's form averaged over the scales; scale ``σ`` runs on a grid ``f`` times
    coarser (``f`` the power of two at most ``σ / BASE_SIGMA``), where it is ``σ / f``."""
    h, w = ind.shape[1:]
    s0 = BASE_SIGMA
    ca = np.zeros((h, w))
    cb = np.zeros((h, w))
    cc = np.zeros((h, w))
    for s in scales:
        f = int(2 ** np.floor(np.log2(max(s / s0, 1.0)) + 1e-9))
        a, b, c = _forms(_pool(ind, f), s / f)
        ca += _up(a, f, (h, w))
        cb += _up(b, f, (h, w))
        cc += _up(c, f, (h, w))
    n = len(scales)
    return ca / n, cb / n, cc / n


def _channels(image: NDArray[np.float64]) -> dict[str, NDArray[np.float32]]:
    """Bin images per cue: ``L``, ``a``, ``b`` (soft bins) and ``texture`` (textons)."""
    out: dict[str, NDArray[np.float32]] = {}
    lum = image[:, :, 0]
    out["L"] = soft_bins(lum, 0.0, 100.0, N_COLOUR_BINS)
    if image.shape[2] == 3:
        out["a"] = soft_bins(image[:, :, 1], -60.0, 60.0, N_COLOUR_BINS)
        out["b"] = soft_bins(image[:, :, 2], -60.0, 60.0, N_COLOUR_BINS)
    if BIN_SMOOTH > 0:  # kernel density: neighbouring bins share their counts
        for key in list(out):
            out[key] = ndimage.gaussian_filter1d(
                out[key], BIN_SMOOTH, axis=0, mode="reflect", truncate=TRUNCATE
            )
    lab = textons(lum)
    out["texture"] = (lab[None] == np.arange(N_TEXTONS)[:, None, None]).astype(np.float32)
    return out


def boundary_energy(
    lab: NDArray[np.float64],
    *,
    scales: tuple[float, ...] = SCALES,
    weights: dict[str, float] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], dict[str, NDArray]]:
    """Combined oriented χ² boundary energy of a Lab image (no thinning).

    Parameters
    ----------
    lab : ndarray, shape (H, W, 3) or (H, W, 1)
        CIE-Lab channels (``L`` in 0..100).
    scales : tuple of float
        Half-disc scales ``σ`` of the brightness cue (px; the colour cues use
        :data:`COLOUR_SCALES`, the texture cue :data:`TEXTURE_SCALES`).
    weights : dict or None
        Cue weights (default :data:`WEIGHTS`; the colour weights of a greyscale image go
        to ``L``).

    Returns
    -------
    energy : ndarray, shape (H, W)
        Largest eigenvalue of the summed quadratic form (the best orientation's
        weighted χ², in ``[0, 1]``).
    nx, ny : ndarray, shape (H, W)
        The boundary normal at each pixel (unit).
    per_cue : dict of str to ndarray (H, W)
        Each cue's χ² at its own best orientation, averaged over the scales (for
        inspection and tests).
    """
    w = dict(WEIGHTS if weights is None else weights)
    chans = _channels(lab)
    if "a" not in chans:
        w["L"] = w.get("L", 0.0) + w.pop("a", 0.0) + w.pop("b", 0.0)
    h, wd = lab.shape[:2]
    fa = np.zeros((h, wd))
    fb = np.zeros((h, wd))
    fc = np.zeros((h, wd))
    per_cue = {}
    for name, ind in chans.items():
        sc = {"texture": TEXTURE_SCALES, "a": COLOUR_SCALES, "b": COLOUR_SCALES}.get(name, scales)
        ca, cb, cc = _cue_forms(ind, sc)
        top = 0.5 * (ca + cc) + np.sqrt(0.25 * (ca - cc) ** 2 + cb**2)
        shrink = np.minimum(1.0, 1.0 / np.maximum(top, 1e-12))  # chi2 <= 1
        ca, cb, cc = ca * shrink, cb * shrink, cc * shrink
        per_cue[name] = top * shrink
        wt = w.get(name, 0.0)
        fa += wt * ca
        fb += wt * cb
        fc += wt * cc
    half = 0.5 * (fa - fc)
    root = np.sqrt(half**2 + fb**2)
    energy = 0.5 * (fa + fc) + root
    # eigenvector of [[a, b], [b, c]] for the largest eigenvalue: angle of the normal
    theta = 0.5 * np.arctan2(2.0 * fb, fa - fc)
    return energy, np.cos(theta), np.sin(theta), per_cue


def working_scale(h: int, w: int) -> float:
    """Factor by which an ``h x w`` image is resampled for the cues (longer side to
    :data:`WORK_SIDE`)."""
    return WORK_SIDE / max(h, w)


def _pooled(
    energy: NDArray, nx: NDArray, ny: NDArray, shape: tuple[int, int], thin: bool
) -> NDArray[np.float64]:
    """An enlarged image's energy brought back to the image's ``shape``: thinned at the
    working size, then each image pixel keeps the strongest response inside it (its
    normal the energy-weighted mean of the double angles there), then thinned again.
    Sampling the working-size map at the pixel centres instead would miss a thin peak
    lying between two of them (a sharp step in a 40 px image came out at 0.67, not 1)."""
    from ._edges import _nms

    h, w = shape
    if thin:
        energy = _nms(energy, nx, ny)
    ang = 2.0 * np.arctan2(ny, nx)
    c2, s2 = energy * np.cos(ang), energy * np.sin(ang)
    # first working row / column inside each image row / column
    rows = np.searchsorted((np.arange(energy.shape[0]) + 0.5) * h / energy.shape[0], np.arange(h))
    cols = np.searchsorted((np.arange(energy.shape[1]) + 0.5) * w / energy.shape[1], np.arange(w))
    pooled = np.maximum.reduceat(np.maximum.reduceat(energy, rows, axis=0), cols, axis=1)
    pc = np.add.reduceat(np.add.reduceat(c2, rows, axis=0), cols, axis=1)
    ps = np.add.reduceat(np.add.reduceat(s2, rows, axis=0), cols, axis=1)
    theta = 0.5 * np.arctan2(ps, pc)
    if thin:
        pooled = _nms(pooled, np.cos(theta), np.sin(theta))
    return pooled


def thinned_energy(lab: NDArray[np.float64], *, thin: bool = True) -> NDArray[np.float64]:
    """The combined boundary energy of a Lab image at the image's size, before the affine
    map to ``[0, 1]`` (cues at :data:`WORK_SIDE`, resized back, then thinned).

    Parameters
    ----------
    lab : ndarray, shape (H, W, 3) or (H, W, 1)
        CIE-Lab channels.
    thin : bool
        Non-maximum suppression across the boundary normal.

    Returns
    -------
    ndarray, shape (H, W), float64
        The best orientation's weighted χ² (see :func:`boundary_energy`).
    """
    from ._edges import _nms

    h, w = lab.shape[:2]
    f = working_scale(h, w)
    work = lab
    if f != 1.0:
        work = ndimage.zoom(lab, (f, f, 1), order=1, mode="nearest")
    energy, nx, ny, _ = boundary_energy(work)
    if f > 1.0:
        return _pooled(energy, nx, ny, (h, w), thin)
    if f < 1.0:
        zoom = (h / energy.shape[0], w / energy.shape[1])
        energy = ndimage.zoom(energy, zoom, order=1, mode="nearest")
        ang = np.arctan2(ny, nx) * 2.0  # double angle: the normal's sign is arbitrary
        c2 = ndimage.zoom(np.cos(ang), zoom, order=1, mode="nearest")
        s2 = ndimage.zoom(np.sin(ang), zoom, order=1, mode="nearest")
        theta = 0.5 * np.arctan2(s2, c2)
        nx, ny = np.cos(theta), np.sin(theta)
        energy, nx, ny = energy[:h, :w], nx[:h, :w], ny[:h, :w]
    if thin:
        energy = _nms(energy, nx, ny)
    return energy


def boundary_map(
    lab: NDArray[np.float64], *, thin: bool = True, floor: float = 0.02
) -> NDArray[np.float64]:
    """Soft boundary map in ``[0, 1]`` of a Lab image (see the module docstring).

    Parameters
    ----------
    lab : ndarray, shape (H, W, 3) or (H, W, 1)
        CIE-Lab channels.
    thin : bool
        Non-maximum suppression across the boundary normal.
    floor : float
        Values below this are set to 0.

    Returns
    -------
    ndarray, shape (H, W), float64
    """
    p = np.clip((thinned_energy(lab, thin=thin) - E_OFFSET) / E_RANGE, 0.0, 1.0)
    p[p < floor] = 0.0
    return p


def halfdisc_chi2_reference(
    labels: NDArray[np.int64], n_bins: int, row: int, col: int, radius: float, theta: float
) -> float:
    """Literal χ² between the two half-disc histograms at one pixel (the tests' oracle).

    Parameters
    ----------
    labels : ndarray, shape (H, W), int
        Bin label of each pixel.
    n_bins : int
    row, col : int
        The disc's centre.
    radius : float
        Disc radius (px).
    theta : float
        Angle of the normal of the dividing line (radians; x right, y down).

    Returns
    -------
    float
        ``½ Σ_b (g_b - h_b)² / (g_b + h_b)`` of the normalised half-disc histograms
        (pixels on the dividing line are left out).
    """
    h, w = labels.shape
    r = int(np.ceil(radius))
    g = np.zeros(n_bins)
    hh = np.zeros(n_bins)
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            if dx * dx + dy * dy > radius * radius:
                continue
            y, x = row + dy, col + dx
            if not (0 <= y < h and 0 <= x < w):
                continue
            side = dx * np.cos(theta) + dy * np.sin(theta)
            if side > 1e-9:
                g[labels[y, x]] += 1
            elif side < -1e-9:
                hh[labels[y, x]] += 1
    g /= max(g.sum(), 1)
    hh /= max(hh.sum(), 1)
    tot = g + hh
    ok = tot > 0
    return float(0.5 * np.sum((g[ok] - hh[ok]) ** 2 / tot[ok]))
