"""The own boundary detector (edge_map(method="own")) on synthetic images with known answers."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from shapetree import ShapeTreeError
from shapetree.detection import DetectParams, edge_map
from shapetree.detection._boundary import (
    WORK_SIDE,
    _forms,
    boundary_energy,
    halfdisc_chi2_reference,
    soft_bins,
    textons,
    working_scale,
)
from shapetree.detection._edges import _as_channels

# at the working size, so these images are not resampled (the scales are the module's)
H, W = 480, WORK_SIDE
YY, XX = np.mgrid[0:H, 0:W]
RNG = np.random.default_rng(0)
V_STRIPES = 0.5 + 0.4 * np.sign(np.sin(XX * 2 * np.pi / 6))
H_STRIPES = 0.5 + 0.4 * np.sign(np.sin(YY * 2 * np.pi / 6))
NOISE = ndimage.gaussian_filter(RNG.random((H, W)), 1.0)
NOISE = (NOISE - NOISE.min()) / np.ptp(NOISE)


def _interior(e: np.ndarray) -> np.ndarray:
    return e[10:-10, 10 : W // 2 - 12]


def _boundary_strength(e: np.ndarray) -> float:
    """Mean over rows of the strongest response within 3 px of the middle column."""
    return float(e[10:-10, W // 2 - 3 : W // 2 + 3].max(axis=1).mean())


@pytest.mark.parametrize("name, image", [("stripes", V_STRIPES), ("noise", NOISE)])
def test_texture_without_boundary_is_weak(name: str, image: np.ndarray) -> None:
    own = edge_map(image, method="own")
    grad = edge_map(image, method="gradient")
    assert own.shape == image.shape and own.min() >= 0.0 and own.max() <= 1.0
    # the gradient magnitude fires all over the texture; the half-disc cues do not
    assert (_interior(grad) > 0.15).mean() > 0.25, name
    assert (_interior(own) > 0.15).mean() < 0.05, name
    assert _interior(own).mean() < 0.02, name


def test_step_between_two_textures_is_strong() -> None:
    """Vertical against horizontal stripes: the same brightness histogram on both sides,
    so only the texture cue can see the boundary."""
    image = np.where(XX < W // 2, V_STRIPES, H_STRIPES)
    e = edge_map(image, method="own")
    assert _boundary_strength(e) > 0.2
    assert _boundary_strength(e) > 10 * _interior(e).mean()
    _, _, _, cues = boundary_energy(_as_channels(image))
    assert cues["texture"][10:-10, W // 2 - 2 : W // 2 + 2].max(axis=1).mean() > 0.9
    assert cues["L"][10:-10, W // 2 - 2 : W // 2 + 2].max(axis=1).mean() < 0.2


def test_brightness_step_is_strong_and_thin() -> None:
    image = np.where(XX < W // 2, 0.3, 0.7) + 0.02 * RNG.standard_normal((H, W))
    e = edge_map(np.clip(image, 0, 1), method="own")
    assert _boundary_strength(e) > 0.8  # brightness alone is capped at 0.72, textons add
    cols = np.nonzero(e[H // 2] > 0.5)[0]
    assert len(cols) <= 2 and np.all(np.abs(cols - (W // 2 - 0.5)) < 2)
    assert _interior(e).max() < 0.15


def test_colour_step_of_equal_brightness_is_found() -> None:
    """Purple-red against green-yellow at the same brightness: both colour cues change."""
    from skimage.color import lab2rgb

    lab = np.zeros((H, W, 3))
    lab[..., 0] = 60.0
    lab[..., 1] = np.where(XX < W // 2, 30.0, -30.0)
    lab[..., 2] = np.where(XX < W // 2, -30.0, 30.0)
    e = edge_map(lab2rgb(lab), method="own")
    # capped at (0.3 - E_OFFSET) / E_RANGE = 0.15 (the module docstring): above the
    # tracer's low threshold (0.06), so such a boundary continues a contour
    assert _boundary_strength(e) > 0.12 and _interior(e).max() < 0.05


def test_steered_chi2_matches_the_literal_half_discs_on_a_step() -> None:
    """Oracle: the literal half-disc chi2 (pure Python) on a straight step between two
    labels is 1 across it and 0 along it; the steered form gives the same there, and the
    best orientation is the step's normal."""
    labels = (XX >= W // 2).astype(np.int64)
    ind = np.stack([labels == 0, labels == 1]).astype(np.float32)
    a, b, c = (np.asarray(v, dtype=np.float64) for v in _forms(ind, 4.0))
    row, col = H // 2, W // 2
    across = halfdisc_chi2_reference(labels, 2, row, col, 8.0, 0.0)
    along = halfdisc_chi2_reference(labels, 2, row, col, 8.0, np.pi / 2)
    assert across > 0.75 and along == pytest.approx(0.0)
    assert a[row, col] == pytest.approx(1.0, abs=0.1)  # theta = 0: cos^2 term
    assert c[row, col] == pytest.approx(0.0, abs=1e-6)  # theta = pi/2
    assert abs(b[row, col]) < 1e-6
    # far from the step both are 0
    assert halfdisc_chi2_reference(labels, 2, row, 10, 8.0, 0.0) == 0.0
    assert a[row, 10] < 1e-6


def test_soft_bins_split_each_value_between_two_bins() -> None:
    x = RNG.uniform(0, 100, size=(7, 9))
    bins = soft_bins(x, 0.0, 100.0, 12)
    assert bins.shape == (12, 7, 9)
    assert np.allclose(bins.sum(axis=0), 1.0, atol=1e-6)
    assert ((bins > 0).sum(axis=0) <= 2).all()
    centres = np.linspace(0.0, 100.0, 12)
    assert np.allclose(np.tensordot(centres, bins, axes=1), x, atol=1e-3)


def test_textons_are_seeded_and_cover_a_flat_image() -> None:
    a = textons(NOISE, k=8, seed=3)
    b = textons(NOISE, k=8, seed=3)
    assert a.shape == NOISE.shape and np.array_equal(a, b)
    assert 2 <= len(np.unique(a)) <= 8
    assert np.all(textons(np.full((20, 20), 0.4), k=8) == 0)


def test_every_image_is_processed_at_the_working_size() -> None:
    assert working_scale(H, W) == 1.0
    assert working_scale(240, 320) == pytest.approx(2.0)
    assert working_scale(1280, 960) == pytest.approx(0.5)
    assert working_scale(170, 255) == pytest.approx(WORK_SIDE / 255)


def _bar_scene(h: int, w: int, bar: int) -> np.ndarray:
    """A dark vertical bar ``bar`` px wide (a leg, a pole) on a lighter soft texture."""
    rng = np.random.default_rng(5)
    img = 0.6 + 0.1 * ndimage.gaussian_filter(rng.standard_normal((h, w)), 0.7)
    c = w // 2
    img[:, c - bar // 2 : c - bar // 2 + bar] = 0.15
    return np.clip(img, 0, 1)


def test_an_enlarged_image_keeps_a_sharp_step_at_full_strength_and_one_pixel_wide() -> None:
    """A 40 px image is computed 16x enlarged; its thin peak lies between two pixel
    centres of the image and must not be lost when the map is brought back."""
    g = np.zeros((40, 40))
    g[:, 20:] = 0.8
    e = edge_map(g, method="own")
    assert np.all(e[:, 19:21].max(axis=1) > 0.95)
    assert np.all((e > 0.1).sum(axis=1) == 1)


def _bar_strength(e: np.ndarray) -> float:
    h, w = e.shape
    m, half = h // 12, w // 25
    return float(e[m:-m, w // 2 - half : w // 2 + half].max(axis=1).mean())


def test_a_small_image_keeps_its_thin_structures() -> None:
    """The cue scales are fractions of the image: a 3 px bar in a 160 px wide image is
    found as strongly as the same scene enlarged 4x (with fixed pixel scales the half-discs
    would cover the bar and both its sides, and the bar would be lost)."""
    small = _bar_scene(120, 160, 3)
    big = np.kron(small, np.ones((4, 4)))
    e_small = edge_map(small, method="own")
    e_big = edge_map(big, method="own")
    assert e_small.shape == small.shape and e_big.shape == big.shape
    assert _bar_strength(e_small) > 0.5
    # each image pixel keeps the strongest response inside it, so a little stronger
    assert _bar_strength(e_big) - 0.1 < _bar_strength(e_small) < _bar_strength(e_big) + 0.15


def test_method_validation_and_detect_params() -> None:
    with pytest.raises(ShapeTreeError, match="unknown edge method"):
        edge_map(NOISE, method="canny")
    with pytest.raises(ShapeTreeError, match="edge_method"):
        DetectParams(edge_method="sobel")
    assert DetectParams().edge_method == "own"
    assert np.all(edge_map(np.full((20, 30), 0.5), method="own") == 0)


@pytest.mark.parametrize("f", [2, 4, 8, 16])
def test_block_means_and_upsampling_agree_with_numpy_and_scipy(f: int) -> None:
    """The coarse-grid helpers give the values of the plain forms they replace: the block
    mean of the edge-padded bin images, and ``map_coordinates`` (order 1, nearest) at the
    output pixel centres (both were bit-identical when written; checked here to float32
    rounding)."""
    from shapetree.detection._boundary import _pool, _up

    rng = np.random.default_rng(f)
    ind = rng.random((3, 61, 47)).astype(np.float32)
    n, h, w = ind.shape
    hh, ww = -(-h // f) * f, -(-w // f) * f
    pad = np.pad(ind, ((0, 0), (0, hh - h), (0, ww - w)), mode="edge")
    want = pad.reshape(n, hh // f, f, ww // f, f).mean(axis=(2, 4))
    got = _pool(ind, f)
    assert got.dtype == np.float32 and got.shape == want.shape
    np.testing.assert_allclose(got, want, rtol=2e-6, atol=1e-7)
    coarse = got[0]
    rows = (np.arange(h) + 0.5) / f - 0.5
    cols = (np.arange(w) + 0.5) / f - 0.5
    rr, cc = np.meshgrid(rows, cols, indexing="ij")
    want_up = ndimage.map_coordinates(coarse, [rr, cc], order=1, mode="nearest")
    got_up = _up(coarse, f, (h, w))
    assert got_up.dtype == np.float32 and got_up.shape == (h, w)
    np.testing.assert_allclose(got_up, want_up, rtol=2e-6, atol=1e-7)
    # a linear ramp is reproduced inside, and the border is clamped
    ramp = np.add.outer(np.arange(8.0), 2 * np.arange(6.0))
    up = _up(ramp, f, (8 * f, 6 * f))
    c = (np.arange(8 * f) + 0.5) / f - 0.5
    d = (np.arange(6 * f) + 0.5) / f - 0.5
    exact = np.add.outer(np.clip(c, 0, 7), 2 * np.clip(d, 0, 5))
    np.testing.assert_allclose(up, exact, atol=1e-12)
