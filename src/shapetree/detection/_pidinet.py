"""PiDiNet, a learned edge detector the user points to (``edge_map(method="pidinet")``).

Su et al., *Pixel Difference Networks for Efficient Edge Detection*, ICCV 2021
(arXiv:2108.07009).  This module runs the authors' BSDS500 checkpoints ("table5" models,
config ``carv4``) with NumPy / SciPy only, in float32, from ``.npz`` copies of their
state dicts (no torch).  It was written from a clean-room description of the
architecture (``shared/models/pidinet/README.md``); no code of the authors is used.

Weights and licence
-------------------
The weights are **not** part of shapetree and are never shipped with it.  They are the
files ``table5_pidinet{,-small,-tiny}{,-l}.pth`` of the repository ``hellozhuo/pidinet``
(folder ``trained_models/``), converted to ``.npz`` (the state dict's arrays under their
names without the ``module.`` prefix).  Their licence is the MIT text preceded by *"It
is just for research purpose, and commercial use should be contacted with authors
first"*: treat them as research-use-only data.  They were trained on BSDS500 (plus the
PASCAL VOC augmentation of RCF), not on ETHZ.

Network (input ``(3, H, W)`` float32, any ``H, W >= 1``)
-----------------------------------------------------------
RGB in ``[0, 1]`` normalised by the ImageNet mean / std.  ``C`` = 60 / 30 / 20 channels
(full / small / tiny; read from the weights).  Every pixel-difference convolution (PDC)
is replaced once, at load time, by the plain kernel it equals (:func:`pdc_kernel`):

* ``init_block``: a full 3x3 conv 3 -> C of type ``cd``;
* 4 stages of residual blocks (3, 4, 4, 4 blocks; C, 2C, 4C, 4C channels; the first
  block of stages 2-4 max-pools 2x2 and has a 1x1 ``shortcut`` with bias): depthwise PDC
  (type ``[cd, ad, rd, cv][layer % 4]``; ``rd`` is a 5x5 kernel) -> ReLU -> 1x1 conv ->
  + input;
* per stage output, with ``sa+dil`` weights (``dilations.*`` keys): CDCM (ReLU, 1x1 conv
  to ``d`` channels, four 3x3 convs of dilation 5, 7, 9, 11 summed) then CSAM (``x *
  sigmoid(conv3x3(conv1x1(relu(x))))``); ``-l`` weights have neither;
* ``conv_reduces.i``: 1x1 conv to one channel, bilinear upsampling to ``(H, W)``
  (``align_corners=False``); ``classifier``: 1x1 conv of the four maps; sigmoid of all
  five.  The fused (fifth) map is the boundary probability, shape ``(H, W)``.

Full convolutions are shifted matrix products (one BLAS ``matmul`` per kernel tap),
depthwise ones shifted multiply-adds.  On the authors' reference crop (ETHZ
``Mugs/apple.jpg``, 320 x 296) the fused map of each of the six checkpoints equals theirs
to 2e-6 - 9e-6, max abs difference (``tests/test_pidinet.py`` asserts 1e-4).  Speed: the
full model takes about 3 s for a 320 x 296 image on 2 CPU cores (0.9 s tiny), and grows
with the pixel count; images over ``MAX_SIDE`` px run reduced.

Thinning and scale (:func:`pidinet_edges`)
------------------------------------------
The fused map is thick (a boundary is 3-8 px wide).  It is thinned by non-maximum
suppression across the ridge: the normal is the eigenvector of the most negative
eigenvalue of the Hessian of the map smoothed with a Gaussian of ``ORIENT_SIGMA`` px; a
pixel is kept where the map smoothed with ``VALUE_SIGMA`` px is larger than its
neighbour one pixel ahead along the normal and not smaller than the one behind
(bilinear interpolation; the strict side breaks ties on flat tops, so a ridge of even
width keeps one pixel).  The kept pixels carry the unsmoothed probability ``P``, mapped
by a fixed monotone function, piecewise linear through the knots ``P_KNOTS``, with
values under ``floor`` set to 0; no per-image normalisation.  The knots were set once
(``benchmarks/eval_ethz.py --calibrate-pidinet``, with ``table5_pidinet``) on 10 ETHZ
images, the first two of each class in file order (``Applelogos/another``,
``Applelogos/bigwindow``, ``Bottles/Chardonnay``, ``Bottles/acaw``, ``Giraffes/african``,
``Giraffes/amsterdam``, ``Mugs/apple``, ``Mugs/blue``, ``Swans/aal``, ``Swans/big``): the
median share of pixels above 0.05, 0.15, 0.3 and 0.5 in the shipped Pb maps (2.9%,
1.5%, 1.1%, 0.75%) is reached by ``P`` above 0.37, 0.77, 0.84 and 0.91, which map to
those four values (plus ``0 -> 0`` and ``1 -> 1``), so the contour tracer's thresholds,
chosen on Pb, mean the same here.  (A line through the four pairs, as the own map's
``E_OFFSET`` / ``E_RANGE``, misses the share above 0.5 by 30 times: the sigmoid output
saturates.)  No ground-truth boxes were used.
"""

