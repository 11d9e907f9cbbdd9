"""Loading silhouette datasets as closed curves, with an on-disk curve cache."""

from __future__ import annotations

import csv
import hashlib
import json
import os
import re
import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from shapetree._atomic import atomic_open
from shapetree._errors import DatasetError, ImageError, ShapeTreeError
from shapetree.datasets._registry import (
    REGISTRY,
    DatasetSpec,
    cache_dir,
    data_dir,
    get_spec,
)

__all__ = [
    "DatasetInfo",
    "ShapeDataset",
    "available",
    "dataset_path",
    "format_available",
    "load",
    "load_labels",
]

#: Bump when the cache file layout or the extraction recipe changes.
_CACHE_VERSION = 1
_MPEG7_NAME = re.compile(r"^(?P<cls>.+)-(?P<num>\d+)\.png$")


@dataclass
class ShapeDataset:
    """A silhouette dataset as closed curves.

    Attributes
    ----------
    name : str
        Registry name (``mpeg7``, ``kimia99``, ``swedish_leaf``).
    names : list of str
        Image file names (relative to ``images_dir``), in ``labels.csv`` order.
    labels : numpy.ndarray of str
        Class label of each image.
    curves : list of numpy.ndarray
        Closed outer boundaries, each ``(n, 2)`` float64 ``(x, y)`` with ``x`` the
        column and ``y`` the row, first point not repeated.
    images_dir : pathlib.Path
        Folder holding the images.
    """

    name: str
    names: list[str]
    labels: np.ndarray
    curves: list[np.ndarray]
    images_dir: Path

    def __len__(self) -> int:
        return len(self.names)

    @property
    def classes(self) -> list[str]:
        """Sorted list of the distinct labels."""
        return sorted(set(self.labels.tolist()))

    @property
    def paths(self) -> list[Path]:
        """Full paths of the images."""
        return [self.images_dir / n for n in self.names]


@dataclass(frozen=True)
class DatasetInfo:
    """What :func:`available` found for one dataset.

    Attributes
    ----------
    name : str
        Registry name.
    path : pathlib.Path
        Folder where the dataset is expected.
    present : bool
        Whether the folder exists and holds at least one image.
    count : int
        Number of images found.
    expected : int
        Number of images the complete dataset has.
    description : str
        One-line description from the registry.
    """

    name: str
    path: Path
    present: bool
    count: int
    expected: int
    description: str

    @property
    def complete(self) -> bool:
        """Whether all expected images are there."""
        return self.present and self.count == self.expected


def _how_to_get(name: str) -> str:
    return (
        f"get it with `shapetree datasets fetch {name}` (or shapetree.datasets.fetch({name!r})), "
        "or set SHAPETREE_DATA to the folder that contains "
        f"{name}/"
    )


def dataset_path(name: str, root: str | os.PathLike[str] | None = None) -> Path:
    """Return the folder of a dataset, checking that it exists.

    Parameters
    ----------
    name : str
        Registry name.
    root : path-like, optional
        The dataset's own folder; default ``data_dir() / name``.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    DatasetError
        If the name is unknown or the folder does not exist; the message says
        where it looked and how to get the data.
    """
    get_spec(name)
    folder = Path(root).expanduser() if root is not None else data_dir() / name
    if not folder.is_dir():
        origin = (
            "given root"
            if root is not None
            else (
                "$SHAPETREE_DATA"
                if os.environ.get("SHAPETREE_DATA", "").strip()
                else "default data dir"
            )
        )
        raise DatasetError(
            f"dataset {name!r} not found: looked in {folder} ({origin}); {_how_to_get(name)}"
        )
    return folder


def _images_dir(spec: DatasetSpec, folder: Path) -> Path:
    if not spec.images_subdir:
        return folder
    primary = folder / spec.images_subdir
    if primary.is_dir():
        return primary
    fallback = spec.extra.get("fallback_subdir")
    if fallback and (folder / fallback).is_dir():
        return folder / fallback
    raise DatasetError(
        f"dataset {spec.name!r} in {folder} is incomplete: no {spec.images_subdir}/ folder"
        + (f" (nor {fallback}/)" if fallback else "")
        + f"; {_how_to_get(spec.name)}"
    )


