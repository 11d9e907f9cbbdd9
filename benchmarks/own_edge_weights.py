"""Can the own edge map's cue weights be fitted closer to Pb? (issue 14, item 2)

The own map (``shapetree.detection._boundary``) adds the oriented χ² forms of four cues
(brightness ``L``, colour ``a`` and ``b``, textons) with fixed weights at fixed scales. This
script asks whether a per-cue, per-scale weighting matches the shipped Pb maps better,
and what it costs the texture cue:

1. For 40 ETHZ images (8 per class, evenly spaced in each class's sorted list), the forms
   of every cue at the scales ``L, a, b``: 1, 2, 4, 8 px and texture: 4, 8, 16 px, each
   clipped to χ² <= 1 (computed with the module's own ``_channels`` / ``_cue_forms``). A
   one-channel image would get zero colour forms here, where the module moves the colour
   weights to ``L``; all 40 images are RGB.
2. The score of a weighting: the F-measure of its thinned map against the Pb map (2 px
   tolerance), with the own map thresholded at the same pixel share as Pb above 0.05, 0.15
   and 0.3 (so no calibration is needed), averaged over the three and over the images.
3. A coordinate search (2 sweeps, each weight x 0, 0.5 or 2) from the shipped weights, on
   the even-numbered 20 images; the odd-numbered 20 are the held-out check.
4. The texture-only cap: a boundary that only the texture cue sees reaches at most
   ``(w_texture - E_OFFSET) / E_RANGE``, with the offset and range refitted (median pixel
   shares of Pb above 0.05, 0.15, 0.3, 0.5, as the module's own constants were set). The
   test ``test_step_between_two_textures_is_strong`` needs more than 0.2 there.

No ground-truth box is used. Run::

    SHAPETREE_DATA=/work/shared/datasets nice python3 benchmarks/own_edge_weights.py

Writes ``benchmarks/results/own_edge_weights.json`` and prints a table.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from scipy import ndimage

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, machine, write_json  # noqa: E402

from shapetree.detection import _boundary as B  # noqa: E402
from shapetree.detection import load_edges, load_image  # noqa: E402
from shapetree.detection._edges import _as_channels, _nms  # noqa: E402
from shapetree.detection._ethz_eval import ethz_root  # noqa: E402

CLASSES = ("Applelogos", "Bottles", "Giraffes", "Mugs", "Swans")
SCALES = {"L": (1.0, 2.0, 4.0, 8.0), "a": (1.0, 2.0, 4.0, 8.0), "b": (1.0, 2.0, 4.0, 8.0)}
SCALES["texture"] = (4.0, 8.0, 16.0)
KEYS = [(c, s) for c in ("L", "a", "b", "texture") for s in SCALES[c]]
#: The shipped weighting in this per-scale form (each cue's weight split over its scales).
SHIPPED = {("L", 2.0): 0.2, ("L", 4.0): 0.2, ("a", 2.0): 0.075, ("a", 4.0): 0.075}
SHIPPED |= {("b", 2.0): 0.075, ("b", 4.0): 0.075, ("texture", 8.0): 0.15}
SHIPPED |= {("texture", 16.0): 0.15}
F_THRESHOLDS = (0.05, 0.15, 0.3)
CAL_THRESHOLDS = (0.05, 0.15, 0.3, 0.5)


def images(root: Path, per_class: int = 8) -> list[tuple[str, str]]:
    out = []
    for c in CLASSES:
        files = sorted(p.name for p in (root / c).glob("*_edges.tif"))  # by file name
        stems = [f[: -len("_edges.tif")] for f in files]
        out += [(c, s) for s in stems[1 :: len(stems) // per_class][:per_class]]
    return out


def forms(path: Path) -> np.ndarray:
    """``(K, 3, H, W)``: the ``(a, b, c)`` form of every key, at the image's size."""
    lab = _as_channels(load_image(path))
    h, w = lab.shape[:2]
    f = B.working_scale(h, w)
    if f != 1.0:
        lab = ndimage.zoom(lab, (f, f, 1), order=1, mode="nearest")
    chans = B._channels(lab)
    out = []
    for c, s in KEYS:
        if c not in chans:  # greyscale: no colour forms
            out.append(np.zeros((3, h, w), np.float32))
            continue
        a, b, cc = B._cue_forms(chans[c], (s,))
        top = 0.5 * (a + cc) + np.sqrt(0.25 * (a - cc) ** 2 + b**2)
        k = np.minimum(1.0, 1.0 / np.maximum(top, 1e-12))
        t3 = [a * k, b * k, cc * k]
        if f != 1.0:
            z = (h / a.shape[0], w / a.shape[1])
            t3 = [ndimage.zoom(x, z, order=1, mode="nearest")[:h, :w] for x in t3]
        out.append(np.stack(t3).astype(np.float32))
    return np.stack(out)


