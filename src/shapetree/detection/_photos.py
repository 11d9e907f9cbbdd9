"""Detection on a batch of users' photos (``shapetree detect MODEL IMAGES...``).

:func:`collect_images` expands files and folders (image extensions, natural sort);
:func:`detect_images` runs one model over them with a progress bar and writes, per image,
a JSON record and a Fig. 5-style picture into a folder, or JSON lines into a file or a
stream.  Runs are resumable: a record carries a key (hash of the model file, the
parameters, ``k``, the edge source, the image file's path / size / modification time and
the code fingerprint); an image whose record exists with the same key is skipped.  Every
file goes through :mod:`shapetree._atomic`.  With two or more images, the collection stage
(:func:`collection_ranking`) ranks all their detections together by the re-scorer's
collection score (``ranking.json``).  A bad image (unreadable, empty, too large, too
small) gives an error record and a message; the batch goes on and counts it.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import re
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import numpy as np

from shapetree._atomic import atomic_write_bytes
from shapetree._errors import ImageError, ShapeTreeError

from ._detect import COLLECTION_FIELDS, DetectParams, detect_detailed
from ._edges import EDGE_METHODS, load_image
from ._model import DetectionModel, load_model

__all__ = [
    "IMAGE_EXTENSIONS",
    "BatchSummary",
    "collect_images",
    "collection_ranking",
    "detect_images",
    "natural_key",
]

#: File extensions taken from folders (files named on the command line are always tried).
IMAGE_EXTENSIONS = (
    ".jpg",
    ".jpeg",
    ".png",
    ".tif",
    ".tiff",
    ".bmp",
    ".gif",
    ".webp",
    ".ppm",
    ".pgm",
    ".pbm",
)

RECORD_VERSION = 1
#: base name of the collection ranking written beside the records (``ranking.json``)
RANKING_NAME = "ranking"


def natural_key(path: str | os.PathLike[str]) -> list[Any]:
    """Sort key that orders ``img2`` before ``img10`` (case-insensitive)."""
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", str(path))]


def collect_images(
    sources: Iterable[str | os.PathLike[str]], *, recursive: bool = False
) -> list[Path]:
    """Image files named by ``sources``: files as given, folders expanded.

    Parameters
    ----------
    sources : iterable of path-like
        Files (kept whatever their extension, so a bad file is reported, not
        skipped) and folders (their files with an extension in
        :data:`IMAGE_EXTENSIONS`, in natural order).
    recursive : bool
        Also look into sub-folders.

    Returns
    -------
    list of Path
        In the order given, each folder's files naturally sorted; duplicates dropped.
        A path that does not exist is kept (its record says so).

    Raises
    ------
    ShapeTreeError
        If no source is given, or a folder holds no image.
    """
    out: list[Path] = []
    seen: set[Path] = set()
    srcs = list(sources)
    if not srcs:
        raise ShapeTreeError("no images given")
    for src in srcs:
        p = Path(src)
        if p.is_dir():
            pattern = "**/*" if recursive else "*"
            found = sorted(
                (
                    f
                    for f in p.glob(pattern)
                    if f.is_file() and f.suffix.lower() in IMAGE_EXTENSIONS
                ),
                key=natural_key,
            )
            if not found:
                raise ShapeTreeError(
                    f"folder {p} holds no image ({', '.join(IMAGE_EXTENSIONS)})"
                    + ("" if recursive else "; --recursive looks into sub-folders")
                )
        else:
            found = [p]
        for f in found:
            key = f.resolve() if f.exists() else f.absolute()
            if key not in seen:
                seen.add(key)
                out.append(f)
    return out


def _file_sha(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _image_stamp(path: Path) -> dict[str, Any]:
    try:
        st = path.stat()
        return {"path": str(path.absolute()), "size": st.st_size, "mtime_ns": st.st_mtime_ns}
    except OSError:
        return {"path": str(path.absolute()), "size": None, "mtime_ns": None}


def _record_names(images: Sequence[Path]) -> list[str]:
    """One output base name per image: its stem, with ``-2``, ``-3``... on collisions
    (``ranking`` is taken by the collection ranking, so ``ranking.jpg`` is ``ranking-2``)."""
    names: list[str] = []
    used: dict[str, int] = {RANKING_NAME: 1}
    for p in images:
        stem = re.sub(r"[^\w.+-]", "_", p.stem) or "image"
        n = used.get(stem.lower(), 0) + 1
        used[stem.lower()] = n
        names.append(stem if n == 1 else f"{stem}-{n}")
    return names


@dataclass
class BatchSummary:
    """What :func:`detect_images` did.

    Attributes
    ----------
    done, skipped, failed : int
        Images detected now, skipped (their record was already there with the same key),
        and failed (an error record, written now or before: a skipped image whose record
        is an error counts in both).
    records : list of dict
        The records of this call, in image order (skipped ones as read back).
    ranking : list of dict
        The collection stage (``params.collection_stage``, on by default, and detections
        in two or more images): every detection of the batch, best first by its
        collection score (:func:`~shapetree.detection.rescore_collection`, or
        :func:`~shapetree.detection.collection_scores` with ``collection_rescore=False``),
        each with ``image``, ``rank`` (its index in the image's record), ``score``,
        ``collection_score``, ``bbox``, ``appearance`` and, with the re-scorer, its
        other terms; empty otherwise.
    ranking_path : Path or None
        Where the ranking was written (``ranking.json`` in the output folder, else
        ``<jsonl stem>.ranking.json`` beside the JSON-lines file), or None.
    seconds : float
    """

    done: int = 0
    skipped: int = 0
    failed: int = 0
    records: list[dict[str, Any]] = field(default_factory=list)
    ranking: list[dict[str, Any]] = field(default_factory=list)
    ranking_path: Path | None = None
    seconds: float = 0.0


def collection_ranking(
    records: Sequence[dict[str, Any]], params: DetectParams, progress: bool = False
) -> list[dict[str, Any]]:
    """The collection stage over the records of a batch (see :class:`BatchSummary`).

    Each image with detections is read again for the colour histograms inside their
    outlines; an image that cannot be read now is left out of the ranking. Returns an
    empty list where the stage is off (``params.collection_stage``) or fewer than two
    images have a detection.
    """
    from tqdm import tqdm

    from ._appearance import colour_bins, interior_histogram
    from ._rescore import collection_table

    todo = [r for r in records if r.get("status") == "ok" and r.get("detections")]
    if not params.collection_stage or len({r["image"] for r in todo}) < 2:
        return []
    keys, dets, hists, rows, shapes = [], [], [], [], {}
    for r in tqdm(todo, desc="collection", unit="img", disable=not progress, file=sys.stderr):
        try:
            bins = colour_bins(load_image(r["image"]))
        except (ShapeTreeError, OSError, MemoryError):
            continue
        shapes[r["image"]] = bins.shape[:2]
        for i, d in enumerate(r["detections"]):
            keys.append(r["image"])
            dets.append(d)
            hists.append(interior_histogram(bins, d["image_points"]))
            rows.append({"image": r["image"], "rank": i, "bbox": d["bbox"]})
    if len(set(keys)) < 2:
        return []
    model_points = next(r["model_points"] for r in todo if r["image"] in shapes)
    cs, table = collection_table(keys, dets, model_points, shapes, np.array(hists), params)
    out = [
        {
            **row,
            "score": float(d["score"]),
            "collection_score": float(cs[i]),
            **{t: round(float(v[i]), 6) for t, v in table.items()},
        }
        for i, (row, d) in enumerate(zip(rows, dets, strict=True))
    ]
    out.sort(key=lambda d: -d["collection_score"])
    return out


def _ranking_note(p: DetectParams) -> str:
    from ._rescore import collection_formula

    return (
        f"every detection of the batch, best first by collection_score = "
        f"{collection_formula(p)}; appearance is the colour agreement with the most "
        "confident detections of the other images; score is the image's own"
    )


def _detection_record(det: Any) -> dict[str, Any]:
    doc = det.to_json()
    doc.pop("model_points", None)  # the same for every detection: kept once per record
    return doc


def detect_images(
    model: str | os.PathLike[str] | DetectionModel,
    images: Sequence[str | os.PathLike[str]],
    *,
    out_dir: str | os.PathLike[str] | None = "shapetree-detect",
    jsonl: str | os.PathLike[str] | IO[str] | None = None,
    pictures: bool = True,
    edges: str = "own",
    k: int = 5,
    params: DetectParams | None = None,
    force: bool = False,
    progress: bool = True,
    report: Callable[[str], None] | None = None,
) -> BatchSummary:
    """Detect a model in many images, one record (and picture) per image, resumable.

    Parameters
    ----------
    model : path-like or DetectionModel
        A silhouette or outline image, an SVG file, or a point file (see
        :func:`load_model`); a model that cannot be read raises at once.
    images : sequence of path-like
        Image files (see :func:`collect_images` to expand folders).
    out_dir : path-like or None
        Folder for ``<stem>.json`` records and ``<stem>.png`` pictures (created).  None
        writes no files there (then ``jsonl`` must be given).
    jsonl : path-like, text stream or None
        Also (or instead) write the records as JSON lines: to this file (rewritten
        atomically after each image; records already in it with the same key are kept
        and their images skipped) or to this open stream (e.g. ``sys.stdout``).
    pictures : bool
        Write the Fig. 5-style picture of each image into ``out_dir`` (default True).
    edges : {"own", "gradient", "pidinet"} or path-like
        Edge source: the project's edge detectors (:func:`edge_map` methods; "pidinet"
        needs ``params.edge_weights``, a PiDiNet weights file) or, for a single image, a
        stored soft edge map.
    k : int
        Detections per image.
    params : DetectParams or None
    force : bool
        Recompute images whose records exist.
    progress : bool
        tqdm progress bar with ETA (on stderr).
    report : callable or None
        Receives one line per failed image (default: printed to stderr).

    Notes
    -----
    After the images, the collection stage (``params.collection_stage``; on by
    default) with detections in two or more images ranks every detection of the batch
    by its collection score (see :class:`BatchSummary`, :func:`collection_ranking`) and
    writes that ranking atomically: ``ranking.json`` in ``out_dir``, else
    ``<jsonl stem>.ranking.json`` beside a JSON-lines file (not for a stream). The
    per-image records and their scores do not depend on the other images; the
    ranking is made again on every call, from the records and the images.

    Returns
    -------
    BatchSummary

    Raises
    ------
    ShapeTreeError
        For a bad model, parameters or edge source, or when neither ``out_dir`` nor
        ``jsonl`` is given; never for a bad image.
    """
    t_start = time.perf_counter()
    p = params or DetectParams()
    if out_dir is None and jsonl is None:
        raise ShapeTreeError("nowhere to write: give an output folder or a JSON-lines target")
    if k < 1:
        raise ShapeTreeError(f"k must be >= 1, got {k}")
    imgs = [Path(i) for i in images]
    p, edge_file, edge_desc = _edge_source(edges, len(imgs), p)
    mdl, model_desc = _batch_model(model, p)
    p = dataclasses.replace(p, m=len(mdl.points))
    from shapetree import __version__
    from shapetree._cache import code_fingerprint

    base_key = {
        "version": RECORD_VERSION,
        "model": model_desc,
        "params": p.as_dict(collection=False),  # the collection stage is redone each run
        "k": k,
        "edges": edge_desc,
        "code": code_fingerprint(),
        "pictures": bool(pictures and out_dir is not None),
    }
    from tqdm import tqdm

    say = report or (lambda line: tqdm.write(line, file=sys.stderr))
    outputs = _Outputs.open(out_dir, jsonl, pictures)
    model_name = model_desc.get("file", model_desc.get("name"))
    summary = BatchSummary()
    bar = tqdm(imgs, desc="detect", unit="img", disable=not progress, file=sys.stderr)
    for img_path, name in zip(bar, _record_names(imgs), strict=True):
        stamp = _image_stamp(img_path)
        key = hashlib.sha256(
            json.dumps({**base_key, "image": stamp}, sort_keys=True).encode()
        ).hexdigest()[:24]
        pic_path = outputs.picture_path(name)
        old = None if force else outputs.existing(key, name)
        if old is not None:
            summary.skipped += 1
            if old.get("status") != "ok":  # the same file fails the same way: say so again
                summary.failed += 1
                say(f"shapetree: {img_path}: error: {old.get('error')} (recorded before)")
            summary.records.append(old)
            outputs.echo(old)
            continue
        record: dict[str, Any] = {
            "key": key,
            "image": str(img_path),
            "image_file": stamp,
            "model": model_name,
            "edges": edge_desc,
            "k": k,
        }
        try:
            record.update(_detect_record(mdl, img_path, stamp, edge_file, k, p, pic_path))
            summary.done += 1
        except (ShapeTreeError, OSError, MemoryError) as exc:
            msg = " ".join(str(exc).split()) or type(exc).__name__
            record.update(status="error", error=msg, detections=[])
            summary.failed += 1
            say(f"shapetree: {img_path}: error: {msg}")
        record["params"] = p.as_dict()
        record["shapetree_version"] = __version__
        summary.records.append(record)
        outputs.write(key, name, record)
    bar.close()
    summary.ranking = collection_ranking(summary.records, p, progress=progress)
    summary.ranking_path = outputs.write_ranking(summary.ranking, p, model_name)
    summary.seconds = time.perf_counter() - t_start
    return summary


def _edge_source(
    edges: str | os.PathLike[str], n_images: int, p: DetectParams
) -> tuple[DetectParams, Path | None, dict[str, Any]]:
    """The batch's edge source, checked: the parameters with its method, the stored map
    (one image only) or None, and its description for the records' keys."""
    if str(edges) in EDGE_METHODS:
        edge_desc: dict[str, Any] = {"method": str(edges)}
        p = dataclasses.replace(p, edge_method=str(edges))  # checks the weights (pidinet)
        if p.edge_weights is not None:
            from ._pidinet import check_weights

            edge_desc["weights_sha256"] = check_weights(p.edge_weights)
        return p, None, edge_desc
    edge_file = Path(edges)
    if n_images != 1:
        raise ShapeTreeError(
            f"a stored edge map ({edge_file}) fits one image, got {n_images}; "
            f"use --edges {'/'.join(EDGE_METHODS)} for many"
        )
    if not edge_file.is_file():
        raise ShapeTreeError(f"edge map file not found: {edge_file}")
    return p, edge_file, {"file": str(edge_file), "sha256": _file_sha(edge_file)}


