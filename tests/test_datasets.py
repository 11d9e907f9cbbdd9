"""Tests of shapetree.datasets loaders against the real data and synthetic broken copies.

The real data are found through ``$SHAPETREE_DATA`` (default ``<repo>/../shared/datasets``,
which CI always provides). Synthetic datasets are built in ``tmp_path`` from numpy arrays;
no dataset file is ever copied.
"""

from __future__ import annotations

import os
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from scipy import ndimage
from skimage.draw import polygon2mask

from shapetree import DatasetError
from shapetree import datasets as ds
from shapetree.curves import signed_area
from shapetree.datasets._registry import ETHZ_CLASSES, REGISTRY, cache_dir, get_spec

REPO = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("SHAPETREE_DATA", str(REPO.parent / "shared" / "datasets")))


@pytest.fixture(scope="module")
def curve_cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One curve cache shared by the module's tests (never the user's)."""
    return tmp_path_factory.mktemp("curve-cache")


@pytest.fixture
def real(monkeypatch: pytest.MonkeyPatch, curve_cache: Path) -> Path:
    """Point SHAPETREE_DATA at the real datasets and SHAPETREE_CACHE at a temp folder."""
    assert DATA.is_dir(), f"real datasets not found at {DATA}; set SHAPETREE_DATA"
    monkeypatch.setenv("SHAPETREE_DATA", str(DATA))
    monkeypatch.setenv("SHAPETREE_CACHE", str(curve_cache))
    return DATA


@pytest.fixture
def tmp_env(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Path:
    """Empty data root and private cache under tmp_path."""
    root = tmp_path / "data"
    root.mkdir()
    monkeypatch.setenv("SHAPETREE_DATA", str(root))
    monkeypatch.setenv("SHAPETREE_CACHE", str(tmp_path / "cache"))
    return root


def _disk_png(path: Path, r: int = 8, size: int = 32, fg: int = 0, bg: int = 255) -> None:
    yy, xx = np.mgrid[:size, :size]
    img = np.where((yy - size / 2) ** 2 + (xx - size / 2) ** 2 <= r * r, fg, bg)
    Image.fromarray(img.astype(np.uint8), mode="L").save(path)


def _make_kimia_like(root: Path, n: int = 4) -> Path:
    folder = root / "kimia99"
    folder.mkdir(parents=True)
    lines = ["filename,class"]
    for i in range(n):
        _disk_png(folder / f"s{i}.png", r=5 + i)
        lines.append(f"s{i}.png,{'a' if i % 2 else 'b'}")
    (folder / "labels.csv").write_text("\n".join(lines) + "\n")
    return folder


def _reference_mask(path: Path) -> np.ndarray:
    """Filled largest 8-connected silhouette, thresholded at 127, inverted if the border is fg."""
    g = np.asarray(Image.open(path).convert("L")) > 127
    border = np.concatenate([g[0], g[-1], g[:, 0], g[:, -1]])
    if border.mean() > 0.5:
        g = ~g
    lab, _ = ndimage.label(g, structure=np.ones((3, 3)))
    big = lab == (np.argmax(np.bincount(lab.ravel())[1:]) + 1)
    return ndimage.binary_fill_holes(big)


# ----------------------------------------------------------------------------- locations


def test_data_dir_env_and_default(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("SHAPETREE_DATA", str(tmp_path))
    assert ds.data_dir() == tmp_path
    monkeypatch.delenv("SHAPETREE_DATA")
    assert ds.data_dir() == Path("~/.cache/shapetree/datasets").expanduser()
    monkeypatch.setenv("SHAPETREE_DATA", "")
    assert ds.data_dir() == Path("~/.cache/shapetree/datasets").expanduser()


def test_cache_dir_env_and_default(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("SHAPETREE_CACHE", str(tmp_path))
    assert cache_dir() == tmp_path / "curves"
    monkeypatch.delenv("SHAPETREE_CACHE")
    assert cache_dir() == Path("~/.cache/shapetree/curves").expanduser()


def test_registry_entries() -> None:
    assert list(REGISTRY) == ["mpeg7", "kimia99", "swedish_leaf", "ethz_shape"]
    expected = {"mpeg7": (1400, 70), "kimia99": (99, 9), "swedish_leaf": (1125, 15)}
    expected["ethz_shape"] = (255, 5)
    for name, (n, k) in expected.items():
        spec = get_spec(name)
        assert (spec.n_images, spec.n_classes) == (n, k)
        assert spec.source.url.startswith("http") and spec.source.citation
        assert spec.description and spec.files
    assert get_spec("mpeg7").source.archive == "rar"
    assert len(get_spec("mpeg7").source.sha256) == 64
    assert len(get_spec("ethz_shape").source.sha1) == 40
    with pytest.raises(DatasetError, match="unknown dataset 'nope'"):
        get_spec("nope")


# ----------------------------------------------------------------------------- available


def test_available_real(real: Path) -> None:
    infos = {i.name: i for i in ds.available()}
    assert set(infos) == set(REGISTRY)
    for info in infos.values():
        assert info.present and info.complete, info
        assert info.count == info.expected
        assert info.path == real / info.name
    table = ds.format_available()
    assert "1400/1400" in table and "99/99" in table and "1125/1125" in table
    assert "255/255" in table and str(real) in table


def test_available_empty(tmp_env: Path) -> None:
    infos = ds.available()
    assert [i.present for i in infos] == [False] * 4
    assert all(i.count == 0 for i in infos)
    table = ds.format_available()
    assert "0/1400" in table and " no " in table


# ----------------------------------------------------------------------------- labels


def test_labels_mpeg7(real: Path) -> None:
    names, labels, images = ds.load_labels("mpeg7")
    assert len(names) == 1400 and images == real / "mpeg7"
    counts = Counter(labels.tolist())
    assert len(counts) == 70 and set(counts.values()) == {20}
    lab = dict(zip(names, labels.tolist(), strict=True))
    assert lab["rat-09.png"] == "rat" and lab["Bone-1.png"] == "Bone"
    assert lab["bottle-01.png"] == "bottle" and lab["cellular_phone-3.png"] == "cellular_phone"


def test_labels_kimia99(real: Path) -> None:
    names, labels, _ = ds.load_labels("kimia99")
    counts = Counter(labels.tolist())
    assert len(names) == 99 and set(counts) == set(get_spec("kimia99").classes)
    assert set(counts.values()) == {11}
    lab = dict(zip(names, labels.tolist(), strict=True))
    assert lab["kk0728.png"] == "ray" and lab["f16.png"] == "airplane"
    assert lab["fgen1ap.png"] == "fgen_mgen" and lab["dude0.png"] == "human"


def test_labels_swedish(real: Path) -> None:
    names, labels, images = ds.load_labels("swedish_leaf")
    assert images == real / "swedish_leaf" / "png512"
    counts = Counter(labels.tolist())
    assert len(names) == 1125 and len(counts) == 15 and set(counts.values()) == {75}
    lab = dict(zip(names, labels.tolist(), strict=True))
    assert lab["l1nr001.png"] == "Ulmus carpinifolia" and lab["l10nr026.png"] == "Sorbus aucuparia"
    assert set(counts) == set(get_spec("swedish_leaf").classes)


# ----------------------------------------------------------------------------- load


def test_load_kimia99_full_and_cache(real: Path, curve_cache: Path) -> None:
    d = ds.load("kimia99", progress=False)
    assert isinstance(d, ds.ShapeDataset) and len(d) == 99
    assert d.images_dir == real / "kimia99" and len(d.classes) == 9
    assert d.labels.dtype.kind == "U" and len(d.labels) == 99
    for c in d.curves:
        assert c.shape == (100, 2) and c.dtype == np.float64 and np.isfinite(c).all()
        assert signed_area(c) > 0  # ccw
        assert not np.allclose(c[0], c[-1])  # closed, endpoint not repeated
    files = list((curve_cache / "curves").glob("kimia99-n100-ccw-*.npz"))
    assert len(files) == 1
    assert not list((curve_cache / "curves").glob(".*"))  # no temp files left
    again = ds.load("kimia99", progress=False)
    assert again.names == d.names
    assert all(np.array_equal(a, b) for a, b in zip(again.curves, d.curves, strict=True))
    cw = ds.load("kimia99", orientation="cw", n_points=64, progress=False, classes=["ray"])
    assert len(cw) == 11 and all(signed_area(c) < 0 and len(c) == 64 for c in cw.curves)


@pytest.mark.parametrize("fname", ["rat-09.png", "Glas-12.png"])
def test_mpeg7_quirky_images(real: Path, fname: str) -> None:
    """rat-09 is inverted and Glas-12 has an inverted palette: both must load as the shape."""
    cls = fname.split("-")[0]
    d = ds.load("mpeg7", classes=[cls], n_points=None, progress=False)
    assert len(d) == 20 and set(d.labels.tolist()) == {cls}
    c = d.curves[d.names.index(fname)]
    ref = _reference_mask(d.images_dir / fname)
    assert abs(signed_area(c) / ref.sum() - 1) < 0.01
    raster = polygon2mask(ref.shape, c[:, ::-1])
    iou = (raster & ref).sum() / (raster | ref).sum()
    assert iou > 0.98
    coarse = ds.load("mpeg7", classes=[cls], n_points=100, progress=False)
    c100 = coarse.curves[coarse.names.index(fname)]
    assert abs(signed_area(c100) / ref.sum() - 1) < 0.03


def test_load_subsets(real: Path) -> None:
    d = ds.load("mpeg7", classes=["Bone", "bottle"], per_class=3, n_points=50, progress=False)
    assert len(d) == 6 and Counter(d.labels.tolist()) == {"Bone": 3, "bottle": 3}
    assert all(c.shape == (50, 2) for c in d.curves)
    s = ds.load("swedish_leaf", classes="Acer", per_class=4, n_points=80, progress=False)
    assert s.names == [f"l2nr00{i}.png" for i in range(1, 5)]
    assert all(c.shape == (80, 2) and signed_area(c) > 0 for c in s.curves)
    with pytest.raises(DatasetError, match="no class"):
        ds.load("mpeg7", classes=["unicorn"], progress=False)


def test_bad_arguments(real: Path) -> None:
    with pytest.raises(DatasetError, match="n_points"):
        ds.load("kimia99", n_points=2, progress=False)
    with pytest.raises(DatasetError, match="orientation"):
        ds.load("kimia99", orientation="up", progress=False)
    with pytest.raises(DatasetError, match="per_class"):
        ds.load("kimia99", per_class=0, progress=False)
    with pytest.raises(DatasetError, match="load_ethz"):
        ds.load("ethz_shape", progress=False)
    with pytest.raises(DatasetError, match="unknown dataset"):
        ds.load("mnist", progress=False)


# ----------------------------------------------------------------------------- failures


def test_missing_dataset_dir(tmp_env: Path) -> None:
    with pytest.raises(DatasetError) as e:
        ds.load("kimia99", progress=False)
    msg = str(e.value)
    assert str(tmp_env / "kimia99") in msg
    assert "shapetree datasets fetch kimia99" in msg and "SHAPETREE_DATA" in msg
    with pytest.raises(DatasetError, match="ethz_shape"):
        ds.load_ethz()


def test_synthetic_loads(tmp_env: Path) -> None:
    _make_kimia_like(tmp_env)
    d = ds.load("kimia99", progress=False, n_points=40)
    assert len(d) == 4 and d.labels.tolist() == ["b", "a", "b", "a"]
    for i, c in enumerate(d.curves):  # disk of radius 5+i
        assert abs(signed_area(c) - np.pi * (5 + i) ** 2) / (np.pi * (5 + i) ** 2) < 0.15


def test_corrupted_image_names_file(tmp_env: Path) -> None:
    folder = _make_kimia_like(tmp_env)
    (folder / "s2.png").write_bytes(b"\x89PNG\r\n\x1a\n this is not a png")
    with pytest.raises(DatasetError, match=r"s2\.png.*cannot read image"):
        ds.load("kimia99", progress=False)


def _png_header_only(path: Path, width: int, height: int) -> None:
    """A tiny PNG whose header claims ``width x height`` grey pixels (a decompression bomb)."""
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr)
    path.write_bytes(png + chunk(b"IDAT", zlib.compress(b"\x00" * 64)) + chunk(b"IEND", b""))


@pytest.mark.parametrize("size", [(30000, 30000), (9000, 8000)])
def test_oversized_image_is_refused_in_one_line(
    tmp_env: Path, monkeypatch: pytest.MonkeyPatch, size: tuple[int, int]
) -> None:
    monkeypatch.delenv("SHAPETREE_MAX_PIXELS", raising=False)
    folder = _make_kimia_like(tmp_env)
    _png_header_only(folder / "s1.png", *size)
    with pytest.raises(DatasetError) as info:
        ds.load("kimia99", progress=False)
    msg = str(info.value)
    assert "\n" not in msg and "s1.png" in msg and "too large" in msg
    assert "64,000,000" in msg and "SHAPETREE_MAX_PIXELS" in msg


def test_blank_image_names_file(tmp_env: Path) -> None:
    folder = _make_kimia_like(tmp_env)
    Image.fromarray(np.full((20, 20), 255, np.uint8)).save(folder / "s1.png")
    with pytest.raises(DatasetError, match=r"s1\.png"):
        ds.load("kimia99", progress=False)


def test_missing_listed_image(tmp_env: Path) -> None:
    folder = _make_kimia_like(tmp_env)
    (folder / "s3.png").unlink()
    with pytest.raises(DatasetError, match=r"missing.*s3\.png"):
        ds.load("kimia99", progress=False)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("name,class\ns0.png,a\n", "no 'filename' column"),
        ("filename,class\n", "lists no images"),
        ("filename,class\ns0.png,a\ns0.png,b\n", "duplicate"),
        ("filename,class\ns0.png,\n", "empty"),
        ("filename,class\n../x.png,a\n", "bad file name"),
    ],
)
def test_bad_labels_csv(tmp_env: Path, text: str, match: str) -> None:
    folder = _make_kimia_like(tmp_env)
    (folder / "labels.csv").write_text(text)
    with pytest.raises(DatasetError, match=match) as e:
        ds.load("kimia99", progress=False)
    assert "labels.csv" in str(e.value)


def test_missing_labels_csv(tmp_env: Path) -> None:
    folder = _make_kimia_like(tmp_env)
    (folder / "labels.csv").unlink()
    with pytest.raises(DatasetError, match=r"labels\.csv.*missing"):
        ds.load("kimia99", progress=False)


def test_mpeg7_labels_from_file_names(tmp_env: Path) -> None:
    folder = tmp_env / "mpeg7"
    folder.mkdir()
    for n in ("cup-1.png", "cup-02.png", "sea_snake-3.png"):
        _disk_png(folder / n, fg=255, bg=0)
    names, labels, _ = ds.load_labels("mpeg7")
    assert dict(zip(names, labels.tolist(), strict=True)) == {
        "cup-02.png": "cup",
        "cup-1.png": "cup",
        "sea_snake-3.png": "sea_snake",
    }


def test_changed_file_invalidates_cache_and_corrupt_cache_is_ignored(tmp_env: Path) -> None:
    folder = _make_kimia_like(tmp_env)
    a = ds.load("kimia99", progress=False, n_points=30)
    _disk_png(folder / "s0.png", r=12)
    os.utime(folder / "s0.png", ns=(1, 1))
    b = ds.load("kimia99", progress=False, n_points=30)
    assert signed_area(b.curves[0]) > 2 * signed_area(a.curves[0])
    for f in cache_dir().glob("*.npz"):
        f.write_bytes(b"garbage")
    with pytest.warns(UserWarning, match="curve cache"):
        c = ds.load("kimia99", progress=False, n_points=30)
    assert all(np.array_equal(x, y) for x, y in zip(b.curves, c.curves, strict=True))
    d = ds.load("kimia99", progress=False, n_points=30, cache=False)
    assert all(np.array_equal(x, y) for x, y in zip(b.curves, d.curves, strict=True))


# ----------------------------------------------------------------------------- ETHZ


def test_ethz_real(real: Path) -> None:
    images = ds.load_ethz()
    assert len(images) == 255
    assert sum(len(i.boxes) for i in images) == 289
    per_class = Counter(i.class_name for i in images)
    assert per_class == {"Applelogos": 40, "Bottles": 48, "Giraffes": 87, "Mugs": 48, "Swans": 32}
    boxes = Counter()
    for im in images:
        boxes[im.class_name] += len(im.boxes)
        assert im.image_path.is_file() and im.edges_path.is_file()
        assert im.edges_path.name == f"{im.stem}_edges.tif"
        assert im.boxes.dtype == np.float64 and im.boxes.shape[1] == 4
        assert (im.boxes[:, 2] > im.boxes[:, 0]).all() and (im.boxes[:, 3] > im.boxes[:, 1]).all()
    assert boxes == {"Applelogos": 44, "Bottles": 55, "Giraffes": 91, "Mugs": 66, "Swans": 33}
    another = next(i for i in images if i.stem == "another")
    assert another.boxes.tolist() == [[104, 34, 282, 286]]
    # the boxes are the very ones evaluate_ethz scores against, fractions included
    from shapetree.datasets._ethz import ethz_root
    from shapetree.detection._ethz_eval import _gt_boxes

    root = ethz_root()
    for im in images:
        tag = ETHZ_CLASSES[im.class_name][0]
        assert np.array_equal(im.boxes, _gt_boxes(root, im.class_name, im.stem, tag)), im.stem
    grey = next(i for i in images if i.stem == "grey" and i.class_name == "Applelogos")
    assert grey.boxes.tolist() == [[690.5, 239.8333, 909.1667, 490.5]]
    for cls, stem in [("Applelogos", "applelogo"), ("bottles", "bottle"), ("giraffe", "giraffe")]:
        assert ds.ethz_model_path(cls) == real / "ethz_shape/ETHZShapeClasses-V1.2/models" / (
            stem + ".tif"
        )
    assert ds.ethz_model_path("SWANS").is_file() and ds.ethz_model_path("Mugs").is_file()
    with pytest.raises(DatasetError, match="unknown ETHZ class"):
        ds.ethz_model_path("cars")
    # root may be the V1.2 folder itself; classes= filters
    sub = ds.load_ethz(real / "ethz_shape" / "ETHZShapeClasses-V1.2", classes=["swans"])
    assert len(sub) == 32 and {i.class_name for i in sub} == {"Swans"}


def _make_ethz_like(root: Path) -> Path:
    base = root / "ethz_shape" / "ETHZShapeClasses-V1.2"
    for cls, (tag, model) in ETHZ_CLASSES.items():
        (base / cls).mkdir(parents=True)
        Image.fromarray(np.zeros((20, 30, 3), np.uint8)).save(base / cls / "im.jpg")
        Image.fromarray(np.zeros((20, 30), np.uint8)).save(base / cls / "im_edges.tif")
        (base / cls / f"im_{tag}.groundtruth").write_text("1 2 10 12 \n3 4 20.4 15 \n")
        (base / "models").mkdir(exist_ok=True)
        Image.fromarray(np.ones((8, 8), bool)).save(base / "models" / f"{model}.tif")
    return base


def test_ethz_synthetic_and_bad_groundtruth(tmp_env: Path) -> None:
    base = _make_ethz_like(tmp_env)
    images = ds.load_ethz()
    # fractional values are kept as the file gives them
    assert len(images) == 5 and images[0].boxes.tolist() == [[1, 2, 10, 12], [3, 4, 20.4, 15]]
    gt = base / "Mugs" / "im_mugs.groundtruth"
    gt.write_text("1 2 3\n")
    with pytest.raises(DatasetError, match=r"im_mugs\.groundtruth.*3 values"):
        ds.load_ethz()
    gt.write_text("1 2 x 4\n")
    with pytest.raises(DatasetError, match=r"im_mugs\.groundtruth.*not numeric"):
        ds.load_ethz()
    gt.write_text("5 5 4 9\n")
    with pytest.raises(DatasetError, match=r"im_mugs\.groundtruth.*empty box"):
        ds.load_ethz()
    gt.unlink()
    with pytest.raises(DatasetError, match=r"im_mugs\.groundtruth.*missing"):
        ds.load_ethz()
    (base / "Swans" / "im_edges.tif").unlink()
    with pytest.raises(DatasetError, match=r"im_edges\.tif.*missing"):
        ds.load_ethz(classes=["Swans"])
    (base / "models" / "giraffe.tif").unlink()
    with pytest.raises(DatasetError, match=r"giraffe\.tif.*missing"):
        ds.ethz_model_path("Giraffes")
