"""Tests of shapetree.curves.curve_from_image and load_curve on images (synthetic and real)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from scipy import ndimage

from shapetree import ImageError
from shapetree.curves import curve_from_image, curve_length, load_curve, signed_area

DATA = Path(
    os.environ.get("SHAPETREE_DATA", Path(__file__).resolve().parents[2] / "shared/datasets")
)


def disc(h: int = 80, w: int = 100, cx: float = 45, cy: float = 38, r: float = 20) -> np.ndarray:
    """White (255) disc on black (0), uint8, shape (h, w)."""
    yy, xx = np.mgrid[:h, :w]
    return np.where((xx - cx) ** 2 + (yy - cy) ** 2 <= r**2, 255, 0).astype(np.uint8)


def radius_stats(curve: np.ndarray, cx: float, cy: float) -> tuple[float, float]:
    d = np.hypot(curve[:, 0] - cx, curve[:, 1] - cy)
    return float(d.mean()), float(np.abs(d - d.mean()).max())


def assert_closed_curve(curve: np.ndarray) -> None:
    assert curve.ndim == 2 and curve.shape[1] == 2 and curve.dtype == np.float64
    assert not np.array_equal(curve[0], curve[-1])  # no repeated endpoint
    assert signed_area(curve) > 0
    # Consecutive marching-squares points are 1 (straight) or sqrt(2)/2 (corner) pixel apart.
    steps = np.hypot(*np.diff(np.vstack([curve, curve[:1]]), axis=0).T)
    assert np.all(np.isclose(steps, 1.0) | np.isclose(steps, np.sqrt(0.5)))


# ---------------------------------------------------------------- synthetic arrays


def test_disc_radius_and_centre_recovered():
    curve = curve_from_image(disc(cx=45, cy=38, r=20))
    assert_closed_curve(curve)
    mean_r, dev = radius_stats(curve, 45, 38)
    assert mean_r == pytest.approx(20, abs=1.0)
    assert dev < 1.0
    assert curve[:, 0].mean() == pytest.approx(45, abs=0.2)  # x is the column
    assert curve[:, 1].mean() == pytest.approx(38, abs=0.2)  # y is the row
    assert signed_area(curve) == pytest.approx(np.pi * 20**2, rel=0.03)


def test_rectangle_boundary_coordinates():
    img = np.zeros((30, 40), np.uint8)
    img[5:15, 10:30] = 255  # rows 5..14, columns 10..29
    curve = curve_from_image(img)
    assert curve[:, 0].min() == pytest.approx(9.5) and curve[:, 0].max() == pytest.approx(29.5)
    assert curve[:, 1].min() == pytest.approx(4.5) and curve[:, 1].max() == pytest.approx(14.5)
    # Marching squares cuts the 4 corners by 1/8 pixel each.
    assert signed_area(curve) == pytest.approx(200 - 0.5)


def test_polarity_inversion_gives_same_curve():
    img = disc()
    white_on_black = curve_from_image(img)
    black_on_white = curve_from_image(255 - img)
    np.testing.assert_array_equal(white_on_black, black_on_white)
    np.testing.assert_array_equal(curve_from_image(255 - img, polarity="dark"), white_on_black)
    np.testing.assert_array_equal(curve_from_image(img, polarity="bright"), white_on_black)


def test_forced_polarity_picks_the_other_class():
    img = disc()
    # "dark" on a white disc: the background (touching the border) becomes the shape.
    background = curve_from_image(img, polarity="dark")
    assert signed_area(background) > 0.9 * img.size


def test_holes_do_not_change_outer_curve():
    img = disc()
    holed = img.copy()
    holed[30:36, 40:50] = 0  # a rectangular hole
    holed[45, 45] = 0  # a one-pixel hole
    np.testing.assert_array_equal(curve_from_image(holed), curve_from_image(img))


def test_largest_component_wins_over_specks_and_small_blobs():
    img = disc()
    with_noise = img.copy()
    with_noise[2, 2] = with_noise[70, 90] = 255  # specks
    with_noise[60:70, 80:90] = 255  # a 100-pixel blob
    np.testing.assert_array_equal(curve_from_image(with_noise), curve_from_image(img))


def test_diagonal_pixels_are_one_8_connected_shape():
    img = np.zeros((20, 20), np.uint8)
    img[2:8, 2:8] = 255
    img[8:14, 8:14] = 255  # touches the first square only at a corner
    curve = curve_from_image(img)
    assert curve[:, 0].min() < 2 and curve[:, 0].max() > 13  # both squares in one boundary
    assert signed_area(curve) == pytest.approx(72, abs=1.5)


def test_shape_touching_border_gets_closed_boundary():
    img = np.zeros((40, 50), np.uint8)
    img[:, :20] = 255  # fills the left 20 columns, top to bottom
    img[10:25, 20:35] = 255
    curve = curve_from_image(img)
    assert_closed_curve(curve)
    assert curve[:, 0].min() == pytest.approx(-0.5)
    assert curve[:, 1].min() == pytest.approx(-0.5) and curve[:, 1].max() == pytest.approx(39.5)
    assert signed_area(curve) == pytest.approx(20 * 40 + 15 * 15, abs=1)


def test_colour_and_bool_and_float_arrays():
    grey = disc()
    ref = curve_from_image(grey)
    rgb = np.stack([grey, grey, grey], axis=-1)
    np.testing.assert_array_equal(curve_from_image(rgb), ref)
    rgba = np.concatenate([rgb, np.full(grey.shape + (1,), 255, np.uint8)], axis=-1)
    np.testing.assert_array_equal(curve_from_image(rgba), ref)
    np.testing.assert_array_equal(curve_from_image(grey > 0), ref)
    np.testing.assert_array_equal(curve_from_image(grey / 255.0), ref)


def test_low_contrast_and_noisy_images_use_otsu():
    shape = disc() > 0
    low = np.where(shape, 60, 20).astype(np.uint8)  # two-valued: midpoint 40
    np.testing.assert_array_equal(curve_from_image(low), curve_from_image(shape))
    rng = np.random.default_rng(1)
    noisy = np.clip(np.where(shape, 70.0, 30.0) + rng.normal(0, 4, shape.shape), 0, 255)
    curve = curve_from_image(noisy.astype(np.uint8))  # all below 127.5: Otsu
    mean_r, _ = radius_stats(curve, 45, 38)
    assert mean_r == pytest.approx(20, abs=1.0)


def test_explicit_threshold():
    img = np.zeros((60, 60), np.uint8)
    img[10:50, 10:50] = 100  # big dim square
    img[25:35, 25:35] = 200  # small bright square inside it
    big = signed_area(curve_from_image(img, threshold=50))
    small = signed_area(curve_from_image(img, threshold=150))
    assert big == pytest.approx(1600 - 0.5) and small == pytest.approx(100 - 0.5)


@pytest.mark.parametrize(
    ("image", "kwargs", "words"),
    [
        (np.zeros((0, 10), np.uint8), {}, ["empty"]),
        (np.full((10, 10), 255, np.uint8), {}, ["blank"]),
        (np.zeros((10, 10), np.uint8), {}, ["blank"]),
        (disc(), {"threshold": 255}, ["blank", "no foreground"]),
        (np.pad(np.full((3, 3), 255, np.uint8), 5), {}, ["too small", "9 pixels"]),
        (disc(r=3), {"min_area": 100}, ["too small", "min_area=100"]),
        (np.zeros((4, 4, 2)), {}, ["shape"]),
        (np.array([["a", "b"], ["c", "d"]]), {}, ["dtype"]),
        (np.array([[0.0, np.nan], [1.0, 0.0]]), {}, ["NaN"]),
        (disc(), {"polarity": "white"}, ["polarity"]),
    ],
)
def test_image_errors(image, kwargs, words):
    with pytest.raises(ImageError) as info:
        curve_from_image(image, **kwargs)
    for word in words:
        assert word in str(info.value)


# ---------------------------------------------------------------- files


def _save(img: np.ndarray, path: Path) -> Path:
    Image.fromarray(img).save(path)
    return path


@pytest.mark.parametrize("ext", [".png", ".gif", ".bmp", ".tif", ".pgm", ".jpg"])
def test_file_formats(tmp_path, ext):
    img = disc()
    ref = curve_from_image(img)
    curve = curve_from_image(_save(255 - img, tmp_path / f"shape{ext}"))  # black on white
    if ext == ".jpg":  # lossy: the boundary may move by a fraction of a pixel
        mean_r, dev = radius_stats(curve, 45, 38)
        assert mean_r == pytest.approx(20, abs=1.0) and dev < 1.5
    else:
        np.testing.assert_array_equal(curve, ref)


def test_palette_image_uses_rendered_grey_not_indices(tmp_path):
    """Index 0 = white, 1 = black (like mpeg7/Glas-12): the shape is the white index-0 part."""
    shape = disc() > 0
    pal = Image.fromarray(np.where(shape, 0, 1).astype(np.uint8), mode="P")
    pal.putpalette([255, 255, 255, 0, 0, 0])
    path = tmp_path / "inverted_palette.png"
    pal.save(path)
    np.testing.assert_array_equal(curve_from_image(path), curve_from_image(shape))


def test_16bit_png(tmp_path):
    img = (disc() > 0).astype(np.uint16) * 40000
    path = tmp_path / "deep.png"
    Image.fromarray(img).save(path)
    np.testing.assert_array_equal(curve_from_image(path), curve_from_image(img > 0))


def test_file_errors(tmp_path):
    with pytest.raises(ImageError, match="not found"):
        curve_from_image(tmp_path / "missing.png")
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"definitely not a png")
    with pytest.raises(ImageError, match="bad.png.*unreadable"):
        curve_from_image(bad)
    with pytest.raises(ImageError, match="blank"):
        curve_from_image(_save(np.full((20, 20), 255, np.uint8), tmp_path / "white.bmp"))
    with pytest.raises(ImageError, match="not a file"):
        curve_from_image(tmp_path)


def test_load_curve_image(tmp_path):
    path = _save(255 - disc(), tmp_path / "d.gif")
    pts, closed = load_curve(path)
    assert closed is True and signed_area(pts) > 0
    np.testing.assert_array_equal(pts, curve_from_image(path))
    pts, _ = load_curve(path, orientation="cw")
    assert signed_area(pts) < 0
    pts, _ = load_curve(path, n_points=100)
    assert pts.shape == (100, 2)
    steps = np.hypot(*np.diff(np.vstack([pts, pts[:1]]), axis=0).T)
    assert steps.std() / steps.mean() < 0.05
    assert curve_length(pts, closed=True) == pytest.approx(2 * np.pi * 20, rel=0.05)


# ---------------------------------------------------------------- real dataset files


REAL = ["mpeg7/rat-09.png", "mpeg7/Glas-12.png", "mpeg7/guitar-3.png", "kimia99/f15.png"]


@pytest.mark.parametrize("rel", REAL)
def test_real_silhouettes(rel):
    path = DATA / rel
    if not path.exists():
        pytest.skip(f"dataset file {path} not available")
    grey = np.asarray(Image.open(path).convert("L"))
    # Independent reference: shape = the class that is not the border majority, 8-connected,
    # largest component, holes filled.
    bright = grey > 127
    border = np.concatenate([bright[0], bright[-1], bright[:, 0], bright[:, -1]])
    fg = ~bright if border.mean() > 0.5 else bright
    labels, _ = ndimage.label(fg, structure=np.ones((3, 3)))
    largest = labels == np.argmax(np.bincount(labels.ravel())[1:]) + 1
    filled = ndimage.binary_fill_holes(largest)

    curve = curve_from_image(path)
    assert_closed_curve(curve)
    assert signed_area(curve) == pytest.approx(filled.sum(), rel=0.02)
    rows, cols = np.nonzero(filled)
    assert curve[:, 0].min() == pytest.approx(cols.min() - 0.5)
    assert curve[:, 0].max() == pytest.approx(cols.max() + 0.5)
    assert curve[:, 1].min() == pytest.approx(rows.min() - 0.5)
    assert curve[:, 1].max() == pytest.approx(rows.max() + 0.5)
    # The curve encloses the shape, not the background.
    assert signed_area(curve) < 0.9 * grey.size


def test_real_specks_and_inversions():
    if not (DATA / "mpeg7").exists():
        pytest.skip("mpeg7 dataset not available")
    # guitar-3: 148 components; the guitar (filled) dwarfs any speck.
    guitar = curve_from_image(DATA / "mpeg7/guitar-3.png")
    assert signed_area(guitar) > 50_000
    # rat-09 is the one inverted (black on white) MPEG-7 image: auto polarity must find the rat.
    rat = curve_from_image(DATA / "mpeg7/rat-09.png")
    rat_dark = curve_from_image(DATA / "mpeg7/rat-09.png", polarity="dark")
    np.testing.assert_array_equal(rat, rat_dark)


# --- oversized images and decompression bombs -------------------------------------------


def _png_header_only(path: Path, width: int, height: int) -> Path:
    """A PNG whose IHDR claims ``width x height`` 8-bit grey pixels, with a tiny IDAT.

    A few hundred bytes on disk; decoding it would need width*height bytes, so nothing may
    decode it: the size check has to come first.
    """
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr)
    png += chunk(b"IDAT", zlib.compress(b"\x00" * 64)) + chunk(b"IEND", b"")
    path.write_bytes(png)
    return path


@pytest.fixture
def bomb(tmp_path: Path) -> Path:
    """30000 x 30000 claimed (900 Mpx): over Pillow's own hard limit too."""
    return _png_header_only(tmp_path / "bomb.png", 30000, 30000)