def _batch_model(
    model: str | os.PathLike[str] | DetectionModel, p: DetectParams
) -> tuple[DetectionModel, dict[str, Any]]:
    """The model, read at ``p.m`` points, and its description for the records' keys."""
    if isinstance(model, DetectionModel):
        return model, {"name": model.name, "points": model.points.round(6).tolist()}
    mpath = Path(model)
    if not mpath.is_file():
        raise ShapeTreeError(f"model file not found: {mpath}")
    return load_model(mpath, m=p.m), {"file": str(mpath), "sha256": _file_sha(mpath)}


def _detect_record(
    mdl: DetectionModel,
    img_path: Path,
    stamp: dict[str, Any],
    edge_file: Path | None,
    k: int,
    p: DetectParams,
    pic_path: Path | None,
) -> dict[str, Any]:
    """Detect the model in one image (and draw it): the record's fields of a success.
    Raises for an empty or unreadable image."""
    t0 = time.perf_counter()
    if stamp["size"] == 0:
        raise ImageError(f"image file {img_path} is empty (0 bytes)")
    image = load_image(img_path)
    run = detect_detailed(mdl, image, edges=edge_file, k=k, params=p)
    if pic_path is not None:
        from shapetree.plotting import plot_detections

        plot_detections(run, image, title=f"{mdl.name} in {img_path.name}", path=pic_path)
    return {
        "status": "ok",
        "image_size": [int(image.shape[1]), int(image.shape[0])],
        "seconds": round(time.perf_counter() - t0, 4),
        "timings": {s: round(v, 4) for s, v in run.timings.items()},
        "n_contours": len(run.contours),
        "model_points": run.model.points.round(3).tolist(),
        "picture": str(pic_path) if pic_path is not None else None,
        "detections": [_detection_record(d) for d in run.detections],
    }