from __future__ import annotations

import hashlib
import os
import threading
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

from shapetree._errors import ShapeTreeError

__all__ = [
    "PDC_TYPES",
    "PiDiNet",
    "load_pidinet",
    "check_weights",
    "weights_sha256",
    "pdc_kernel",
    "pidinet_edges",
    "fused_probability",
    "edges_from_probability",
    "network_fingerprint",
    "thin_ridges",
    "P_KNOTS",
]

#: PDC type of each of the 16 PDC layers (0 = ``init_block``, 1-15 the blocks), config carv4.
PDC_TYPES = tuple(("cd", "ad", "rd", "cv")[k % 4] for k in range(16))
#: The fixed map of the thinned probability ``P`` to the Pb scale: piecewise linear
#: through these ``(P, value)`` knots (module docstring; ``benchmarks/eval_ethz.py
#: --calibrate-pidinet``, table5_pidinet weights).
P_KNOTS = ((0.0, 0.0), (0.3695, 0.05), (0.7691, 0.15), (0.841, 0.3), (0.9136, 0.5), (1.0, 1.0))
#: Gaussian scale (px) of the map whose Hessian gives the ridge normal.
ORIENT_SIGMA = 2.0
#: Gaussian scale (px) of the map compared in the non-maximum suppression.
VALUE_SIGMA = 1.0
#: Images whose longer side exceeds this are reduced for the network, and the map resized back.
MAX_SIDE = 1024

_MEAN = np.array([0.485, 0.456, 0.406], np.float32)
_STD = np.array([0.229, 0.224, 0.225], np.float32)
_AD_PERM = [3, 0, 1, 6, 4, 2, 7, 8, 5]
_RD_OUTER = [0, 2, 4, 10, 14, 20, 22, 24]
_RD_INNER = [6, 7, 8, 11, 13, 16, 17, 18]
_BLOCKS = [("block1", 3), ("block2", 4), ("block3", 4), ("block4", 4)]
_WHERE = (
    "PiDiNet weights are the authors' BSDS500 checkpoints (hellozhuo/pidinet, "
    "trained_models/table5_pidinet*.pth, converted to .npz: the state dict's arrays under "
    "their names without 'module.'); they are for research use only (the repository's "
    "licence) and are not shipped with shapetree: point to the .npz file"
)


