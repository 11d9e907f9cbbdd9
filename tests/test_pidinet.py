"""PiDiNet edge maps (detection/_pidinet.py): the authors' outputs, the converted kernels,
thinning, the weights option everywhere and its errors, and the once-per-image edge cache.

The weights and reference outputs are research-use data kept outside the repository
(``$SHAPETREE_DATA/../models/pidinet``, i.e. ``../shared/models/pidinet`` in CI); the
tests that need them are skipped, with the reason, when that folder is absent.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from shapetree import ShapeTreeError
from shapetree.detection import DetectParams, edge_map, load_image
from shapetree.detection import _pidinet as pid
from shapetree.detection._pidinet import load_pidinet, pdc_kernel, thin_ridges

_DEFAULT = Path(__file__).resolve().parents[1] / ".." / "shared" / "datasets"
DATA = Path(os.environ.get("SHAPETREE_DATA", _DEFAULT))
MODELS = DATA.parent / "models" / "pidinet"
REFERENCE = MODELS / "reference"
CROP = "Mugs_apple_crop320x296"
VARIANTS = [
    "table5_pidinet",
    "table5_pidinet-small",
    "table5_pidinet-tiny",
    "table5_pidinet-l",
    "table5_pidinet-small-l",
    "table5_pidinet-tiny-l",
]
needs_models = pytest.mark.skipif(
    not (MODELS / "table5_pidinet-tiny.npz").is_file(),
    reason=f"PiDiNet weights not available (research-use data, expected in {MODELS})",
)
ETHZ = DATA / "ethz_shape" / "ETHZShapeClasses-V1.2"
needs_ethz = pytest.mark.skipif(not (ETHZ / "models").is_dir(), reason="ETHZ data not available")
TINY = MODELS / "table5_pidinet-tiny.npz"


@needs_models
@pytest.mark.parametrize("variant", VARIANTS)
def test_network_matches_the_authors_reference_output(variant: str) -> None:
    """Every checkpoint's fused map on the reference crop equals the authors' to <= 1e-4."""
    net = load_pidinet(MODELS / f"{variant}.npz")
    assert net.variant == variant.removeprefix("table5_")
    assert net.sa_dil == (not variant.endswith("-l"))
    image = load_image(REFERENCE / f"{CROP}.png")
    ref = np.load(REFERENCE / f"{variant}__{CROP}.npy")
    out = net(image)
    assert out.shape == ref.shape == (320, 296) and out.dtype == np.float32
    assert float(np.abs(out - ref).max()) <= 1e-4


# --------------------------------------------------------------------------- kernels
_RING = [0, 1, 2, 5, 8, 7, 6, 3]  # the 3x3 neighbours, clockwise from the top left
_DIRS = [(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)]


def _direct_pdc(x: np.ndarray, w: np.ndarray, kind: str) -> np.ndarray:
    """Pixel-difference convolutions by their definitions (zero padding), one channel.

    cv: Σ_j w_j x_j; cd: Σ_j w_j (x_j - x_centre); ad: Σ_j w_j (x_j - x_next(j)) over the
    ring of neighbours, next = clockwise; rd: Σ_k w_k (x[c + 2 d_k] - x[c + d_k]) over the
    8 directions d_k (row-major), w_k the stored entries 1..8.
    """
    h, wd = x.shape
    xp = np.pad(x, 2)
    wf = w.ravel()
    out = np.zeros((h, wd))
    for r in range(h):
        for c in range(wd):
            patch = xp[r + 1 : r + 4, c + 1 : c + 4].ravel()  # 3x3 around (r, c)
            if kind == "cv":
                v = float(np.dot(wf, patch))
            elif kind == "cd":
                v = float(sum(wf[j] * (patch[j] - patch[4]) for j in range(9)))
            elif kind == "ad":
                v = 0.0
                for i, j in enumerate(_RING):
                    nxt = _RING[(i + 1) % 8]
                    v += wf[j] * (patch[j] - patch[nxt])
            else:  # rd
                v = 0.0
                for k, (dy, dx) in enumerate(_DIRS):
                    outer = xp[r + 2 + 2 * dy, c + 2 + 2 * dx]
                    inner = xp[r + 2 + dy, c + 2 + dx]
                    v += wf[k + 1] * (outer - inner)
            out[r, c] = v
    return out


@pytest.mark.parametrize("kind", ["cv", "cd", "ad", "rd"])
def test_converted_kernels_equal_the_pixel_difference_definitions(kind: str) -> None:
    """The plain kernel of each PDC type, run as a depthwise and as a full convolution,
    equals the pixel-difference definition computed directly on a small image."""
    rng = np.random.default_rng(3)
    x = rng.normal(size=(7, 6)).astype(np.float32)
    w = rng.normal(size=(1, 1, 3, 3)).astype(np.float32)
    k = pdc_kernel(w, kind)
    assert k.shape == ((1, 1, 5, 5) if kind == "rd" else (1, 1, 3, 3))
    if kind == "ad":
        assert k[0, 0, 1, 1] == 0.0
    want = _direct_pdc(x.astype(np.float64), w[0, 0].astype(np.float64), kind)
    got_dw = pid._conv_depthwise(x[None], k)[0]
    got_full = pid._conv_full(x[None], k)[0]
    np.testing.assert_allclose(got_dw, want, atol=1e-5)
    np.testing.assert_allclose(got_full, want, atol=1e-5)


def test_pdc_kernel_refuses_bad_input() -> None:
    with pytest.raises(ShapeTreeError, match="unknown PDC type"):
        pdc_kernel(np.zeros((1, 1, 3, 3)), "xx")
    with pytest.raises(ShapeTreeError, match=r"\(out, in, 3, 3\)"):
        pdc_kernel(np.zeros((1, 1, 5, 5)), "cd")


def test_dilated_full_conv_equals_a_direct_sum() -> None:
    """The shifted-product full convolution with dilation (CDCM) against a direct loop."""
    rng = np.random.default_rng(4)
    x = rng.normal(size=(2, 9, 8)).astype(np.float32)
    k = rng.normal(size=(3, 2, 3, 3)).astype(np.float32)
    d = 2
    xp = np.pad(x.astype(np.float64), ((0, 0), (d, d), (d, d)))
    want = np.zeros((3, 9, 8))
    for o in range(3):
        for r in range(9):
            for c in range(8):
                for a in range(3):
                    for b in range(3):
                        want[o, r, c] += np.dot(k[o, :, a, b], xp[:, r + a * d, c + b * d])
    np.testing.assert_allclose(pid._conv_full(x, k, d), want, atol=1e-4)


def test_upsample_matches_align_corners_false() -> None:
    """Bilinear resize, align_corners=False: a 2x2 -> 4x4 example worked by hand."""
    x = np.array([[0.0, 1.0], [2.0, 3.0]], np.float32)
    up = pid._upsample(x, 4, 4)
    np.testing.assert_allclose(up[0], [0.0, 0.25, 0.75, 1.0], atol=1e-6)
    np.testing.assert_allclose(up[:, 0], [0.0, 0.5, 1.5, 2.0], atol=1e-6)


# --------------------------------------------------------------------------- thinning
@pytest.mark.parametrize("width", [5, 6, 9])
def test_thinning_leaves_a_one_pixel_line_for_a_thick_ridge(width: int) -> None:
    """A flat-topped vertical ridge of any width keeps exactly one pixel per row, in its
    middle; a thick diagonal (Gaussian) ridge one pixel per row too; the flat background
    none."""
    e = np.zeros((40, 40))
    e[:, 15 : 15 + width] = 0.9
    t = thin_ridges(e)
    rows = t[4:-4]
    assert np.all((rows > 0).sum(axis=1) == 1)
    cols = np.flatnonzero(rows[10])
    assert abs(cols[0] - (15 + (width - 1) / 2)) <= 0.5
    assert np.all(rows[rows > 0] == 0.9)  # the kept pixels carry the map's value
    yy, xx = np.mgrid[0:40, 0:40]
    diag = np.exp(-(((xx - yy) / np.sqrt(2)) ** 2) / 8.0)
    td = thin_ridges(diag)[6:-6, 6:-6]
    assert np.all((td > 0.5).sum(axis=1) == 1)
    assert not thin_ridges(np.zeros((20, 20))).any()


def test_fixed_map_is_monotone_onto_unit_interval() -> None:
    xs, ys = zip(*pid.P_KNOTS, strict=True)
    assert xs[0] == 0.0 and ys[0] == 0.0 and xs[-1] == 1.0 and ys[-1] == 1.0
    assert np.all(np.diff(xs) > 0) and np.all(np.diff(ys) > 0)
    p = np.linspace(0, 1, 11)[None, :].repeat(3, 0)
    out = pid.edges_from_probability(p, thin=False, floor=0.0)
    assert np.all(np.diff(out[0]) > 0) and out.min() == 0.0 and out.max() == 1.0


# --------------------------------------------------------------------------- errors
def _check_message(exc: pytest.ExceptionInfo) -> None:
    msg = str(exc.value)
    assert "research use" in msg and "hellozhuo/pidinet" in msg


def test_clear_errors_for_bad_weights(tmp_path: Path) -> None:
    """No weights, a missing file, a torch checkpoint, a non-npz, wrong keys, wrong shapes:
    each a ShapeTreeError that names the problem and says where the weights come from."""
    img = np.zeros((12, 12, 3))
    with pytest.raises(ShapeTreeError, match="needs a weights file") as exc:
        edge_map(img, method="pidinet")
    _check_message(exc)
    with pytest.raises(ShapeTreeError, match="not found") as exc:
        edge_map(img, method="pidinet", weights=tmp_path / "nope.npz")
    _check_message(exc)
    pth = tmp_path / "table5_pidinet.pth"
    pth.write_bytes(b"PK\x03\x04 not really")
    with pytest.raises(ShapeTreeError, match="torch checkpoint") as exc:
        load_pidinet(pth)
    _check_message(exc)
    junk = tmp_path / "junk.npz"
    junk.write_text("hello")  # an image or a text file given by mistake
    with pytest.raises(ShapeTreeError, match="not an .npz archive") as exc:
        load_pidinet(junk)
    _check_message(exc)
    broken = tmp_path / "broken.npz"
    broken.write_bytes(b"PK\x03\x04" + b"\0" * 40)  # a damaged archive
    with pytest.raises(ShapeTreeError, match="cannot read PiDiNet weights") as exc:
        load_pidinet(broken)
    _check_message(exc)
    other = tmp_path / "other.npz"
    np.savez(other, something=np.zeros(3))
    with pytest.raises(ShapeTreeError, match="no 'init_block.weight'") as exc:
        load_pidinet(other)
    _check_message(exc)
    partial = tmp_path / "partial.npz"
    np.savez(partial, **{"init_block.weight": np.zeros((20, 3, 3, 3), np.float32)})
    with pytest.raises(ShapeTreeError, match="'block1_1.conv1.weight' is missing"):
        load_pidinet(partial)
    with pytest.raises(ShapeTreeError, match="weights= is for edge method 'pidinet'"):
        edge_map(img, method="own", weights=partial)


@needs_models
def test_wrong_shapes_and_extra_keys_are_refused(tmp_path: Path) -> None:
    with np.load(TINY) as z:
        arrays = {k: z[k] for k in z.files}
    bad = dict(arrays)
    bad["classifier.weight"] = np.zeros((1, 5, 1, 1), np.float32)
    np.savez(tmp_path / "bad.npz", **bad)
    with pytest.raises(ShapeTreeError, match=r"'classifier.weight' has shape \(1, 5, 1, 1\)"):
        load_pidinet(tmp_path / "bad.npz")
    np.savez(tmp_path / "extra.npz", **arrays, surplus=np.zeros(2))
    with pytest.raises(ShapeTreeError, match="unexpected arrays"):
        load_pidinet(tmp_path / "extra.npz")
    # the torch-style 'module.' prefix is accepted
    np.savez(tmp_path / "module.npz", **{f"module.{k}": v for k, v in arrays.items()})
    assert load_pidinet(tmp_path / "module.npz").variant == "pidinet-tiny"


def test_detect_params_validate_the_weights_option(tmp_path: Path) -> None:
    """One field, checked when the parameters are made; left out of as_dict when unset, so
    every existing cache key (the Pb runs') stays the same."""
    assert "edge_weights" not in DetectParams().as_dict()
    with pytest.raises(ShapeTreeError, match="needs a weights file") as exc:
        DetectParams(edge_method="pidinet")
    _check_message(exc)
    with pytest.raises(ShapeTreeError, match="not found"):
        DetectParams(edge_method="pidinet", edge_weights=str(tmp_path / "x.npz"))
    with pytest.raises(ShapeTreeError, match="edge_weights is for edge_method"):
        DetectParams(edge_weights=str(tmp_path / "x.npz"))
    with pytest.raises(ShapeTreeError, match="must be a file path"):
        DetectParams(edge_method="pidinet", edge_weights=3)


@needs_ethz
def test_evaluate_ethz_refuses_bad_weights(tmp_path: Path) -> None:
    from shapetree.detection import evaluate_ethz

    with pytest.raises(ShapeTreeError, match="needs a weights file"):
        evaluate_ethz(DATA, edges="pidinet", cache_dir=tmp_path, progress=False)
    with pytest.raises(ShapeTreeError, match="edge_weights is for edges='pidinet'"):
        evaluate_ethz(DATA, edges="own", edge_weights=TINY, cache_dir=tmp_path, progress=False)


def test_cli_bad_weights_is_an_error_not_a_traceback(tmp_path: Path, capsys) -> None:
    from PIL import Image

    from shapetree.cli import main

    Image.new("RGB", (40, 30), (200, 200, 200)).save(tmp_path / "photo.png")
    model = tmp_path / "m.csv"
    model.write_text("0,0\n10,0\n10,10\n0,10\n")
    missing = tmp_path / "missing.npz"
    for argv in (
        ["detect", model, tmp_path / "photo.png", "-o", tmp_path / "out", "--edges", "pidinet"],
        ["detect", model, tmp_path / "photo.png", "-o", tmp_path / "out", "--edges", "pidinet",
         "--edge-weights", missing],
        ["detect", model, tmp_path / "photo.png", "-o", tmp_path / "p.png", "--edges", "pidinet",
         "--edge-weights", missing],
        ["evaluate", "ethz", "--edges", "pidinet", "--edge-weights", missing],
    ):  # fmt: skip
        code = main([str(a) for a in argv])
        _out, err = capsys.readouterr()
        assert code != 0
        assert "Traceback" not in err and "research use" in err, err


# --------------------------------------------------------------------------- use
@needs_models
def test_edge_map_pidinet_is_thin_and_on_the_unit_scale() -> None:
    """edge_map(method="pidinet") on part of the reference crop: values in [0, 1], thinned
    (under half the thick map's pixels, never above it), the outlines above the tracer's
    0.15 on a few % of the pixels, as in the Pb maps (about 1.5%)."""
    image = load_image(REFERENCE / f"{CROP}.png")[:200, :180]
    e = edge_map(image, method="pidinet", weights=TINY)
    thick = edge_map(image, method="pidinet", weights=TINY, thin=False)
    assert e.shape == (200, 180) and e.min() >= 0.0 and e.max() <= 1.0
    assert np.all(e <= thick + 1e-12) and (e > 0).sum() < 0.5 * (thick > 0).sum()
    share = float((e > 0.15).mean())
    assert 0.003 < share < 0.08
    # grey images run too (replicated to RGB)
    assert edge_map(image[:40, :50].mean(axis=2), method="pidinet", weights=TINY).shape == (40, 50)


@needs_models
def test_detect_with_pidinet_edges_through_params(tmp_path: Path) -> None:
    """detect / detect_images take the weights from DetectParams.edge_weights, and the
    batch record names the method and the weights' hash."""
    import json

    from PIL import Image, ImageDraw

    from shapetree.detection import make_model
    from shapetree.detection._photos import detect_images

    im = Image.new("RGB", (90, 80), (230, 230, 230))
    ImageDraw.Draw(im).ellipse((20, 15, 70, 65), fill=(40, 40, 160))
    im.save(tmp_path / "disc.png")
    t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    circle = make_model(np.c_[np.cos(t), np.sin(t)] * 20, m=30)
    p = DetectParams(edge_method="pidinet", edge_weights=str(TINY))
    summary = detect_images(
        circle, [tmp_path / "disc.png"], out_dir=tmp_path / "out", pictures=False,
        edges="pidinet", params=p, k=1, progress=False,
    )  # fmt: skip
    rec = json.loads((tmp_path / "out" / "disc.json").read_text())
    assert summary.failed == 0 and rec["status"] == "ok"
    assert rec["edges"]["method"] == "pidinet"
    assert rec["edges"]["weights_sha256"] == load_pidinet(TINY).sha256
    box = rec["detections"][0]["bbox"]
    assert abs((box[0] + box[2]) / 2 - 45) < 6 and abs((box[1] + box[3]) / 2 - 40) < 6


@needs_ethz
def test_ethz_computed_edges_once_per_image(tmp_path: Path, monkeypatch) -> None:
    """evaluate_ethz computes a computed edge map once per image (not per model), caches it
    by method and edge code, reads it back on a second run, and keeps the results equal."""
    import shapetree.detection._edges as edges_mod
    import shapetree.detection._ethz_eval as ev

    calls: list[tuple] = []
    real = edges_mod.edge_map

    def counting(image, **kw):
        calls.append(np.asarray(image).shape)
        return real(image, **kw)

    monkeypatch.setattr(edges_mod, "edge_map", counting)
    kw = dict(
        classes=["swans", "applelogos"], images=[("Swans", "aal"), ("Applelogos", "another")],
        k=2, workers=1, progress=False, edges="own", cache_dir=tmp_path,
    )  # fmt: skip
    first = ev.evaluate_ethz(DATA, **kw)
    assert len(calls) == 2  # two images, two models each: two edge maps
    files = sorted(p.name for p in Path(first["edge_cache_dir"]).glob("*.npz"))
    assert files == ["Applelogos__another.npz", "Swans__aal.npz"]
    assert first["edge_map_seconds_median"] > 0
    # the map's time is shared by the two models of its image, in the "edges" stage
    assert first["seconds_breakdown_median"]["edges"] >= 0.5 * first["edge_map_seconds_median"] / 2
    again = ev.evaluate_ethz(DATA, **kw)
    assert len(calls) == 2 and again["overlap_20"] == first["overlap_20"]
    # the Pb key stays the historical formula (no edge source, no edge_weights, and none
    # of the collection stage's fields, which never change a cached detection)
    import hashlib
    import json

    fields = DetectParams().as_dict(collection=False)
    assert "appearance_check" not in fields and "edge_method" in fields
    doc = {"params": fields, "k": 5, "code": ev.code_fingerprint()}
    blob = json.dumps(doc, sort_keys=True).encode()
    assert ev._params_key(DetectParams(), 5, "pb") == hashlib.sha256(blob).hexdigest()[:16]