def _read_labels_csv(path: Path, column: str) -> tuple[list[str], list[str]]:
    try:
        with open(path, newline="", encoding="utf-8") as f:
            rows = list(csv.reader(f))
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        raise DatasetError(f"{path}: cannot read labels file ({e})") from e
    if not rows:
        raise DatasetError(f"{path}: labels file is empty")
    header = [h.strip() for h in rows[0]]
    for need in ("filename", column):
        if need not in header:
            raise DatasetError(
                f"{path}: labels file has no {need!r} column (header: {','.join(header)})"
            )
    i_file, i_lab = header.index("filename"), header.index(column)
    names: list[str] = []
    labels: list[str] = []
    seen: set[str] = set()
    for lineno, row in enumerate(rows[1:], start=2):
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) <= max(i_file, i_lab):
            raise DatasetError(f"{path}: line {lineno} has {len(row)} fields, expected more")
        fname, lab = row[i_file].strip(), row[i_lab].strip()
        if not fname or not lab:
            raise DatasetError(f"{path}: line {lineno} has an empty filename or {column}")
        if "/" in fname or "\\" in fname or fname in (".", ".."):
            raise DatasetError(f"{path}: line {lineno}: bad file name {fname!r}")
        if fname in seen:
            raise DatasetError(f"{path}: line {lineno}: duplicate file name {fname!r}")
        seen.add(fname)
        names.append(fname)
        labels.append(lab)
    if not names:
        raise DatasetError(f"{path}: labels file lists no images")
    return names, labels


def _mpeg7_labels_from_names(folder: Path) -> tuple[list[str], list[str]]:
    names, labels = [], []
    for p in sorted(folder.glob("*.png")):
        m = _MPEG7_NAME.match(p.name)
        if m is None:
            raise DatasetError(f"{p}: file name is not <class>-<n>.png")
        names.append(p.name)
        labels.append(m.group("cls"))
    if not names:
        raise DatasetError(f"dataset 'mpeg7' in {folder} has no labels.csv and no *.png files")
    return names, labels


def load_labels(
    name: str, *, root: str | os.PathLike[str] | None = None
) -> tuple[list[str], np.ndarray, Path]:
    """Read a dataset's file names and class labels without touching the images.

    Parameters
    ----------
    name : str
        ``mpeg7``, ``kimia99`` or ``swedish_leaf``.
    root : path-like, optional
        The dataset's own folder; default ``data_dir() / name``.

    Returns
    -------
    names : list of str
        Image file names, in ``labels.csv`` order.
    labels : numpy.ndarray of str
        Class of each image: column ``class`` (mpeg7, kimia99) or
        ``species_name`` (swedish_leaf). For mpeg7 without ``labels.csv`` the
        class is the file name's part before the last ``-``.
    images_dir : pathlib.Path
        Folder holding the images (``png512/`` for swedish_leaf, or
        ``source_png_fullres/`` when only that is present).

    Raises
    ------
    DatasetError
        If the dataset is missing, the labels file is bad, or a listed image is missing.
    """
    spec = get_spec(name)
    if not spec.loadable:
        raise DatasetError(
            f"dataset {name!r} is not a silhouette set; use shapetree.datasets.load_ethz()"
        )
    folder = dataset_path(name, root)
    images = _images_dir(spec, folder)
    csv_path = folder / "labels.csv"
    if csv_path.is_file():
        names, labels = _read_labels_csv(csv_path, spec.label_column or "class")
    elif name == "mpeg7":
        names, labels = _mpeg7_labels_from_names(images)
    else:
        raise DatasetError(f"{csv_path}: labels file is missing; {_how_to_get(name)}")
    missing = [n for n in names if not (images / n).is_file()]
    if missing:
        more = f" and {len(missing) - 3} more" if len(missing) > 3 else ""
        raise DatasetError(
            f"dataset {name!r}: {len(missing)} image(s) listed in labels but missing from "
            f"{images}: {', '.join(missing[:3])}{more}"
        )
    return names, np.array(labels, dtype=str), images


def _read_gray(path: Path) -> np.ndarray:
    from shapetree.curves._image import open_image

    try:
        with open_image(path) as im:  # refuses images over the pixel limit, undecoded
            im.load()
            arr = np.asarray(im.convert("L"))
    except ImageError as e:
        raise DatasetError(str(e)) from None
    except (OSError, ValueError, SyntaxError) as e:
        raise DatasetError(f"{path}: cannot read image ({type(e).__name__}: {e})") from e
    if arr.ndim != 2 or arr.size == 0:
        raise DatasetError(f"{path}: image is empty")
    return arr


