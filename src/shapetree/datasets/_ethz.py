"""ETHZ Shape Classes V1.2: images, Pb edge maps, ground-truth boxes and models."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from shapetree._errors import DatasetError
from shapetree.datasets._load import dataset_path
from shapetree.datasets._registry import ETHZ_CLASSES, REGISTRY

__all__ = ["EthzImage", "ethz_model_path", "ethz_root", "load_ethz"]

_SUBDIR = REGISTRY["ethz_shape"].images_subdir


@dataclass(frozen=True)
class EthzImage:
    """One ETHZ test image.

    Attributes
    ----------
    image_path : pathlib.Path
        The ``.jpg``.
    edges_path : pathlib.Path
        The Berkeley Pb edge map ``<image>_edges.tif`` (8-bit, same size as the image).
    class_name : str
        Class folder: ``Applelogos``, ``Bottles``, ``Giraffes``, ``Mugs`` or ``Swans``.
    boxes : numpy.ndarray
        ``(N, 4)`` float64 ground-truth boxes ``x1, y1, x2, y2`` (pixels) of every
        instance of the image's class, as the file gives them. A few files of the
        release hold fractional values (e.g. ``Applelogos/grey``); they are kept, so
        these are exactly the boxes :func:`shapetree.detection.evaluate_ethz` scores
        against.
    """

    image_path: Path
    edges_path: Path
    class_name: str
    boxes: np.ndarray

    @property
    def stem(self) -> str:
        """Image name without extension."""
        return self.image_path.stem


def ethz_root(root: str | os.PathLike[str] | None = None) -> Path:
    """Return the ``ETHZShapeClasses-V1.2`` folder.

    Parameters
    ----------
    root : path-like, optional
        Either the ``ETHZShapeClasses-V1.2`` folder itself or the folder that
        contains it; default ``data_dir() / "ethz_shape"``.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    DatasetError
        If the folder is missing.
    """
    folder = dataset_path("ethz_shape", root)
    if (folder / _SUBDIR).is_dir():
        return folder / _SUBDIR
    if all((folder / c).is_dir() for c in ETHZ_CLASSES):
        return folder
    raise DatasetError(
        f"dataset 'ethz_shape' in {folder} is incomplete: no {_SUBDIR}/ folder; "
        "get it with `shapetree datasets fetch ethz_shape`"
    )


def read_boxes(path: Path) -> np.ndarray:
    """The ``(N, 4)`` float64 boxes of one ``.groundtruth`` file (validated)."""
    try:
        text = path.read_text(encoding="ascii")
    except (OSError, UnicodeDecodeError) as e:
        raise DatasetError(f"{path}: cannot read ground truth ({e})") from e
    boxes = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        parts = line.split()
        try:
            vals = [float(t) for t in parts]
        except ValueError:
            raise DatasetError(f"{path}: line {lineno} is not numeric: {line!r}") from None
        if len(vals) != 4:
            raise DatasetError(f"{path}: line {lineno} has {len(vals)} values, expected 4")
        if not all(np.isfinite(vals)):
            raise DatasetError(f"{path}: line {lineno} has non-finite values: {line!r}")
        x1, y1, x2, y2 = vals
        if x2 <= x1 or y2 <= y1:
            raise DatasetError(f"{path}: line {lineno}: empty box {line.strip()!r}")
        boxes.append((x1, y1, x2, y2))
    if not boxes:
        raise DatasetError(f"{path}: ground-truth file has no boxes")
    return np.array(boxes, dtype=np.float64).reshape(-1, 4)


def load_ethz(
    root: str | os.PathLike[str] | None = None, *, classes: list[str] | None = None
) -> list[EthzImage]:
    """List the ETHZ Shape Classes test images with their edge maps and boxes.

    Parameters
    ----------
    root : path-like, optional
        See :func:`ethz_root`.
    classes : list of str, optional
        Class folders to include (default all five).

    Returns
    -------
    list of EthzImage
        Sorted by class folder, then image name (255 images for the full set).

    Raises
    ------
    DatasetError
        If a class folder, an edge map or a ground-truth file is missing, or a
        ground-truth file is malformed (the message names the file).
    """
    base = ethz_root(root)
    wanted = list(ETHZ_CLASSES) if classes is None else [_class_folder(c) for c in classes]
    out: list[EthzImage] = []
    for cls in wanted:
        tag = ETHZ_CLASSES[cls][0]
        folder = base / cls
        if not folder.is_dir():
            raise DatasetError(f"ETHZ class folder missing: {folder}")
        jpgs = sorted(folder.glob("*.jpg"))
        if not jpgs:
            raise DatasetError(f"ETHZ class folder has no images: {folder}")
        for jpg in jpgs:
            edges = folder / f"{jpg.stem}_edges.tif"
            gt = folder / f"{jpg.stem}_{tag}.groundtruth"
            if not edges.is_file():
                raise DatasetError(f"{edges}: edge map missing for {jpg.name}")
            if not gt.is_file():
                raise DatasetError(f"{gt}: ground-truth file missing for {jpg.name}")
            out.append(EthzImage(jpg, edges, cls, read_boxes(gt)))
    return out


def _class_folder(class_name: str) -> str:
    key = str(class_name).strip().lower()
    for folder, (tag, model) in ETHZ_CLASSES.items():
        if key in (folder.lower(), tag, model):
            return folder
    raise DatasetError(
        f"unknown ETHZ class {class_name!r}; known classes: {', '.join(ETHZ_CLASSES)}"
    )


def ethz_model_path(class_name: str, root: str | os.PathLike[str] | None = None) -> Path:
    """Return the hand-drawn model of an ETHZ class.

    Parameters
    ----------
    class_name : str
        Class folder (``Applelogos``), file tag (``applelogos``) or model stem
        (``applelogo``); case-insensitive.
    root : path-like, optional
        See :func:`ethz_root`.

    Returns
    -------
    pathlib.Path
        ``models/<model>.tif``: a 1-bit image with a black 1-px outline on white
        (the giraffe model is an open contour).

    Raises
    ------
    DatasetError
        If the class is unknown or the model file is missing.
    """
    folder = _class_folder(class_name)
    path = ethz_root(root) / "models" / f"{ETHZ_CLASSES[folder][1]}.tif"
    if not path.is_file():
        raise DatasetError(f"{path}: ETHZ model file missing")
    return path