@pytest.fixture
def default_limit(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("SHAPETREE_MAX_PIXELS", raising=False)


def _assert_one_line_refusal(msg: str, path: Path, limit: str = "64,000,000") -> None:
    assert "\n" not in msg
    assert str(path) in msg and limit in msg and "SHAPETREE_MAX_PIXELS" in msg
    assert "too large" in msg


def test_max_image_pixels_default_and_env(monkeypatch: pytest.MonkeyPatch) -> None:
    from shapetree.curves._image import MAX_IMAGE_PIXELS, max_image_pixels

    monkeypatch.delenv("SHAPETREE_MAX_PIXELS", raising=False)
    assert max_image_pixels() == MAX_IMAGE_PIXELS == 64_000_000
    monkeypatch.setenv("SHAPETREE_MAX_PIXELS", " 1_000 ")
    assert max_image_pixels() == 1000
    for bad in ("0", "-5", "lots", "1.5"):
        monkeypatch.setenv("SHAPETREE_MAX_PIXELS", bad)
        with pytest.raises(ImageError, match="SHAPETREE_MAX_PIXELS must be a positive integer"):
            max_image_pixels()


def test_bomb_is_refused_by_read_grey_and_load_curve(bomb: Path, default_limit: None) -> None:
    from shapetree.curves._image import read_grey

    for reader in (read_grey, curve_from_image, load_curve):
        with pytest.raises(ImageError) as info:
            reader(bomb)
        _assert_one_line_refusal(str(info.value), bomb)
        assert "900,000,000 pixels" in str(info.value)
        assert info.value.__cause__ is None and info.value.__suppress_context__


def test_over_our_limit_under_pillows_is_refused_before_decoding(
    tmp_path: Path, default_limit: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    big = _png_header_only(tmp_path / "big.png", 9000, 8000)  # 72 Mpx: Pillow would decode it

    def no_decoding(self):
        raise AssertionError("decoded an oversized image")

    monkeypatch.setattr(Image.Image, "load", no_decoding)
    monkeypatch.setattr(Image.Image, "convert", no_decoding)
    with pytest.raises(ImageError) as info:
        curve_from_image(big)
    _assert_one_line_refusal(str(info.value), big)
    assert "9000x8000 = 72,000,000 pixels" in str(info.value)


def test_pillow_bomb_warning_becomes_image_error(tmp_path: Path, default_limit: None) -> None:
    import warnings

    from shapetree.curves._image import read_grey

    big = _png_header_only(tmp_path / "warn.png", 10000, 10000)  # over Pillow's warning level
    with pytest.warns(Image.DecompressionBombWarning), pytest.raises(ImageError, match="too large"):
        read_grey(big)
    with warnings.catch_warnings():
        warnings.simplefilter("error", Image.DecompressionBombWarning)
        with pytest.raises(ImageError) as info:
            read_grey(big)
    _assert_one_line_refusal(str(info.value), big)


def test_limit_is_overridable(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from shapetree.curves._image import read_grey

    p = tmp_path / "disc.png"
    Image.fromarray(disc()).save(p)  # 100 x 80 = 8000 px
    monkeypatch.setenv("SHAPETREE_MAX_PIXELS", "7999")
    with pytest.raises(ImageError) as info:
        read_grey(p)
    _assert_one_line_refusal(str(info.value), p, limit="7,999")
    assert "100x80 = 8,000 pixels" in str(info.value)
    monkeypatch.setenv("SHAPETREE_MAX_PIXELS", "8000")
    assert read_grey(p).shape == (80, 100)


def test_limit_above_pillows_ceiling_reaches_pillow(
    bomb: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A raised SHAPETREE_MAX_PIXELS must not be undone by Pillow's own (lower) hard limit."""
    from shapetree.curves._image import open_image

    monkeypatch.setattr(Image, "MAX_IMAGE_PIXELS", Image.MAX_IMAGE_PIXELS)  # restored after
    monkeypatch.setenv("SHAPETREE_MAX_PIXELS", str(30000 * 30000))
    with open_image(bomb) as im:  # opened, not decoded
        assert im.size == (30000, 30000)
    monkeypatch.setenv("SHAPETREE_MAX_PIXELS", str(30000 * 30000 - 1))
    with pytest.raises(ImageError, match="30000x30000"):
        with open_image(bomb):
            pass


def test_raised_limit_silences_pillows_warning(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Images the user allowed (over Pillow's warning level) open without Pillow's warning."""
    import warnings

    from shapetree.curves._image import open_image

    big = _png_header_only(tmp_path / "big.png", 10000, 10000)
    monkeypatch.setattr(Image, "MAX_IMAGE_PIXELS", Image.MAX_IMAGE_PIXELS)  # restored after
    monkeypatch.setenv("SHAPETREE_MAX_PIXELS", "100000000")
    with warnings.catch_warnings():
        warnings.simplefilter("error", Image.DecompressionBombWarning)
        with open_image(big) as im:
            assert im.size == (10000, 10000)


def test_bomb_is_refused_by_detection_loaders(bomb: Path, default_limit: None) -> None:
    from shapetree.detection import load_edges, load_image

    for reader in (load_image, load_edges):
        with pytest.raises(ImageError) as info:
            reader(bomb)
        _assert_one_line_refusal(str(info.value), bomb)


def test_cli_match_bomb_is_one_line_exit_2(
    bomb: Path, default_limit: None, capsys: pytest.CaptureFixture[str]
) -> None:
    from shapetree.cli import main

    assert main(["match", str(bomb), str(bomb)]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("shapetree: error: ")
    _assert_one_line_refusal(lines[0], bomb)