def _extract_curve(path: Path, n_points: int | None, orientation: str | None) -> np.ndarray:
    from shapetree import curves

    gray = _read_gray(path)
    try:
        c = curves.curve_from_image(gray, polarity="auto")
        if orientation is not None:
            c = curves.orient(c, orientation)
        if n_points is not None:
            c = curves.resample(c, n_points, closed=True)
    except ShapeTreeError as e:
        raise DatasetError(f"{path}: cannot extract a curve ({e})") from e
    c = np.ascontiguousarray(c, dtype=np.float64)
    if c.ndim != 2 or c.shape[1] != 2 or len(c) < 3 or not np.isfinite(c).all():
        raise DatasetError(f"{path}: extracted curve is invalid (shape {c.shape})")
    return c


def _cache_key(
    name: str,
    images: Path,
    names: Sequence[str],
    labels: Sequence[str],
    n_points: int | None,
    orientation: str | None,
) -> str:
    entries = []
    for n, lab in zip(names, labels, strict=True):
        st = (images / n).stat()
        entries.append([n, lab, st.st_size, st.st_mtime_ns])
    from shapetree import __version__

    blob = json.dumps(
        [_CACHE_VERSION, __version__, name, str(images.resolve()), n_points, orientation, entries]
    )
    return hashlib.sha256(blob.encode("utf-8")).hexdigest()[:20]


def _cache_file(name: str, n_points: int | None, orientation: str | None, key: str) -> Path:
    return cache_dir() / f"{name}-n{n_points or 'raw'}-{orientation or 'asis'}-{key}.npz"


def _read_cache(path: Path, names: Sequence[str]) -> list[np.ndarray] | None:
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            cnames = z["names"].tolist()
            counts = z["counts"].astype(np.int64)
            points = z["points"].astype(np.float64)
    except Exception as e:  # corrupt cache: recompute, never fail the load
        warnings.warn(f"ignoring unreadable curve cache {path}: {e}", stacklevel=3)
        return None
    if cnames != list(names) or counts.sum() != len(points) or points.ndim != 2:
        warnings.warn(f"ignoring inconsistent curve cache {path}", stacklevel=3)
        return None
    out = np.split(points, np.cumsum(counts)[:-1])
    return [np.ascontiguousarray(c) for c in out]


def _write_cache(
    path: Path, names: Sequence[str], labels: Sequence[str], curves: Sequence[np.ndarray]
) -> None:
    try:
        with atomic_open(path, "wb") as f:
            np.savez(
                f,
                names=np.array(names, dtype=str),
                labels=np.array(labels, dtype=str),
                counts=np.array([len(c) for c in curves], dtype=np.int64),
                points=np.concatenate(curves, axis=0),
            )
    except OSError as e:
        warnings.warn(f"could not write curve cache {path}: {e}", stacklevel=3)


