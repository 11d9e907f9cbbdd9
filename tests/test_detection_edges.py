"""Edge maps and contour tracing on images the tests draw themselves."""

from __future__ import annotations

import numpy as np
import pytest

from shapetree import ImageError, ShapeTreeError
from shapetree.detection import edge_map, load_edges, trace_contours


def _disc_image(h: int = 120, w: int = 140, r: float = 40.0) -> tuple[np.ndarray, float, float]:
    yy, xx = np.mgrid[0:h, 0:w]
    cx, cy = 70.0, 60.0
    inside = (xx - cx) ** 2 + (yy - cy) ** 2 <= r**2
    img = np.zeros((h, w, 3))
    img[...] = (0.2, 0.3, 0.8)
    img[inside] = (0.9, 0.7, 0.1)
    return img, cx, cy


def test_edge_map_peaks_on_drawn_boundary() -> None:
    img, cx, cy = _disc_image()
    e = edge_map(img)
    assert e.shape == img.shape[:2]
    assert e.min() >= 0.0 and e.max() <= 1.0
    yy, xx = np.nonzero(e > 0.5)
    d = np.hypot(xx - cx, yy - cy)
    # strong responses lie on the circle of radius 40 (within 2 px) ...
    assert np.all(np.abs(d - 40.0) < 2.5)
    # ... and cover most of it
    ang = np.arctan2(yy - cy, xx - cx)
    assert len(np.unique(np.round(ang * 20))) > 0.8 * 2 * np.pi * 20
    # thinned: at most a few pixels per ray
    assert (e > 0.5).sum() < 2 * np.pi * 40 * 2.0
    # flat regions respond nothing
    assert e[60, 70] == 0.0 and e[5, 5] == 0.0


def test_edge_map_blank_and_grey_and_errors() -> None:
    assert np.all(edge_map(np.full((20, 30), 0.5)) == 0)
    g = np.zeros((40, 40), np.uint8)
    g[:, 20:] = 200
    e = edge_map(g)
    assert e[:, 19:21].max() == pytest.approx(1.0)
    with pytest.raises(ImageError):
        edge_map(np.zeros((2, 2)))
    with pytest.raises(ImageError):
        edge_map(np.full((10, 10), np.nan))
    with pytest.raises(ShapeTreeError):
        edge_map(g, method="canny")


def test_load_image_names_a_too_small_file(tmp_path) -> None:
    from PIL import Image

    from shapetree.detection import load_image

    Image.new("RGB", (2, 5)).save(tmp_path / "tiny.png")
    with pytest.raises(ImageError, match=r"tiny\.png is 2x5 pixels; at least 3x3"):
        load_image(tmp_path / "tiny.png")
    Image.new("L", (3, 4), 128).save(tmp_path / "ok.png")
    im = load_image(tmp_path / "ok.png")
    assert im.shape == (4, 3, 3) and np.allclose(im, 128 / 255)


def test_load_edges_reads_8bit(tmp_path) -> None:
    from PIL import Image

    a = np.zeros((10, 12), np.uint8)
    a[3, 4] = 255
    a[5, 6] = 51
    Image.fromarray(a).save(tmp_path / "e.tif")
    e = load_edges(tmp_path / "e.tif")
    assert e.shape == (10, 12) and e[3, 4] == 1.0 and e[5, 6] == pytest.approx(0.2)
    with pytest.raises(ImageError):
        load_edges(tmp_path / "missing.tif")


def test_trace_circle_is_one_long_chain() -> None:
    img, cx, cy = _disc_image()
    cs = trace_contours(edge_map(img), min_length=20)
    assert len(cs) >= 1
    lengths = [np.sum(np.hypot(*np.diff(c, axis=0).T)) for c in cs]
    # a loop is opened and cut in two at the farthest pixel: two halves ~ 126 px each
    assert sum(sorted(lengths)[-2:]) > 0.9 * 2 * np.pi * 40
    assert max(lengths) > 0.4 * 2 * np.pi * 40
    for c in cs:
        d = np.hypot(c[:, 0] - cx, c[:, 1] - cy)
        assert np.all(np.abs(d - 40) < 2.5)
        # uniform spacing ~5 px
        sp = np.hypot(*np.diff(c, axis=0).T)
        assert np.allclose(sp, sp.mean(), rtol=0.05) and 3.5 < sp.mean() < 6.5


def test_trace_breaks_at_sharp_corner() -> None:
    e = np.zeros((100, 100))
    e[20, 20:81] = 0.8  # horizontal arm
    e[20:81, 80] = 0.8  # vertical arm: a right-angle corner at (x=80, y=20)
    cs = trace_contours(e, min_length=10)
    assert len(cs) == 2
    ends = np.array([c[[0, -1]] for c in cs]).reshape(-1, 2)
    # both pieces end at the corner
    assert (np.hypot(ends[:, 0] - 80, ends[:, 1] - 20) < 3).sum() == 2
    for c in cs:
        assert np.sum(np.hypot(*np.diff(c, axis=0).T)) > 50
    # a gentle arc is not broken
    t = np.linspace(0, np.pi / 2, 200)
    arc = np.zeros((100, 100))
    arc[np.round(10 + 70 * np.sin(t)).astype(int), np.round(10 + 70 * np.cos(t)).astype(int)] = 1
    assert len(trace_contours(arc, min_length=10)) == 1


def test_trace_junction_splits_and_short_dropped() -> None:
    e = np.zeros((80, 80))
    e[40, 5:75] = 0.9
    e[5:40, 40] = 0.9  # T junction
    e[70, 10:15] = 0.9  # too short
    cs = trace_contours(e, min_length=15, n_points=10)
    assert len(cs) == 3
    assert all(len(c) == 10 for c in cs)
    ends = np.array([c[[0, -1]] for c in cs]).reshape(-1, 2)
    assert (np.hypot(ends[:, 0] - 40, ends[:, 1] - 40) < 2).sum() == 3
    with pytest.raises(ShapeTreeError):
        trace_contours(e, threshold=2.0)
    with pytest.raises(ImageError):
        trace_contours(np.zeros(5))
    assert trace_contours(np.zeros((10, 10))) == []
