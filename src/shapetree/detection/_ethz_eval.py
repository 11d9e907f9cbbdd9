"""ETHZ Shape Classes evaluation: each hand-drawn model over all 255 images (DR vs FPPI).

Protocol (ETHZ README; Ferrari et al.): the class's hand-drawn model is the
only training example; it is run on all 255 images, so the other classes'
images are negatives.  A detection is correct if its box overlaps a still
unclaimed ground-truth box of the class in the same image by IoU >= 0.2
(the "20% rule") or IoU >= 0.5 (PASCAL); further detections of a claimed box
are false positives.  Sweeping the score threshold gives detection rate (DR,
share of ground-truth boxes found) against false positives per image (FPPI,
over all 255 images); DR at a given FPPI is the highest DR reached with FPPI
at most that value.

Per-image detections are cached as JSON files (one per class and image) under
``$SHAPETREE_CACHE/ethz_detect/<key>`` (default ``~/.cache/shapetree/ethz_detect``),
so an interrupted run resumes.  ``<key>`` hashes the parameters, ``k`` and
:func:`shapetree._cache.code_fingerprint` (the package version and the source of
the matching and detection code), so results of other code are never reused.

A computed edge map (``edges="own"`` or ``"pidinet"``) is made once per image, before
the detections, and kept as ``<cache>/edges/<method>-<key>/<folder>__<stem>.npz``
(``<key>``: the method, the weights' SHA-256 and the edge-map code), so the protocol
costs one edge map per image, not one per (image, model), and a rerun reads them back.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from shapetree._atomic import atomic_write_bytes
from shapetree._cache import cache_root, code_fingerprint
from shapetree._errors import DatasetError, ShapeTreeError
from shapetree.datasets._registry import ETHZ_CLASSES as _REGISTRY_CLASSES

from ._detect import DetectParams, detect_detailed
from ._template import TEMPLATE_TERMS

__all__ = ["evaluate_ethz", "ethz_root", "ETHZ_CLASSES", "dr_at_fppi", "dr_fppi_curve"]

#: ``{class tag: (image folder, model file stem)}``: the dataset registry's table
#: (``shapetree.datasets._registry.ETHZ_CLASSES``, keyed by folder) keyed by class tag.
ETHZ_CLASSES: dict[str, tuple[str, str]] = {
    tag: (folder, stem) for folder, (tag, stem) in _REGISTRY_CLASSES.items()
}


def ethz_root(data_dir: str | os.PathLike[str] | None = None) -> Path:
    """Locate the ``ETHZShapeClasses-V1.2`` folder.

    Parameters
    ----------
    data_dir : path-like or None
        The folder itself, its parent ``ethz_shape/``, or the datasets root holding
        ``ethz_shape/``; default: the datasets root (``$SHAPETREE_DATA``, else the default
        data folder), as for every other dataset.

    Returns
    -------
    Path

    Raises
    ------
    DatasetError
        If no such folder is found (the message says where it looked and how to get it).
    """
    from shapetree.datasets._ethz import ethz_root as dataset_root

    if data_dir is not None and (Path(data_dir) / "ethz_shape").is_dir():
        data_dir = Path(data_dir) / "ethz_shape"  # a datasets root
    return dataset_root(data_dir)


def _images(root: Path) -> list[tuple[str, str]]:
    """All (class folder, image stem) pairs, sorted."""
    out = []
    for folder, _ in ETHZ_CLASSES.values():
        for p in sorted((root / folder).glob("*.jpg")):
            out.append((folder, p.stem))
    if not out:
        raise DatasetError(f"no ETHZ images under {root}")
    return out


def _gt_boxes(root: Path, folder: str, stem: str, cls: str) -> np.ndarray:
    """The boxes of class tag ``cls`` in one image (none when it has no such file), read
    by the dataset loader's reader, so the evaluation and ``load_ethz`` agree."""
    from shapetree.datasets._ethz import read_boxes

    p = root / folder / f"{stem}_{cls}.groundtruth"
    if not p.exists():
        return np.zeros((0, 4))
    return read_boxes(p)