def thinned(F: np.ndarray, w: np.ndarray) -> np.ndarray:
    fa, fb, fc = (np.tensordot(w, F[:, i], 1) for i in range(3))
    e = 0.5 * (fa + fc) + np.sqrt((0.5 * (fa - fc)) ** 2 + fb**2)
    th = 0.5 * np.arctan2(2 * fb, fa - fc)
    return _nms(e, np.cos(th), np.sin(th))


def f_measure(ours: np.ndarray, pb: np.ndarray, tol: float = 2.0) -> float:
    fs = []
    for t in F_THRESHOLDS:
        P = pb > t
        share = P.mean()
        if share == 0:
            continue
        thr = np.quantile(ours, 1 - share) if share < (ours > 0).mean() else 0.0
        O = ours > max(thr, 1e-9)
        dP = ndimage.distance_transform_edt(~P)
        dO = ndimage.distance_transform_edt(~O)
        prec = float((dP[O] <= tol).mean()) if O.any() else 0.0
        rec = float((dO[P] <= tol).mean())
        fs.append(2 * prec * rec / max(prec + rec, 1e-9))
    return float(np.mean(fs))


def share_levels(ths: list[np.ndarray], pbs: list[np.ndarray]) -> tuple[np.ndarray, list[float]]:
    """For each Pb strength in ``CAL_THRESHOLDS``: the median share of Pb pixels above it,
    and the energy at which the median share of pixels of ``ths`` above it is the same
    (bisection)."""
    target = np.median([[(p > t).mean() for t in CAL_THRESHOLDS] for p in pbs], axis=0)
    qs = []
    for j in range(len(CAL_THRESHOLDS)):
        lo, hi = 0.0, 3.0
        for _ in range(40):
            q = 0.5 * (lo + hi)
            share = np.median([(e > q).mean() for e in ths])
            lo, hi = (q, hi) if share > target[j] else (lo, q)
        qs.append(0.5 * (lo + hi))
    return target, qs


def calibration(ths: list[np.ndarray], pbs: list[np.ndarray]) -> tuple[float, float]:
    """``(E_OFFSET, E_RANGE)``: the line through :func:`share_levels`' energies."""
    _, qs = share_levels(ths, pbs)
    slope, off = np.polyfit(CAL_THRESHOLDS, qs, 1)
    return float(off), float(slope)


def f_score(ths: list[np.ndarray], data: list[dict], idx: list[int]) -> float:
    """Mean F-measure of thinned maps ``ths`` against the Pb maps of images ``idx``."""
    return float(np.mean([f_measure(t, data[i]["pb"]) for t, i in zip(ths, idx, strict=True)]))


def search_f(w: np.ndarray, data: list[dict], idx: list[int]) -> float:
    """What the search maximises: the F-measure alone (no calibration needed)."""
    return f_score([thinned(data[i]["forms"], w) for i in idx], data, idx)