def pdc_kernel(weight: ArrayLike, kind: str) -> NDArray[np.float32]:
    """The plain convolution kernel equal to a pixel-difference convolution.

    Parameters
    ----------
    weight : array_like, shape (out, in, 3, 3)
        The stored 3x3 kernels ``W`` (``j`` = row-major index 0..8, centre 4).
    kind : {"cv", "cd", "ad", "rd"}
        ``cv`` vanilla (``K = W``); ``cd`` central difference (``Σ_j W_j (x_j - x_c)``:
        ``K_4 = W_4 - Σ_j W_j``); ``ad`` angular difference (``K_j = W_j - W_p(j)``,
        ``p = [3, 0, 1, 6, 4, 2, 7, 8, 5]``); ``rd`` radial difference (a 5x5 kernel:
        ``+W_1..W_8`` on the outer ring, ``-W_1..W_8`` on the inner ring).

    Returns
    -------
    ndarray, shape (out, in, 3, 3), or (out, in, 5, 5) for ``rd``, float32
        The kernel of an ordinary cross-correlation (zero padding 1, or 2 for ``rd``).

    Raises
    ------
    ShapeTreeError
        For an unknown ``kind`` or a weight that is not ``(out, in, 3, 3)``.
    """
    w = np.asarray(weight, dtype=np.float32)
    if w.ndim != 4 or w.shape[2:] != (3, 3):
        raise ShapeTreeError(f"a PDC weight must have shape (out, in, 3, 3), got {w.shape}")
    o, i = w.shape[:2]
    if kind == "cv":
        return w.copy()
    if kind == "cd":
        k = w.copy()
        k[:, :, 1, 1] -= w.sum(axis=(2, 3))
        return k
    if kind == "ad":
        flat = w.reshape(o, i, 9)
        return (flat - flat[:, :, _AD_PERM]).reshape(o, i, 3, 3)
    if kind == "rd":
        flat = w.reshape(o, i, 9)
        k = np.zeros((o, i, 25), np.float32)
        k[:, :, _RD_OUTER] = flat[:, :, 1:]
        k[:, :, _RD_INNER] = -flat[:, :, 1:]
        return k.reshape(o, i, 5, 5)
    raise ShapeTreeError(f"unknown PDC type {kind!r}; choose one of cv, cd, ad, rd")


# --------------------------------------------------------------------------- layers
def _pad(x: NDArray[np.float32], p: int) -> NDArray[np.float32]:
    return np.pad(x, ((0, 0), (p, p), (p, p))) if p else x


def _conv_full(
    x: NDArray[np.float32], k: NDArray[np.float32], dilation: int = 1
) -> NDArray[np.float32]:
    """Cross-correlation ``(in, H, W) -> (out, H, W)``, kernel ``(out, in, s, s)``, same padding."""
    return _conv_sum(x, [(k, dilation)])