def _iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU of box ``a`` (4,) with boxes ``b`` (n, 4)."""
    ix = np.clip(np.minimum(a[2], b[:, 2]) - np.maximum(a[0], b[:, 0]), 0, None)
    iy = np.clip(np.minimum(a[3], b[:, 3]) - np.maximum(a[1], b[:, 1]), 0, None)
    inter = ix * iy
    area_a = max(a[2] - a[0], 0.0) * max(a[3] - a[1], 0.0)
    area_b = np.clip(b[:, 2] - b[:, 0], 0, None) * np.clip(b[:, 3] - b[:, 1], 0, None)
    return inter / np.maximum(area_a + area_b - inter, 1e-9)


def greedy_claims(
    dets: Sequence[tuple[str, float, Sequence[float]]],
    gts: dict[str, np.ndarray],
    iou_thr: float,
    n: int | None = None,
) -> tuple[list[int], np.ndarray, dict[str, np.ndarray]]:
    """The evaluation's greedy claim of ground-truth boxes by detections.

    Detections are taken in decreasing score order (ties in input order); each claims the
    unclaimed ground-truth box of its image it overlaps most, if that IoU is >= ``iou_thr``.

    Parameters
    ----------
    dets, gts, iou_thr
        As in :func:`dr_fppi_curve`.
    n : int, optional
        Only the ``n`` best detections claim (default all).

    Returns
    -------
    order : list of int
        Indices into ``dets``, best first (the first ``n``).
    hit : ndarray of bool, shape (len(order),)
        Whether each of them claimed a box (a true detection) or not (a false positive).
    claimed : dict of image key -> ndarray of bool, shape (g,)
        The ground-truth boxes claimed once they have all claimed.
    """
    order = sorted(range(len(dets)), key=lambda i: -dets[i][1])[:n]
    claimed = {k: np.zeros(len(g), bool) for k, g in gts.items()}
    hit = np.zeros(len(order), bool)
    for pos, i in enumerate(order):
        key, _, box = dets[i]
        g = gts.get(key)
        if g is not None and len(g):
            ious = _iou(np.asarray(box, float), g)
            ious[claimed[key]] = -1.0
            j = int(np.argmax(ious))
            if ious[j] >= iou_thr:
                claimed[key][j] = True
                hit[pos] = True
    return order, hit, claimed


def dr_fppi_curve(
    dets: Sequence[tuple[str, float, Sequence[float]]],
    gts: dict[str, np.ndarray],
    n_images: int,
    iou_thr: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Detection rate vs false positives per image.

    Parameters
    ----------
    dets : sequence of (image key, score, box)
        All detections of one class over all images (box ``x1, y1, x2, y2``).
    gts : dict of image key -> ndarray, shape (g, 4)
        Ground-truth boxes of the class.
    n_images : int
        Number of images (the FPPI denominator).
    iou_thr : float
        A detection is correct when its IoU with an unclaimed box is >= this
        (:func:`greedy_claims`).

    Returns
    -------
    fppi, dr, scores : ndarray, shape (n_dets,)
        After each detection in decreasing score order.
    """
    n_gt = sum(len(g) for g in gts.values())
    order, hit, _ = greedy_claims(dets, gts, iou_thr)
    fppi = np.cumsum(~hit) / n_images
    dr = np.cumsum(hit) / max(n_gt, 1)
    return fppi, dr, np.array([dets[i][1] for i in order], dtype=float)


def recall_any(
    dets: Sequence[tuple[str, float, Sequence[float]]],
    gts: dict[str, np.ndarray],
    iou_thr: float,
) -> float:
    """Share of ground-truth boxes overlapped (IoU >= ``iou_thr``) by *any* detection.

    The ceiling of the detection rate at unlimited FPPI for the detections kept (``k``
    per image): what a perfect ranking of these detections across images would reach.
    """
    n_gt = sum(len(g) for g in gts.values())
    if n_gt == 0:
        return 0.0
    hit = {k: np.zeros(len(g), bool) for k, g in gts.items()}
    for key, _score, box in dets:
        g = gts.get(key)
        if g is not None and len(g):
            hit[key] |= _iou(np.asarray(box, float), g) >= iou_thr
    return float(sum(h.sum() for h in hit.values()) / n_gt)


def dr_at_fppi(fppi: np.ndarray, dr: np.ndarray, at: float) -> float:
    """Highest detection rate reached with FPPI <= ``at`` (0 if none)."""
    ok = fppi <= at + 1e-12
    return float(dr[ok].max()) if ok.any() else 0.0