def load(
    name: str,
    *,
    n_points: int | None = 100,
    orientation: str | None = "ccw",
    progress: bool = True,
    classes: Iterable[str] | None = None,
    per_class: int | None = None,
    root: str | os.PathLike[str] | None = None,
    cache: bool = True,
) -> ShapeDataset:
    """Load a silhouette dataset as closed curves.

    Each image is read with Pillow (``convert('L')``), its outer boundary is
    extracted with :func:`shapetree.curves.curve_from_image` (``polarity="auto"``,
    so inverted images such as MPEG-7's ``rat-09`` are handled), oriented, and
    resampled to ``n_points`` points uniformly in arc length.

    Parameters
    ----------
    name : str
        ``mpeg7``, ``kimia99`` or ``swedish_leaf``.
    n_points : int or None, default 100
        Points per curve; ``None`` keeps the extracted boundary as is.
    orientation : {"ccw", "cw"} or None, default "ccw"
        Orientation of the curves (``None``: as extracted).
    progress : bool, default True
        Show a tqdm progress bar while extracting.
    classes : iterable of str, optional
        Load only images whose label is in this set (each must exist).
    per_class : int, optional
        Load only the first ``per_class`` images of each class (in ``labels.csv`` order).
    root : path-like, optional
        The dataset's own folder; default ``data_dir() / name``.
    cache : bool, default True
        Read/write extracted curves from/to the cache (see Notes).

    Returns
    -------
    ShapeDataset

    Raises
    ------
    DatasetError
        If the dataset is missing, a requested class is unknown, or any image is
        missing, unreadable or has no usable silhouette (the message names the file).

    Notes
    -----
    Curves are cached in ``$SHAPETREE_CACHE/curves`` (default
    ``~/.cache/shapetree/curves``) as ``<name>-n<n_points>-<orientation>-<key>.npz``
    holding ``names``, ``labels``, ``counts`` (points per curve) and ``points``
    (all curves concatenated). ``key`` hashes the selected files' names, labels,
    sizes and modification times, the images folder, ``n_points`` and the
    orientation, so a changed file invalidates the cache. Files are written
    atomically (:func:`shapetree._atomic.atomic_open`).
    """
    if n_points is not None:
        if isinstance(n_points, bool) or not isinstance(n_points, int | np.integer):
            raise DatasetError(f"n_points must be an int or None, got {n_points!r}")
        if n_points < 3:
            raise DatasetError(f"n_points must be at least 3, got {n_points}")
        n_points = int(n_points)
    if orientation not in ("ccw", "cw", None):
        raise DatasetError(f"orientation must be 'ccw', 'cw' or None, got {orientation!r}")
    if per_class is not None and (isinstance(per_class, bool) or int(per_class) < 1):
        raise DatasetError(f"per_class must be a positive int, got {per_class!r}")

    names, labels, images = load_labels(name, root=root)
    keep = np.ones(len(names), dtype=bool)
    if classes is not None:
        wanted = [classes] if isinstance(classes, str) else list(classes)
        unknown = sorted(set(wanted) - set(labels.tolist()))
        if unknown:
            raise DatasetError(
                f"dataset {name!r} has no class(es) {unknown}; "
                f"its classes are: {', '.join(sorted(set(labels.tolist())))}"
            )
        keep &= np.isin(labels, wanted)
    if per_class is not None:
        seen: dict[str, int] = {}
        for i, lab in enumerate(labels.tolist()):
            if keep[i]:
                seen[lab] = seen.get(lab, 0) + 1
                keep[i] = seen[lab] <= int(per_class)
    sel_names = [n for n, k in zip(names, keep, strict=True) if k]
    sel_labels = labels[keep]

    cpath: Path | None = None
    curves: list[np.ndarray] | None = None
    if cache:
        key = _cache_key(name, images, sel_names, sel_labels.tolist(), n_points, orientation)
        cpath = _cache_file(name, n_points, orientation, key)
        curves = _read_cache(cpath, sel_names)
    if curves is None:
        it: Iterable[str] = sel_names
        if progress:
            from tqdm.auto import tqdm

            it = tqdm(sel_names, desc=f"extracting {name} curves", unit="img")
        curves = [_extract_curve(images / n, n_points, orientation) for n in it]
        if cpath is not None:
            _write_cache(cpath, sel_names, sel_labels.tolist(), curves)
    return ShapeDataset(
        name=name, names=sel_names, labels=sel_labels, curves=curves, images_dir=images
    )


def _count_images(spec: DatasetSpec, folder: Path) -> int:
    if not folder.is_dir():
        return 0
    if spec.name == "ethz_shape":
        base = folder / spec.images_subdir
        if not base.is_dir():
            base = folder
        return sum(len(list((base / c).glob("*.jpg"))) for c in REGISTRY[spec.name].classes)
    try:
        images = _images_dir(spec, folder)
    except DatasetError:
        return 0
    return len(list(images.glob("*.png")))


def available() -> list[DatasetInfo]:
    """Report which datasets are present under :func:`data_dir`.

    Returns
    -------
    list of DatasetInfo
        One entry per registered dataset, in registry order. ``count`` is the
        number of image files found (``*.png``; ``*.jpg`` in the ETHZ class folders).
    """
    root = data_dir()
    out = []
    for spec in REGISTRY.values():
        folder = root / spec.name
        n = _count_images(spec, folder)
        out.append(
            DatasetInfo(
                name=spec.name,
                path=folder,
                present=folder.is_dir() and n > 0,
                count=n,
                expected=spec.n_images,
                description=spec.description,
            )
        )
    return out


def format_available() -> str:
    """Return :func:`available` as a plain-text table.

    Returns
    -------
    str
        Columns ``name``, ``present``, ``count/expected`` and ``path``, one
        line per dataset, plus a header and a line naming the data root.
    """
    infos = available()
    rows = [("name", "present", "count/expected", "path")]
    for i in infos:
        present = "yes" if i.complete else ("partial" if i.present else "no")
        rows.append((i.name, present, f"{i.count}/{i.expected}", str(i.path)))
    widths = [max(len(r[k]) for r in rows) for k in range(3)]
    lines = ["  ".join(r[k].ljust(widths[k]) for k in range(3)) + "  " + r[3] for r in rows]
    lines.insert(1, "  ".join("-" * w for w in widths) + "  " + "-" * 4)
    lines.append(f"data dir: {data_dir()} (set SHAPETREE_DATA to change)")
    return "\n".join(lines)