def evaluate(w: np.ndarray, data: list[dict], idx: list[int]) -> dict[str, float]:
    ths = [thinned(data[i]["forms"], w) for i in idx]
    off, rng = calibration(ths, [data[i]["pb"] for i in idx])
    tex = sum(w[j] for j, (c, _) in enumerate(KEYS) if c == "texture")
    return {
        "f": f_score(ths, data, idx),
        "e_offset": off,
        "e_range": rng,
        "texture_only_cap": float((tex - off) / rng),
    }


def search(
    w0: np.ndarray, data: list[dict], train: list[int], texture_floor: float | None = None
) -> tuple[np.ndarray, list]:
    """Coordinate search of the F-measure from ``w0``; with ``texture_floor``, a step is
    taken only if the texture-only cap on the training images (offset and range refitted
    for the step's weights) stays at or above it."""
    best = w0.copy()
    bf = search_f(best, data, train)
    steps = []
    for sweep in range(2):
        for j, key in enumerate(KEYS):
            for fac in (0.0, 0.5, 2.0):
                w = best.copy()
                w[j] = w[j] * fac if w[j] > 0 else (0.05 if fac == 2.0 else 0.0)
                f = search_f(w, data, train)
                if f <= bf + 1e-4:
                    continue
                if (
                    texture_floor is not None
                    and evaluate(w, data, train)["texture_only_cap"] < texture_floor
                ):
                    continue
                best, bf = w, f
                steps.append([sweep, f"{key[0]}:{key[1]:g}", fac, round(f, 4)])
                print(f"  sweep {sweep} {key} x{fac}: train F {f:.4f}", flush=True)
    return best, steps


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--data", default=None)
    ap.add_argument("--json", default=str(RESULTS / "own_edge_weights.json"))
    ap.add_argument(
        "--texture-floor",
        type=float,
        default=None,
        help="take only steps that keep the texture-only cap on the training images at or "
        "above this (the shipped weights: 0.215; the two-texture test needs > 0.2 on a "
        "synthetic image); default: no constraint",
    )
    args = ap.parse_args(argv)
    root = ethz_root(args.data)
    t0 = time.perf_counter()
    names = images(root)
    data = []
    for c, s in names:
        data.append(
            {"forms": forms(root / c / f"{s}.jpg"), "pb": load_edges(root / c / f"{s}_edges.tif")}
        )
    print(f"forms of {len(data)} images: {time.perf_counter() - t0:.0f} s", flush=True)
    train = list(range(0, len(data), 2))
    test = list(range(1, len(data), 2))
    w0 = np.array([SHIPPED.get(k, 0.0) for k in KEYS])
    best, steps = search(w0, data, train, args.texture_floor)
    rows = {}
    for label, w in (("shipped", w0), ("searched", best)):
        rows[label] = {
            "weights": {
                f"{c}:{s:g}": round(float(v), 4) for (c, s), v in zip(KEYS, w, strict=True) if v
            },
            "train": evaluate(w, data, train),
            "held_out": evaluate(w, data, test),
        }
    out: dict[str, Any] = {
        "command": "python3 benchmarks/own_edge_weights.py " + " ".join(argv or sys.argv[1:]),
        "protocol": __doc__.split("\n\n")[1].replace("\n", " "),
        "images": [f"{c}/{s}" for c, s in names],
        "train": "even positions of 'images'",
        "held_out": "odd positions",
        "texture_floor": args.texture_floor,
        "search_steps": steps,
        "rows": rows,
        "seconds": round(time.perf_counter() - t0, 1),
        "machine": machine(),
    }
    write_json(Path(args.json), out)
    print(f"\n{'weights':10s} {'F train':>8s} {'F held-out':>10s} {'texture-only cap':>17s}")
    for label, r in rows.items():
        print(
            f"{label:10s} {r['train']['f']:8.4f} {r['held_out']['f']:10.4f} "
            f"{r['held_out']['texture_only_cap']:17.3f}"
        )
    print(f"json: {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