def _params_key(params: DetectParams, k: int, edges: str = "pb") -> str:
    """Cache sub-folder name: hash of the parameters, ``k``, the edge source and the code.

    The collection stage's fields (``_detect.COLLECTION_FIELDS``) are left out: they
    re-rank the cached detections and never change them."""
    doc: dict[str, Any] = {
        "params": params.as_dict(collection=False),  # the collection stage is not cached
        "k": k,
        "code": code_fingerprint(),
    }
    if edges != "pb":  # the Pb runs keep their historical key
        doc["edges"] = edges
    blob = json.dumps(doc, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def default_cache_dir() -> Path:
    """Default ETHZ detection cache: ``cache_root() / "ethz_detect"``.

    That is ``$SHAPETREE_CACHE/ethz_detect``, or ``~/.cache/shapetree/ethz_detect``.
    """
    return cache_root() / "ethz_detect"


_MODELS: dict[str, Any] = {}


def _warm_up() -> None:
    """Pool initializer: load the compiled kernels so timings exclude JIT loading."""
    t = np.linspace(0, 2 * np.pi, 60, endpoint=False)
    circle = np.c_[np.cos(t), np.sin(t)]
    try:
        detect_detailed(circle, None, contours=[circle[:25] * 30 + 50, circle[30:55] * 30 + 50])
    except Exception:  # pragma: no cover - warm-up is best effort
        pass


EDGE_SOURCES = ("pb", "own", "pidinet")
#: Computed edge sources (the others are read from the dataset's files).
COMPUTED_EDGES = ("own", "pidinet")

#: The stages timed per detection run (``DetectionRun.timings``), in order.
STAGES = {
    "edges": "edge map: the Pb map read from disk; for a computed map (own, pidinet) the "
    "map read from the per-image edge cache plus its computation (image read, network or "
    "cues, thinning) divided by the number of models run on the image (it is computed "
    "once per image); with the model prepared",
    "contours": "contour tracing on the edge map",
    "tables": "contour-vs-model tables (section 3 kernel)",
    "stitch": "stitching DP with gaps",
    "select": "verification and selection: reconstruction of each complete match, the "
    "holistic outline check and size prior of the ranking score, non-maximum suppression, "
    "the upright template check of each kept detection's box and the box refinement",
    "appearance": "collection stage: the image read and its Lab colour "
    "bins, the colour histogram inside each kept detection's outline, divided by the number "
    "of models run on the image (done once per image); the agreements themselves are "
    "computed once for the collection and not counted",
}


def _edge_fingerprint() -> str:
    """SHA-256 of the version and the edge-map sources (``_edges``, ``_boundary``, ``_pidinet``).

    Keys the per-image edge cache: any edit of how a map is computed, thinned or scaled
    gives a new folder, while edits elsewhere (matching, stitching) keep the maps.
    """
    from shapetree import __version__

    h = hashlib.sha256(f"shapetree-edge-maps\0{__version__}\0".encode())
    here = Path(__file__).resolve().parent
    for name in ("_edges.py", "_boundary.py", "_pidinet.py"):
        data = (here / name).read_bytes()
        h.update(f"{name}\0{len(data)}\0".encode() + data)
    return h.hexdigest()


def edge_cache_dirs(
    base: Path, edges: str, weights_sha: str | None = None
) -> tuple[Path, Path | None]:
    """Per-image edge caches of a computed source under ``base / "edges"``.

    Returns
    -------
    final : Path
        ``<method>-<key>``: the finished maps (``<folder>__<stem>.npz``: ``edges`` (H, W)
        float64, ``seconds`` of computing it); the key hashes the method, the weights'
        SHA-256 and :func:`_edge_fingerprint`.
    raw : Path or None
        pidinet only, ``pidinet-raw-<key>``: the network's fused maps before thinning
        (``prob`` float32, ``seconds``), keyed by the weights' SHA-256 and
        :func:`shapetree.detection._pidinet.network_fingerprint`, so a new thinning or
        scale reuses them.
    """
    doc = {"method": edges, "weights": weights_sha, "code": _edge_fingerprint()}
    key = hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()[:16]
    final = base / "edges" / f"{edges}-{key}"
    raw = None
    if edges == "pidinet":
        from ._pidinet import network_fingerprint

        rdoc = {"weights": weights_sha, "network": network_fingerprint()}
        rkey = hashlib.sha256(json.dumps(rdoc, sort_keys=True).encode()).hexdigest()[:16]
        raw = base / "edges" / f"pidinet-raw-{rkey}"
    return final, raw


def _save_npz(path: Path, **arrays: Any) -> None:
    import io

    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    atomic_write_bytes(path, buf.getvalue())


def _load_npz(path: Path, names: Sequence[str]) -> dict[str, np.ndarray] | None:
    """The arrays ``names`` of a cached ``.npz``, or None if absent or damaged."""
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            return {n: np.asarray(z[n]) for n in names}
    except (OSError, ValueError, KeyError, EOFError):
        return None  # a damaged entry is recomputed


def _edge_one(task: tuple[str, str, str, str, str | None, str, str | None]) -> tuple[str, float]:
    """Worker: the computed edge map of one image, cached; returns (image key, seconds)."""
    root_s, folder, stem, edges, weights, final_s, raw_s = task
    final = Path(final_s) / f"{folder}__{stem}.npz"
    got = _load_npz(final, ["seconds"])
    if got is not None:
        return f"{folder}/{stem}", float(got["seconds"])
    from ._edges import edge_map, load_image

    image_path = Path(root_s) / folder / f"{stem}.jpg"
    t0 = time.perf_counter()
    if edges == "own":
        e = edge_map(load_image(image_path), method="own")
        sec = time.perf_counter() - t0
    else:
        from ._pidinet import edges_from_probability, fused_probability

        raw = Path(str(raw_s)) / f"{folder}__{stem}.npz"
        got = _load_npz(raw, ["prob", "seconds"])
        if got is None:
            prob = fused_probability(load_image(image_path), weights)
            net_sec = time.perf_counter() - t0
            _save_npz(raw, prob=prob.astype(np.float32), seconds=np.float64(net_sec))
        else:
            prob, net_sec = got["prob"], float(got["seconds"])
        t1 = time.perf_counter()
        e = edges_from_probability(prob)
        sec = net_sec + time.perf_counter() - t1
    _save_npz(final, edges=e.astype(np.float64), seconds=np.float64(sec))
    return f"{folder}/{stem}", sec


def _run_one(
    task: tuple[str, str, str, str, str, dict, int, str, str | None],
) -> tuple[str, str, str, dict]:
    """Worker: detect one class model in one image (cached)."""
    root_s, cls, folder, stem, cache_s, pdict, k, edges, edge_dir = task
    cache = Path(cache_s) / cls / f"{folder}__{stem}.json"
    if cache.exists():
        try:
            return cls, folder, stem, json.loads(cache.read_text())
        except (OSError, json.JSONDecodeError):
            pass
    from ._model import load_model

    root = Path(root_s)
    params = DetectParams(**pdict)
    if cls not in _MODELS:
        _MODELS[cls] = load_model(root / "models" / f"{ETHZ_CLASSES[cls][1]}.tif", m=params.m)
    t0 = time.perf_counter()
    if edges == "pb":
        run = detect_detailed(
            _MODELS[cls], None, edges=root / folder / f"{stem}_edges.tif", k=k, params=params
        )
    else:  # a computed map, read from the per-image edge cache (made once per image)
        got = _load_npz(Path(str(edge_dir)) / f"{folder}__{stem}.npz", ["edges"])
        if got is None:
            raise ShapeTreeError(f"edge map of {folder}/{stem} missing from {edge_dir}")
        run = detect_detailed(_MODELS[cls], None, edges=got["edges"], k=k, params=params)
    sec = time.perf_counter() - t0
    doc = {
        "seconds": sec,
        "timings": run.timings,
        "n_contours": len(run.contours),
        "detections": [
            {
                "score": d.score,
                "bbox": list(d.bbox),
                "coverage": d.coverage,
                "image_points": np.round(d.image_points, 2).tolist(),
                "matched": [bool(v) for v in d.matched],
                "pieces": [[int(p["contour"]), bool(p["reversed"])] for p in d.pieces],
                **{t: float(getattr(d, t)) for t in TEMPLATE_TERMS},
                **({} if d.match_bbox is None else {"match_bbox": list(d.match_bbox)}),
            }
            for d in run.detections
        ],
    }
    atomic_write_bytes(cache, json.dumps(doc).encode())
    return cls, folder, stem, doc


def _appearance_one(
    task: tuple[str, str, str, dict[str, list]],
) -> tuple[str, dict, tuple[int, int], float]:
    """Worker: the interior colour histograms of every class's detections in one image,
    and the image's ``(H, W)``."""
    from ._appearance import colour_bins, interior_histogram
    from ._edges import load_image

    root_s, folder, stem, outlines = task
    t0 = time.perf_counter()
    bins = colour_bins(load_image(Path(root_s) / folder / f"{stem}.jpg"))
    hists = {c: [interior_histogram(bins, pts) for pts in v] for c, v in outlines.items()}
    shape = (int(bins.shape[0]), int(bins.shape[1]))
    return f"{folder}/{stem}", hists, shape, time.perf_counter() - t0


def _collection_rank(
    results: dict[tuple[str, str, str], dict],
    hists: dict[str, dict[str, list]],
    shapes: dict[str, tuple[int, int]],
    models: dict[str, np.ndarray],
    params: DetectParams,
) -> None:
    """Add ``collection_score`` and the collection stage's terms to every detection (in
    place) and re-order each image's detections by the collection score."""
    from ._rescore import collection_table

    for c, model_points in models.items():
        items = [(key, doc) for key, doc in results.items() if key[0] == c]
        keys, dets, hs = [], [], []
        for (_c, f, s), doc in items:
            for d, h in zip(doc["detections"], hists[f"{f}/{s}"][c], strict=True):
                keys.append(f"{f}/{s}")
                dets.append(d)
                hs.append(h)
        if not keys:
            continue
        cs, table = collection_table(keys, dets, model_points, shapes, np.array(hs), params)
        i = 0
        for key, doc in items:
            ranked = [dict(d) for d in doc["detections"]]
            for d in ranked:
                d.update({t: float(v[i]) for t, v in table.items()})
                d["collection_score"] = float(cs[i])
                i += 1
            ranked.sort(key=lambda d: -d["collection_score"])
            results[key] = dict(doc, detections=ranked)


def _ranked_by_note(params: DetectParams, collection: bool) -> str:
    from ._rescore import collection_formula

    if not collection:
        return "score: each image's own ranking score (no collection stage, or one image)"
    fitted = " (in sample for the Pb run)" if params.collection_rescore else ""
    return (
        f"collection_score = {collection_formula(params)}{fitted}: the collection stage "
        "(transductive: each detection is compared with the most confident detections of "
        "the same model in the other images and with the other detections of its own "
        "image, no labels used)"
    )


def evaluate_ethz(
    data_dir: str | os.PathLike[str] | None = None,
    *,
    json_path: str | os.PathLike[str] | None = None,
    out_dir: str | os.PathLike[str] | None = None,
    classes: Sequence[str] | None = None,
    cache_dir: str | os.PathLike[str] | None = None,
    params: DetectParams | None = None,
    k: int = 5,
    workers: int = 2,
    progress: bool = True,
    images: Sequence[tuple[str, str]] | None = None,
    edges: str = "pb",
    edge_weights: str | os.PathLike[str] | None = None,
) -> dict[str, Any]:
    """Run the ETHZ protocol and report DR at 0.3 / 0.4 FPPI.

    Parameters
    ----------
    data_dir : path-like or None
        ETHZ location (see :func:`ethz_root`; default env ``SHAPETREE_DATA``).
    json_path : path-like or None
        Write the result dict here (atomically).
    out_dir : path-like or None
        Write ``ethz_dr_fppi.png`` (DR/FPPI curves) and
        ``ethz_gallery_swans.png`` / ``ethz_gallery_bottles.png`` (best
        detection in each image of the class) here.
    classes : sequence of str or None
        Subset of ``applelogos, bottles, giraffes, mugs, swans`` (default all).
    cache_dir : path-like or None
        Per-image detection cache (default ``$SHAPETREE_CACHE/ethz_detect``, i.e.
        ``~/.cache/shapetree/ethz_detect``); a sub-folder per hash of ``params``, ``k``
        and the code fingerprint, so a changed package never reuses stale detections.
    params : DetectParams or None
        Detection parameters (default :class:`DetectParams`).
    k : int
        Detections kept per image (default 5).
    workers : int
        Processes (default 2); 1 runs in-process.
    progress : bool
        Show a tqdm progress bar with ETA.
    images : sequence of (folder, stem) or None
        Restrict to these images (for quick checks; FPPI then uses their count).
    edges : {"pb", "own", "pidinet"}
        Edge source: ``"pb"`` (default) reads the Berkeley Pb maps shipped with the
        dataset (``*_edges.tif``); ``"own"`` computes the project's own edge map
        (:func:`edge_map`) from each image, as ``shapetree detect`` does on any photo;
        ``"pidinet"`` the learned PiDiNet map from the weights ``edge_weights``.  A
        computed map is made once per image (not per model) and cached under
        ``<cache>/edges/`` (keyed by the method, the weights' SHA-256 and the edge code;
        resumable).
    edge_weights : path-like or None
        ``edges="pidinet"`` only (required there): a PiDiNet ``table5_*.npz`` weights
        file (the authors' BSDS500 checkpoints, research use only, not shipped).

    Notes
    -----
    With the collection stage on (``params.collection_stage``: the re-scorer by default,
    :func:`shapetree.detection.rescore_collection`) and more than one image, the
    detections are ranked across images by their collection score: after the
    detections, each image is read once more for the colour histograms inside its
    detections' outlines. The per-image cache holds the detections with their own
    scores only, so other collection settings re-rank them without detecting again.

    Returns
    -------
    dict
        ``overlap_20`` / ``overlap_50`` -> ``dr_fppi_0.3`` / ``dr_fppi_0.4``
        -> {class: DR, "mean": DR}; ``seconds_per_image_median`` /
        ``_p90`` (one detection run of one model on one image, single core);
        ``seconds_breakdown_median`` / ``_mean`` per stage (edges, contours,
        tables, stitch, select; described under ``stages``); ``edges`` (the
        source); ``n_images``, ``n_gt``, ``params``, ``k``, ``classes``; for a
        computed source also ``edge_map_seconds_median`` / ``_mean`` (one map per
        image, computed once; its share per model is in the ``edges`` stage) and, for
        pidinet, ``edge_weights`` (file name, SHA-256, variant); ``ranked_by``
        (``"collection_score"`` or ``"score"``).
    """
    source = _EdgeSource.resolve(edges, edge_weights)
    root = ethz_root(data_dir)
    params = params or DetectParams()
    cls_list = _class_list(classes)
    imgs = list(images) if images is not None else _images(root)
    base = Path(cache_dir).expanduser() if cache_dir else default_cache_dir()
    cache = base / _params_key(params, k, source.key)
    edge_dir: Path | None = None
    raw_dir: Path | None = None
    if edges in COMPUTED_EDGES:
        edge_dir, raw_dir = edge_cache_dirs(base, edges, source.sha)
    # the collection stage: it needs another image to compare with
    collection = params.collection_stage and len(imgs) > 1
    pdict = params.as_dict()
    looks: list[tuple[str, dict, tuple[int, int], float]] = []
    with _mapper(workers) as imap:
        edge_secs = dict(
            _tracked(
                imap,
                _edge_one,
                source.edge_tasks(root, imgs, edge_dir, raw_dir),
                f"ETHZ {edges} edges",
                progress,
            )
        )
        tasks = [
            (str(root), c, f, s, str(cache), pdict, k, edges, _opt_str(edge_dir))
            for c in cls_list
            for f, s in imgs
        ]
        results = {
            (c, f, s): doc
            for c, f, s, doc in _tracked(imap, _run_one, tasks, "ETHZ detect", progress)
        }
        if collection:
            looks = list(
                _tracked(
                    imap,
                    _appearance_one,
                    _appearance_tasks(root, imgs, cls_list, results),
                    "ETHZ appearance",
                    progress,
                )
            )
    app_secs = {key: sec for key, _h, _shape, sec in looks}
    # a computed edge map and the colour bins serve every model run on their image: each
    # run carries its share
    _charge_shared(results, edge_secs, len(cls_list), "edges")
    _charge_shared(results, app_secs, len(cls_list), "appearance")
    if collection:
        from ._model import load_model

        models = {
            c: load_model(root / "models" / f"{ETHZ_CLASSES[c][1]}.tif", m=params.m).points
            for c in cls_list
        }
        hists = {key: h for key, h, _shape, _sec in looks}
        shapes = {key: shape for key, _h, shape, _sec in looks}
        _collection_rank(results, hists, shapes, models, params)
    rank_by = "collection_score" if collection else "score"

    out, curves, n_gt = _score(root, results, cls_list, imgs, rank_by)
    out.update(_timing_summary(results, edge_secs, edges, len(cls_list)))
    if edge_secs:
        out["edge_cache_dir"] = str(edge_dir)
    if source.info is not None:
        out["edge_weights"] = source.info
    out["edges"] = edges
    out["ranked_by"] = rank_by
    out["ranked_by_note"] = _ranked_by_note(params, collection)
    out["n_images"] = len(imgs)
    out["n_gt"] = n_gt
    out["k"] = k
    out["classes"] = cls_list
    out["params"] = pdict
    out["protocol"] = (
        "hand-drawn model vs all images; IoU>=0.2 (overlap_20) or >=0.5 (overlap_50) with an "
        "unclaimed GT box; DR at FPPI<=x is the max DR over score thresholds with FPPI<=x"
    )
    out["cache_dir"] = str(cache)
    if json_path is not None:
        atomic_write_bytes(json_path, (json.dumps(out, indent=2) + "\n").encode())
    if out_dir is not None:
        _plots(Path(out_dir), root, cls_list, curves, results, imgs)
    return out


def _opt_str(path: Path | None) -> str | None:
    return None if path is None else str(path)


@dataclass(frozen=True)
class _EdgeSource:
    """An edge source of the protocol, checked: its name, and for ``pidinet`` its weights
    (the file's path, SHA-256 and the record that goes into the result)."""

    edges: str
    weights_path: str | None = None
    sha: str | None = None
    info: dict[str, Any] | None = None

    @classmethod
    def resolve(cls, edges: str, edge_weights: str | os.PathLike[str] | None) -> _EdgeSource:
        if edges not in EDGE_SOURCES:
            raise ShapeTreeError(f"unknown edge source {edges!r}; choose one of {EDGE_SOURCES}")
        if edges == "pidinet":
            from ._pidinet import load_pidinet

            net = load_pidinet(edge_weights)  # a clear ShapeTreeError for missing / bad weights
            info = {"file": net.path.name, "sha256": net.sha256, "variant": net.variant}
            return cls(edges, str(net.path), net.sha256, info)
        if edge_weights is not None:
            raise ShapeTreeError(f"edge_weights is for edges='pidinet', not {edges!r}")
        return cls(edges)

    @property
    def key(self) -> str:
        """The source as it enters the detection cache key (:func:`_params_key`)."""
        return self.edges if self.sha is None else f"{self.edges}:{self.sha}"

    def edge_tasks(
        self, root: Path, imgs: Sequence[tuple[str, str]], final: Path | None, raw: Path | None
    ) -> list[tuple[str, str, str, str, str | None, str, str | None]]:
        """One :func:`_edge_one` task per image for a computed source, none for Pb."""
        if final is None:
            return []
        return [
            (str(root), f, s, self.edges, self.weights_path, str(final), _opt_str(raw))
            for f, s in imgs
        ]


def _class_list(classes: Sequence[str] | None) -> list[str]:
    """The classes to run, checked against :data:`ETHZ_CLASSES` (default all, in order)."""
    cls_list = list(classes) if classes else list(ETHZ_CLASSES)
    for c in cls_list:
        if c not in ETHZ_CLASSES:
            raise DatasetError(f"unknown ETHZ class {c!r}; known: {sorted(ETHZ_CLASSES)}")
    return cls_list


@contextmanager
def _mapper(workers: int) -> Iterator[Callable[[Callable, list], Iterable]]:
    """``map`` in this process (``workers <= 1``) or over a pool of spawned workers, each
    warmed up by :func:`_warm_up`; results arrive in any order."""
    if workers <= 1:
        _warm_up()
        yield map
        return
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    with ctx.Pool(workers, initializer=_warm_up) as pool:
        yield lambda fn, items: pool.imap_unordered(fn, items, chunksize=1)


def _tracked(
    imap: Callable[[Callable, list], Iterable], fn: Callable, tasks: list, desc: str, progress: bool
) -> Iterator:
    """``imap(fn, tasks)`` under a tqdm bar (per image); nothing, and no bar, without tasks."""
    if not tasks:
        return
    from tqdm import tqdm

    with tqdm(total=len(tasks), disable=not progress, desc=desc, unit="img") as bar:
        for item in imap(fn, tasks):
            yield item
            bar.update()


def _appearance_tasks(
    root: Path,
    imgs: Sequence[tuple[str, str]],
    cls_list: Sequence[str],
    results: dict[tuple[str, str, str], dict],
) -> list[tuple[str, str, str, dict[str, list]]]:
    """One :func:`_appearance_one` task per image: every class's placed outlines in it."""
    return [
        (
            str(root),
            f,
            s,
            {c: [d["image_points"] for d in results[(c, f, s)]["detections"]] for c in cls_list},
        )
        for f, s in imgs
    ]


def _charge_shared(
    results: dict[tuple[str, str, str], dict], secs: dict[str, float], n_models: int, stage: str
) -> None:
    """Add each image's once-per-image time ``secs`` (an edge map, the colour bins), split
    over the ``n_models`` runs on it, to every run's seconds and its ``stage`` (in place)."""
    for key, doc in results.items():
        extra = secs.get(f"{key[1]}/{key[2]}", 0.0) / n_models
        if extra:
            doc = dict(doc, seconds=doc["seconds"] + extra)
            doc["timings"] = dict(doc["timings"], **{stage: doc["timings"].get(stage, 0.0) + extra})
            results[key] = doc


def _score(
    root: Path,
    results: dict[tuple[str, str, str], dict],
    cls_list: Sequence[str],
    imgs: Sequence[tuple[str, str]],
    rank_by: str,
) -> tuple[dict[str, Any], dict[tuple[str, float], tuple[np.ndarray, np.ndarray]], dict[str, int]]:
    """DR at 0.3 / 0.4 FPPI and the share of boxes any kept detection finds, per class and
    their mean, under both overlap rules; the DR/FPPI curves; the ground-truth counts."""
    out: dict[str, Any] = {"overlap_20": {}, "overlap_50": {}}
    curves: dict[tuple[str, float], tuple[np.ndarray, np.ndarray]] = {}
    n_gt: dict[str, int] = {}
    for thr, key in ((0.2, "overlap_20"), (0.5, "overlap_50")):
        for at in (0.3, 0.4):
            out[key][f"dr_fppi_{at}"] = {}
        for c in cls_list:
            folder = ETHZ_CLASSES[c][0]
            gts = {f"{f}/{s}": _gt_boxes(root, f, s, c) for f, s in imgs if f == folder}
            n_gt[c] = int(sum(len(g) for g in gts.values()))
            dets = [
                (f"{f}/{s}", d[rank_by], d["bbox"])
                for f, s in imgs
                for d in results[(c, f, s)]["detections"]
            ]
            fppi, dr, _ = dr_fppi_curve(dets, gts, len(imgs), thr)
            curves[(c, thr)] = (fppi, dr)
            out[key].setdefault("recall_any_k", {})[c] = round(recall_any(dets, gts, thr), 4)
            for at in (0.3, 0.4):
                out[key][f"dr_fppi_{at}"][c] = round(dr_at_fppi(fppi, dr, at), 4)
        for sub in [f"dr_fppi_{at}" for at in (0.3, 0.4)] + ["recall_any_k"]:
            v = out[key][sub]
            v["mean"] = round(float(np.mean([v[c] for c in cls_list])), 4)
    return out, curves, n_gt


def _timing_summary(
    results: dict[tuple[str, str, str], dict],
    edge_secs: dict[str, float],
    edges: str,
    n_models: int,
) -> dict[str, Any]:
    """Median / 90th percentile seconds of one detection run, per stage medians and means,
    and for a computed edge source the per-image map times."""
    secs = np.array([d["seconds"] for d in results.values()])
    out: dict[str, Any] = {
        "seconds_per_image_median": round(float(np.median(secs)), 4),
        "seconds_per_image_p90": round(float(np.percentile(secs, 90)), 4),
    }
    for name, stat in (("median", np.median), ("mean", np.mean)):
        out[f"seconds_breakdown_{name}"] = {
            st: round(float(stat([d["timings"].get(st, 0.0) for d in results.values()])), 4)
            for st in STAGES
        }
    out["stages"] = dict(STAGES)
    out["seconds_per_image_note"] = (
        "one model on one image, one process (single core), "
        + (
            "Pb edges read from disk"
            if edges == "pb"
            else f"{edges} edge map computed once per image, its time shared by the "
            f"{n_models} models run on it"
        )
        + "; includes contour tracing, tables and stitching"
    )
    if edge_secs:
        es = np.array(list(edge_secs.values()))
        out["edge_map_seconds_median"] = round(float(np.median(es)), 4)
        out["edge_map_seconds_mean"] = round(float(np.mean(es)), 4)
        out["edge_map_note"] = (
            "seconds to compute one image's edge map (image read, map, thinning), once per "
            "image; a map read back from the edge cache keeps the time it took when made"
        )
    return out


def _plots(out_dir: Path, root: Path, cls_list, curves, results, imgs) -> None:
    """DR/FPPI curves and the swan / bottle galleries (drawn by :mod:`shapetree.plotting`)."""
    from shapetree.plotting._detection import save_ethz_figures

    galleries = {}
    for c in ("swans", "bottles"):
        if c not in cls_list:
            continue
        folder = ETHZ_CLASSES[c][0]
        galleries[c] = [
            (
                s,
                root / f / f"{s}.jpg",
                _gt_boxes(root, f, s, c),
                (results[(c, f, s)]["detections"] or [None])[0],
            )
            for f, s in imgs
            if f == folder
        ]
    save_ethz_figures(out_dir, curves, galleries)