@dataclass
class _Outputs:
    """Where a batch writes: per-image ``<name>.json`` records and ``<name>.png``
    pictures in a folder, a JSON-lines file (rewritten atomically after each image) or
    stream, and the collection ranking; and the records already there."""

    out: Path | None
    pictures: bool
    jsonl_path: Path | None = None
    stream: IO[str] | None = None
    lines: dict[str, dict[str, Any]] = field(default_factory=dict)  # key -> JSON-lines record

    @classmethod
    def open(
        cls,
        out_dir: str | os.PathLike[str] | None,
        jsonl: str | os.PathLike[str] | IO[str] | None,
        pictures: bool,
    ) -> _Outputs:
        out = Path(out_dir) if out_dir is not None else None
        if out is not None:
            if out.exists() and not out.is_dir():
                raise ShapeTreeError(f"{out}: exists and is not a folder")
            out.mkdir(parents=True, exist_ok=True)
        self = cls(out, pictures)
        if jsonl is None:
            return self
        if hasattr(jsonl, "write"):
            self.stream = jsonl  # type: ignore[assignment]
            return self
        self.jsonl_path = Path(jsonl)  # type: ignore[arg-type]
        if self.jsonl_path.is_file():
            for line in self.jsonl_path.read_text(encoding="utf-8").splitlines():
                try:
                    rec = json.loads(line)
                    self.lines[rec["key"]] = rec
                except (json.JSONDecodeError, KeyError, TypeError):
                    continue  # a damaged line is recomputed
        return self

    @property
    def _jsonl(self) -> bool:
        return self.jsonl_path is not None or self.stream is not None

    def record_path(self, name: str) -> Path | None:
        """The per-image record file: in the folder, unless JSON lines are written."""
        return self.out / f"{name}.json" if self.out is not None and not self._jsonl else None

    def picture_path(self, name: str) -> Path | None:
        return self.out / f"{name}.png" if self.out is not None and self.pictures else None

    def existing(self, key: str, name: str) -> dict[str, Any] | None:
        """The stored record of this image with this key (see :func:`_existing`)."""
        return _existing(key, self.record_path(name), self.picture_path(name), self.lines)

    def echo(self, record: dict[str, Any]) -> None:
        """A record kept from before goes to the stream again."""
        if self.stream is not None:
            self.stream.write(json.dumps(record) + "\n")

    def write(self, key: str, name: str, record: dict[str, Any]) -> None:
        """A new record: its file, the whole JSON-lines file again, or the stream."""
        rec_path = self.record_path(name)
        if rec_path is not None:
            atomic_write_bytes(
                rec_path, (json.dumps(record, indent=1) + "\n").encode(), fsync=False
            )
        if self.jsonl_path is not None:
            self.lines[key] = record
            text = "".join(json.dumps(r) + "\n" for r in self.lines.values())
            atomic_write_bytes(self.jsonl_path, text.encode(), fsync=False)
        if self.stream is not None:
            self.stream.write(json.dumps(record) + "\n")
            self.stream.flush()

    def _ranking_paths(self) -> list[Path]:
        """Where a ranking goes, first choice first: ``ranking.json`` in the folder, then
        ``<stem>.ranking.json`` beside the JSON-lines file; none for a stream alone."""
        paths = [self.out / f"{RANKING_NAME}.json"] if self.out is not None else []
        if self.jsonl_path is not None:
            paths.append(self.jsonl_path.with_name(f"{self.jsonl_path.stem}.ranking.json"))
        return paths

    def write_ranking(
        self, ranking: list[dict[str, Any]], p: DetectParams, model_name: Any
    ) -> Path | None:
        """Write the collection ranking atomically to the first of :meth:`_ranking_paths`
        (a rerun with the same ranking touches nothing) and return its path; with no
        ranking, remove the rankings of earlier runs there, which would now mislead."""
        paths = self._ranking_paths()
        if not ranking:
            for path in paths:
                path.unlink(missing_ok=True)
            return None
        if not paths:
            return None
        path = paths[0]
        doc = {
            "model": model_name,
            "n_images": len({d["image"] for d in ranking}),
            **{f: getattr(p, f) for f in COLLECTION_FIELDS},
            "note": _ranking_note(p),
            "detections": ranking,
        }
        blob = (json.dumps(doc, indent=1) + "\n").encode()
        if not (path.is_file() and path.read_bytes() == blob):
            atomic_write_bytes(path, blob, fsync=False)
        return path


def _existing(
    key: str, rec_path: Path | None, pic_path: Path | None, lines: dict[str, dict[str, Any]]
) -> dict[str, Any] | None:
    """The stored record of this image with this key, if it and its picture exist."""
    rec = lines.get(key)
    if rec is None and rec_path is not None and rec_path.is_file():
        try:
            doc = json.loads(rec_path.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError, UnicodeDecodeError):
            return None
        rec = doc if isinstance(doc, dict) and doc.get("key") == key else None
    if rec is None:
        return None
    if pic_path is not None and rec.get("status") == "ok" and not pic_path.is_file():
        return None
    return rec
