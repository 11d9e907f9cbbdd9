"""Detection models from drawings: closed outlines, open strokes chained by free chords."""

from __future__ import annotations

import numpy as np
import pytest

from shapetree import ShapeTreeError
from shapetree.detection import load_model, make_model
from shapetree.detection._model import chain_strokes, outline_strokes


def _two_strokes() -> np.ndarray:
    """A 'table': a long open hook and a separate short open stroke below it."""
    img = np.full((120, 160), 255, np.uint8)
    img[20, 20:140] = 0  # top
    img[20:100, 20] = 0  # left leg
    img[20:100, 139] = 0  # right leg
    img[60, 50:110] = 0  # separate inner stroke (40% of the hook's pixels or so)
    img[60:100, 50] = 0
    return img


def test_outline_strokes_keeps_all_open_strokes(tmp_path) -> None:
    strokes, closed = outline_strokes(_two_strokes())
    assert closed is False and len(strokes) == 2
    assert len(strokes[0]) > len(strokes[1])
    from PIL import Image

    path = tmp_path / "table.png"
    Image.fromarray(_two_strokes()).save(path)
    m = load_model(path, m=40, all_strokes=True)
    assert m.closed is False
    # two artificial chords (between the strokes and the closing one) cost no gap
    free = m.gap_weight == 0
    assert 1 <= free.sum() <= 6
    runs = np.sum(free & ~np.roll(free, 1))
    assert runs == 2
    assert m.gap_weight.sum() == pytest.approx(1.0)
    single = load_model(path, m=40, closed=True)  # override: main outline only, closed
    assert single.closed and np.all(single.gap_weight > 0)


def test_chain_strokes_orders_and_flags_chords() -> None:
    a = np.c_[np.linspace(0, 10, 11), np.zeros(11)]
    b = np.c_[np.linspace(30, 12, 10), np.ones(10)]  # its nearer end is its last point
    c = np.c_[np.full(5, 10.5), np.linspace(2, 6, 5)]  # starts next to a's end
    pts, free = chain_strokes([a, b, c])
    assert len(pts) == len(free) == 26
    assert np.allclose(pts[11], c[0])  # c comes after a
    assert np.allclose(pts[16], b[-1])  # then b, reversed
    assert np.flatnonzero(free).tolist() == [10, 15, 25]


def test_make_model_free_segments() -> None:
    sq = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    m = make_model(sq, m=40, free=[False, True, False, False])
    assert m.gap_weight[10:20].sum() == pytest.approx(0.0, abs=1e-12)
    assert m.gap_weight.sum() == pytest.approx(1.0)
    assert np.allclose(m.gap_weight[m.gap_weight > 0], 1 / 30)
    with pytest.raises(ShapeTreeError):
        make_model(sq, free=[True, True])
    with pytest.raises(ShapeTreeError):
        make_model(sq, free=[True] * 4)


def _png_header_only(path, width: int, height: int):
    """A PNG whose header claims ``width x height`` grey pixels (a few hundred bytes)."""
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


def test_model_drawings_obey_the_pixel_limit(tmp_path, monkeypatch) -> None:
    """Model drawings are opened through curves._image.open_image: the size is checked
    from the header, before any pixel is decoded."""
    from shapetree import ImageError

    monkeypatch.delenv("SHAPETREE_MAX_PIXELS", raising=False)
    big = _png_header_only(tmp_path / "model.png", 9000, 8000)  # 72 Mpx > 64 Mpx default
    with pytest.raises(ImageError, match="image too large: 9000x8000"):
        load_model(big)
    monkeypatch.setenv("SHAPETREE_MAX_PIXELS", "100")
    from PIL import Image

    Image.fromarray(_two_strokes()).save(tmp_path / "small.png")  # 160 x 120 > 100 px
    with pytest.raises(ImageError, match="over the limit of 100 pixels"):
        load_model(tmp_path / "small.png")