def _conv_sum(
    x: NDArray[np.float32], kernels: list[tuple[NDArray[np.float32], int]]
) -> NDArray[np.float32]:
    """Sum of same-padded cross-correlations of ``x`` with ``(kernel, dilation)`` pairs.

    ``x`` is ``(in, H, W)``, each kernel ``(out, in, s, s)``.  The padded input is
    flattened to ``(in, Hp * Wp)``; a tap at offset ``(dy, dx)`` then reads the strided
    view starting at ``dy * Wp + dx`` (no copy), and one matrix product per tap adds its
    share to an output laid out on the padded width (whose extra columns are dropped).
    """
    cin, h, w = x.shape
    pad = max(d * (k.shape[2] // 2) for k, d in kernels)
    wp = w + 2 * pad
    # one extra row so the last tap's view of h * wp values stays inside the buffer
    xp = np.zeros((cin, h + 2 * pad + 1, wp), np.float32)
    xp[:, pad : pad + h, pad : pad + w] = x
    flat = xp.reshape(cin, -1)
    cout = kernels[0][0].shape[0]
    out = np.zeros((cout, h * wp), np.float32)
    tmp = np.empty_like(out)
    for k, d in kernels:
        s = k.shape[2]
        for a in range(s):
            for b in range(s):
                tap = np.ascontiguousarray(k[:, :, a, b])
                if not tap.any():
                    continue
                off = (pad + (a - s // 2) * d) * wp + pad + (b - s // 2) * d
                np.matmul(tap, flat[:, off : off + h * wp], out=tmp)
                out += tmp
    return out.reshape(cout, h, wp)[:, :, :w].copy()


def _conv_depthwise(x: NDArray[np.float32], k: NDArray[np.float32]) -> NDArray[np.float32]:
    """Depthwise cross-correlation ``(C, H, W)``, kernel ``(C, 1, s, s)``, same padding."""
    c, h, w = x.shape
    s = k.shape[2]
    xp = _pad(x, s // 2)
    out = np.zeros_like(x)
    tmp = np.empty_like(x)
    for a in range(s):
        for b in range(s):
            tap = k[:, 0, a, b]
            if not tap.any():
                continue
            np.multiply(xp[:, a : a + h, b : b + w], tap[:, None, None], out=tmp)
            out += tmp
    return out


def _conv1x1(
    x: NDArray[np.float32], wt: NDArray[np.float32], bias: NDArray[np.float32] | None = None
) -> NDArray[np.float32]:
    c, h, w = x.shape
    out = wt.reshape(wt.shape[0], c) @ x.reshape(c, -1)
    if bias is not None:
        out += bias[:, None]
    return out.reshape(-1, h, w)


def _maxpool2(x: NDArray[np.float32]) -> NDArray[np.float32]:
    c, h, w = x.shape
    h2, w2 = h // 2, w // 2
    return x[:, : 2 * h2, : 2 * w2].reshape(c, h2, 2, w2, 2).max(axis=(2, 4))


def _resize_weights(n_in: int, n_out: int) -> tuple[NDArray, NDArray, NDArray]:
    """Bilinear (``align_corners=False``) source indices and weights along one axis."""
    src = (np.arange(n_out, dtype=np.float64) + 0.5) * (n_in / n_out) - 0.5
    src = np.maximum(src, 0.0)
    i0 = np.minimum(np.floor(src).astype(np.int64), n_in - 1)
    i1 = np.minimum(i0 + 1, n_in - 1)
    lam = (src - i0).astype(np.float32)
    return i0, i1, lam


def _upsample(x: NDArray[np.float32], h: int, w: int) -> NDArray[np.float32]:
    """Bilinear resize of ``(hi, wi)`` to ``(h, w)`` as ``F.interpolate(align_corners=False)``."""
    r0, r1, lr = _resize_weights(x.shape[0], h)
    c0, c1, lc = _resize_weights(x.shape[1], w)
    rows = x[r0] * (1 - lr)[:, None] + x[r1] * lr[:, None]
    return rows[:, c0] * (1 - lc)[None] + rows[:, c1] * lc[None]


def _sigmoid(x: NDArray[np.float32]) -> NDArray[np.float32]:
    return (0.5 * (1.0 + np.tanh(0.5 * x))).astype(np.float32)


# --------------------------------------------------------------------------- network
def _expected_shapes(c: int, sa_dil: bool, d: int) -> dict[str, tuple[int, ...]]:
    """Every parameter of a carv4 PiDiNet with ``c`` channels (``d``: CDCM width)."""
    shp: dict[str, tuple[int, ...]] = {"init_block.weight": (c, 3, 3, 3)}
    chans = [c, 2 * c, 4 * c, 4 * c]
    prev = c
    for s, (name, n) in enumerate(_BLOCKS):
        for i in range(1, n + 1):
            key = f"{name}_{i}"
            cin = prev if i == 1 else chans[s]
            if s > 0 and i == 1:
                shp[f"{key}.shortcut.weight"] = (chans[s], cin, 1, 1)
                shp[f"{key}.shortcut.bias"] = (chans[s],)
            shp[f"{key}.conv1.weight"] = (cin, 1, 3, 3)
            shp[f"{key}.conv2.weight"] = (chans[s], cin, 1, 1)
        prev = chans[s]
    for i, f in enumerate(chans):
        red = d if sa_dil else f
        shp[f"conv_reduces.{i}.conv.weight"] = (1, red, 1, 1)
        shp[f"conv_reduces.{i}.conv.bias"] = (1,)
        if sa_dil:
            shp[f"attentions.{i}.conv1.weight"] = (4, d, 1, 1)
            shp[f"attentions.{i}.conv1.bias"] = (4,)
            shp[f"attentions.{i}.conv2.weight"] = (1, 4, 3, 3)
            shp[f"dilations.{i}.conv1.weight"] = (d, f, 1, 1)
            shp[f"dilations.{i}.conv1.bias"] = (d,)
            for j in range(1, 5):
                shp[f"dilations.{i}.conv2_{j}.weight"] = (d, d, 3, 3)
    shp["classifier.weight"] = (1, 4, 1, 1)
    shp["classifier.bias"] = (1,)
    return shp


@dataclass(frozen=True)
class PiDiNet:
    """A loaded PiDiNet (converted kernels), callable on RGB images.

    Attributes
    ----------
    path : Path
        The weights file.
    sha256 : str
        Its SHA-256 (hex).
    channels : int
        ``C`` (60 full, 30 small, 20 tiny).
    sa_dil : bool
        Whether the model has CDCM and CSAM side branches (False for the ``-l`` models).
    variant : str
        ``"pidinet"``, ``"pidinet-small"``, ``"pidinet-tiny"``, with ``"-l"`` appended
        for the models without CDCM / CSAM.
    params : dict of str to ndarray
        The weights, float32, PDC kernels already converted (``*.conv1.weight`` of the
        blocks and ``init_block.weight``).
    """

    path: Path
    sha256: str
    channels: int
    sa_dil: bool
    variant: str
    params: dict[str, NDArray[np.float32]]

    def side_maps(self, image: ArrayLike) -> NDArray[np.float32]:
        """All five output maps (4 side outputs, then the fused one), after the sigmoid.

        Parameters
        ----------
        image : array_like, shape (H, W, 3)
            RGB in ``[0, 1]`` (float).

        Returns
        -------
        ndarray, shape (5, H, W), float32
            Values in ``[0, 1]``.
        """
        rgb = np.asarray(image, dtype=np.float32)
        if rgb.ndim != 3 or rgb.shape[2] != 3 or min(rgb.shape[:2]) < 1:
            raise ShapeTreeError(f"PiDiNet needs an (H, W, 3) RGB image, got shape {rgb.shape}")
        h, w = rgb.shape[:2]
        x = np.ascontiguousarray(((rgb - _MEAN) / _STD).transpose(2, 0, 1))
        q = self.params
        x = _conv_full(x, q["init_block.weight"])
        feats = []
        for s, (name, n) in enumerate(_BLOCKS):
            for i in range(1, n + 1):
                key = f"{name}_{i}"
                if s > 0 and i == 1:
                    x = _maxpool2(x)
                    short = _conv1x1(x, q[f"{key}.shortcut.weight"], q[f"{key}.shortcut.bias"])
                else:
                    short = x
                y = _conv_depthwise(x, q[f"{key}.conv1.weight"])
                np.maximum(y, 0.0, out=y)
                y = _conv1x1(y, q[f"{key}.conv2.weight"])
                y += short
                x = y
            feats.append(x)
        sides = []
        for i, f in enumerate(feats):
            if self.sa_dil:
                t = _conv1x1(
                    np.maximum(f, 0.0),
                    q[f"dilations.{i}.conv1.weight"],
                    q[f"dilations.{i}.conv1.bias"],
                )
                z = _conv_sum(
                    t,
                    [
                        (q[f"dilations.{i}.conv2_{j}.weight"], dil)
                        for j, dil in enumerate((5, 7, 9, 11), start=1)
                    ],
                )
                a = _conv1x1(
                    np.maximum(z, 0.0),
                    q[f"attentions.{i}.conv1.weight"],
                    q[f"attentions.{i}.conv1.bias"],
                )
                a = _sigmoid(_conv_full(a, q[f"attentions.{i}.conv2.weight"]))
                f = z * a
            e = _conv1x1(f, q[f"conv_reduces.{i}.conv.weight"], q[f"conv_reduces.{i}.conv.bias"])
            sides.append(_upsample(e[0], h, w))
        cw = q["classifier.weight"].reshape(4)
        fused = sum(cw[i] * sides[i] for i in range(4)) + q["classifier.bias"][0]
        return _sigmoid(np.stack([*sides, fused]))

    def __call__(self, image: ArrayLike) -> NDArray[np.float32]:
        """The fused boundary probability, shape ``(H, W)``, float32 in ``[0, 1]``."""
        return self.side_maps(image)[4]


_LOADED: dict[tuple[str, int, int], PiDiNet] = {}
_LOCK = threading.Lock()


def weights_sha256(path: str | os.PathLike[str]) -> str:
    """SHA-256 (hex) of a weights file (part of the edge-cache keys)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def load_pidinet(path: str | os.PathLike[str] | None) -> PiDiNet:
    """Load (and check) PiDiNet weights from an ``.npz`` file; cached per file.

    Parameters
    ----------
    path : path-like
        One of the ``table5_*.npz`` files (the variant is read from its keys).

    Returns
    -------
    PiDiNet

    Raises
    ------
    ShapeTreeError
        If ``path`` is None, missing, unreadable, a torch ``.pth`` file, or its arrays are
        not a carv4 PiDiNet (a key missing or of the wrong shape); the message says where
        the weights can be had and that they are for research use only.
    """
    if path is None:
        raise ShapeTreeError(
            "edge method 'pidinet' needs a weights file (edge_weights= / --edge-weights "
            f"PATH). {_WHERE}"
        )
    p = Path(path).expanduser()
    if not p.is_file():
        raise ShapeTreeError(f"PiDiNet weights file not found: {p}. {_WHERE}")
    st = p.stat()
    key = (str(p.resolve()), st.st_size, st.st_mtime_ns)
    with _LOCK:
        if key in _LOADED:
            return _LOADED[key]
    if p.suffix.lower() in (".pth", ".pt"):
        raise ShapeTreeError(
            f"{p} is a torch checkpoint; shapetree reads the .npz copy (no torch). {_WHERE}"
        )
    with open(p, "rb") as fh:
        if fh.read(4) != b"PK\x03\x04":  # an .npz is a zip archive
            raise ShapeTreeError(f"{p} is not an .npz archive of PiDiNet weights. {_WHERE}")
    try:
        with np.load(p, allow_pickle=False) as z:
            raw = {k.removeprefix("module."): np.asarray(z[k]) for k in z.files}
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as exc:
        raise ShapeTreeError(f"cannot read PiDiNet weights {p}: {exc}. {_WHERE}") from None
    init = raw.get("init_block.weight")
    if init is None or init.ndim != 4:
        raise ShapeTreeError(
            f"{p} holds no PiDiNet weights (no 'init_block.weight' array). {_WHERE}"
        )
    c = int(init.shape[0])
    sa_dil = "dilations.0.conv1.weight" in raw
    d = int(raw["dilations.0.conv1.weight"].shape[0]) if sa_dil else 0
    want = _expected_shapes(c, sa_dil, d)
    for name, shape in want.items():
        if name not in raw:
            raise ShapeTreeError(f"{p}: PiDiNet weight {name!r} is missing. {_WHERE}")
        if tuple(raw[name].shape) != shape:
            raise ShapeTreeError(
                f"{p}: PiDiNet weight {name!r} has shape {tuple(raw[name].shape)}, "
                f"expected {shape}. {_WHERE}"
            )
        if not np.all(np.isfinite(raw[name])):
            raise ShapeTreeError(f"{p}: PiDiNet weight {name!r} has non-finite values")
    extra = sorted(set(raw) - set(want))
    if extra:
        raise ShapeTreeError(f"{p}: unexpected arrays {extra[:5]} for a PiDiNet. {_WHERE}")
    params = {k: v.astype(np.float32) for k, v in raw.items()}
    params["init_block.weight"] = pdc_kernel(params["init_block.weight"], PDC_TYPES[0])
    layer = 1
    for name, n in _BLOCKS:
        for i in range(1, n + 1):
            k = f"{name}_{i}.conv1.weight"
            params[k] = pdc_kernel(params[k], PDC_TYPES[layer])
            layer += 1
    size = {60: "pidinet", 30: "pidinet-small", 20: "pidinet-tiny"}.get(c, f"pidinet-c{c}")
    net = PiDiNet(
        path=p,
        sha256=weights_sha256(p),
        channels=c,
        sa_dil=sa_dil,
        variant=size + ("" if sa_dil else "-l"),
        params=params,
    )
    with _LOCK:
        _LOADED[key] = net
    return net


def check_weights(path: str | os.PathLike[str] | None) -> str:
    """Validate a weights file at the boundary; return its SHA-256 (see :func:`load_pidinet`)."""
    return load_pidinet(path).sha256


# --------------------------------------------------------------------------- thinning
def thin_ridges(
    prob: ArrayLike, *, orient_sigma: float = ORIENT_SIGMA, value_sigma: float = VALUE_SIGMA
) -> NDArray[np.float64]:
    """Non-maximum suppression of a thick soft edge map across its ridges.

    Parameters
    ----------
    prob : array_like, shape (H, W)
        Soft boundary map (e.g. PiDiNet's fused output).
    orient_sigma : float
        Gaussian scale (px) of the map whose Hessian gives the ridge normal.
    value_sigma : float
        Gaussian scale (px) of the map compared along the normal (0: the map itself).

    Returns
    -------
    ndarray, shape (H, W), float64
        ``prob`` where a pixel is a ridge maximum across the normal (strictly larger
        than the smoothed value one pixel ahead, at least the one behind), else 0.
    """
    e = np.asarray(prob, dtype=np.float64)
    o = ndimage.gaussian_filter
    hxx = o(e, orient_sigma, order=(0, 2), mode="nearest")
    hyy = o(e, orient_sigma, order=(2, 0), mode="nearest")
    hxy = o(e, orient_sigma, order=(1, 1), mode="nearest")
    theta = 0.5 * np.arctan2(2.0 * hxy, hxx - hyy) + 0.5 * np.pi  # most negative curvature
    ux, uy = np.cos(theta), np.sin(theta)
    s = o(e, value_sigma, mode="nearest") if value_sigma > 0 else e
    h, w = e.shape
    rr, cc = np.mgrid[0:h, 0:w].astype(np.float64)
    ahead = ndimage.map_coordinates(s, [rr + uy, cc + ux], order=1, mode="nearest")
    behind = ndimage.map_coordinates(s, [rr - uy, cc - ux], order=1, mode="nearest")
    keep = (s > ahead) & (s >= behind)
    return np.where(keep, e, 0.0)


def _as_rgb(image: ArrayLike) -> NDArray[np.float32]:
    from ._edges import _as_unit

    arr = _as_unit(image)
    if arr.ndim == 2:
        arr = arr[:, :, None]
    if arr.shape[2] == 1:
        arr = np.repeat(arr, 3, axis=2)
    return arr.astype(np.float32)


def network_fingerprint() -> str:
    """SHA-256 (hex) of the source of the code that computes the fused map.

    The network's functions only (kernels, layers, the forward pass, the input
    conversion and resizing; not the thinning or the scale), so a cache of raw fused
    maps survives a change of the calibration but never a change of the network.
    """
    import inspect

    from shapetree import __version__

    from . import _edges

    h = hashlib.sha256(f"pidinet-network\0{__version__}\0{MAX_SIDE}\0".encode())
    for fn in (
        pdc_kernel,
        _pad,
        _conv_full,
        _conv_sum,
        _conv_depthwise,
        _conv1x1,
        _maxpool2,
        _resize_weights,
        _upsample,
        _sigmoid,
        _expected_shapes,
        PiDiNet,
        load_pidinet,
        _as_rgb,
        _edges._as_unit,
        fused_probability,
    ):
        h.update(inspect.getsource(fn).encode())
    return h.hexdigest()


def fused_probability(
    image: ArrayLike, weights: str | os.PathLike[str] | None
) -> NDArray[np.float32]:
    """PiDiNet's fused boundary probability of an image, before thinning.

    Parameters
    ----------
    image : array_like, shape (H, W) or (H, W, 3|4)
        Greyscale or RGB(A) image (as :func:`shapetree.detection.edge_map` takes it).
    weights : path-like
        A ``table5_*.npz`` weights file.

    Returns
    -------
    ndarray, shape (H, W), float32
        In ``[0, 1]``.  Images with a side over ``MAX_SIDE`` px run reduced, and the map
        is resized back (bilinear).
    """
    net = load_pidinet(weights)
    rgb = _as_rgb(image)
    h, w = rgb.shape[:2]
    f = min(1.0, MAX_SIDE / max(h, w))
    if f < 1.0:
        rgb = ndimage.zoom(rgb, (f, f, 1), order=1, mode="nearest")
    prob = net(rgb)
    if f < 1.0:
        prob = _upsample(prob, h, w)
    return prob


def edges_from_probability(
    prob: ArrayLike, *, thin: bool = True, floor: float = 0.02
) -> NDArray[np.float64]:
    """Thin a fused PiDiNet map and put it on the Pb scale (see the module docstring).

    Parameters
    ----------
    prob : array_like, shape (H, W)
        :func:`fused_probability`'s output.
    thin : bool
        Non-maximum suppression across the ridges (default True).
    floor : float
        Values below this after the fixed map are set to 0 (default 0.02).

    Returns
    -------
    ndarray, shape (H, W), float64
        The (thinned) map through the fixed map ``P_KNOTS``, in ``[0, 1]``.
    """
    e = np.asarray(prob, dtype=np.float64)
    if thin:
        e = thin_ridges(e)
    xs, ys = zip(*P_KNOTS, strict=True)
    out = np.interp(np.clip(e, 0.0, 1.0), xs, ys)
    out[out < floor] = 0.0
    return out


def pidinet_edges(
    image: ArrayLike,
    weights: str | os.PathLike[str] | None,
    *,
    thin: bool = True,
    floor: float = 0.02,
) -> NDArray[np.float64]:
    """PiDiNet soft edge map of an image, thinned and on the Pb scale.

    Parameters
    ----------
    image : array_like, shape (H, W) or (H, W, 3|4)
        Greyscale or RGB(A) image (as :func:`shapetree.detection.edge_map` takes it).
    weights : path-like
        A ``table5_*.npz`` PiDiNet weights file (research use only; see the module
        docstring).
    thin : bool
        Non-maximum suppression across the ridges (:func:`thin_ridges`) (default True).
    floor : float
        Values below this after the fixed map are set to 0 (default 0.02).

    Returns
    -------
    ndarray, shape (H, W), float64
        The (thinned) fused probability through the fixed map ``P_KNOTS``.

    Raises
    ------
    ShapeTreeError
        For bad weights (see :func:`load_pidinet`) or a bad image
        (:class:`~shapetree.ImageError`).
    """
    return edges_from_probability(fused_probability(image, weights), thin=thin, floor=floor)
