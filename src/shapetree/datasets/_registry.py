"""Registry of the datasets shapetree knows, and where they live on disk.

Nothing in this module touches the network. Dataset files are never part of the
package: they live under :func:`data_dir` (``$SHAPETREE_DATA`` or
``~/.cache/shapetree/datasets``), one folder per dataset, and
:func:`shapetree.datasets.fetch` puts them there.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

from shapetree._cache import cache_root
from shapetree._errors import DatasetError

__all__ = [
    "DEFAULT_DATA_DIR",
    "ETHZ_CLASSES",
    "REGISTRY",
    "DatasetSpec",
    "Source",
    "cache_dir",
    "data_dir",
    "get_spec",
]

#: Default dataset root when ``$SHAPETREE_DATA`` is not set.
DEFAULT_DATA_DIR = Path("~/.cache/shapetree/datasets")


def data_dir() -> Path:
    """Return the root folder that holds the datasets.

    Returns
    -------
    pathlib.Path
        ``$SHAPETREE_DATA`` if that environment variable is set and non-empty,
        else ``~/.cache/shapetree/datasets`` (the default destination of
        :func:`shapetree.datasets.fetch`). Each dataset is a sub-folder named
        after it, e.g. ``<data_dir>/mpeg7``. The folder need not exist.
    """
    env = os.environ.get("SHAPETREE_DATA", "").strip()
    return Path(env).expanduser() if env else DEFAULT_DATA_DIR.expanduser()


def cache_dir() -> Path:
    """Return the folder that holds cached extracted curves.

    Returns
    -------
    pathlib.Path
        ``cache_root() / "curves"`` (:func:`shapetree._cache.cache_root`): that is
        ``$SHAPETREE_CACHE/curves`` if ``$SHAPETREE_CACHE`` is set and non-empty, else
        ``~/.cache/shapetree/curves``. The folder need not exist.
    """
    return cache_root() / "curves"


@dataclass(frozen=True)
class Source:
    """Where a dataset can be downloaded from.

    Attributes
    ----------
    url : str
        Public address of the archive.
    archive : str
        Archive format: ``"zip"``, ``"tar.gz"`` or ``"rar"`` (rar cannot be
        extracted with the standard library; :func:`fetch` explains the manual step).
    sha256 : str or None
        Known SHA-256 of the archive, or ``None`` when none is published.
    sha1 : str or None
        Known SHA-1 of the archive (used only when no SHA-256 is known).
    citation : str
        Reference to cite when using the data.
    notes : str
        How the archive maps onto the layout :func:`load` expects.
    """

    url: str
    archive: str
    sha256: str | None
    sha1: str | None
    citation: str
    notes: str = ""


@dataclass(frozen=True)
class DatasetSpec:
    """Static description of one dataset.

    Attributes
    ----------
    name : str
        Registry key and folder name under :func:`data_dir`.
    description : str
        One-line description.
    n_images : int
        Expected number of images.
    n_classes : int
        Expected number of classes.
    classes : tuple of str
        Class names as they appear in the labels (empty if too many to list here).
    source : Source
        Public source of the archive and the citation.
    files : str
        Human-readable description of the expected files.
    label_column : str
        Column of ``labels.csv`` used as the class label (``None`` for ETHZ).
    images_subdir : str
        Folder (relative to the dataset folder) holding the images listed in
        ``labels.csv``; ``""`` for the dataset folder itself.
    loadable : bool
        Whether :func:`shapetree.datasets.load` handles it (ETHZ has its own loader).
    """

    name: str
    description: str
    n_images: int
    n_classes: int
    classes: tuple[str, ...]
    source: Source
    files: str
    label_column: str | None
    images_subdir: str
    loadable: bool = True
    extra: dict[str, str] = field(default_factory=dict)


#: Kimia-99 class ids (1..9) of the source's ``classes.txt`` and their names.
KIMIA99_CLASS_NAMES: dict[int, str] = {
    1: "fish",
    2: "rabbit",
    3: "airplane",
    4: "fgen_mgen",
    5: "tool",
    6: "hand",
    7: "human",
    8: "quadruped",
    9: "ray",
}

#: Swedish leaf species numbers (Söderkvist's numbering) and names, as the dataset gives them.
SWEDISH_SPECIES: dict[int, str] = {
    1: "Ulmus carpinifolia",
    2: "Acer",
    3: "Salix aurita",
    4: "Quercus",
    5: "Alnus incana",
    6: "Betula pubescens",
    7: "Salix alba 'Sericea'",
    8: "Populus tremula",
    9: "Ulmus glabra",
    10: "Sorbus aucuparia",
    11: "Salix sinerea",
    12: "Populus",
    13: "Tilia",
    14: "Sorbus intermedia",
    15: "Fagus silvatica",
}

#: ETHZ Shape Classes folders, their tag in file names, and their model file stem.
ETHZ_CLASSES: dict[str, tuple[str, str]] = {
    "Applelogos": ("applelogos", "applelogo"),
    "Bottles": ("bottles", "bottle"),
    "Giraffes": ("giraffes", "giraffe"),
    "Mugs": ("mugs", "mug"),
    "Swans": ("swans", "swan"),
}

REGISTRY: dict[str, DatasetSpec] = {
    "mpeg7": DatasetSpec(
        name="mpeg7",
        description="MPEG-7 CE-Shape-1 Part B: 1400 silhouettes, 70 classes x 20",
        n_images=1400,
        n_classes=70,
        classes=(),
        source=Source(
            url=(
                "https://github.com/wvenialbo/mpeg7ce1dataset/raw/"
                "9ad968a6a0b0abf87469f3e51982e65776577c83/datasets/mpeg7shapeB-PNG.rar"
            ),
            archive="rar",
            sha256="200ce9793452eddf8d1fa278522dce9928691bd3ea4cdbd3eb38540b81ffaf80",
            sha1=None,
            citation=(
                "Latecki, Lakaemper & Eckhardt, 'Shape descriptors for non-rigid shapes with a "
                "single closed contour', CVPR 2000 (MPEG-7 CE-Shape-1)"
            ),
            notes=(
                "images are Part-B/1-Similarity/*.png inside the archive; the class is the part "
                "of the file name before the last '-'"
            ),
        ),
        files="<class>-<n>.png (1400) and labels.csv (filename,class)",
        label_column="class",
        images_subdir="",
    ),
    "kimia99": DatasetSpec(
        name="kimia99",
        description="Kimia-99 silhouettes: 99 images, 9 classes x 11",
        n_images=99,
        n_classes=9,
        classes=tuple(KIMIA99_CLASS_NAMES.values()),
        source=Source(
            url=(
                "https://github.com/mmssouza/kimia99/archive/"
                "dea3607c88b4a6f29a197d465c245e4906689af6.zip"
            ),
            archive="zip",
            sha256=None,
            sha1=None,
            citation=(
                "Sebastian, Klein & Kimia, 'Recognition of shapes by editing their shock "
                "graphs', PAMI 2004"
            ),
            notes="labels.csv is derived from the source's classes.txt (class ids 1..9)",
        ),
        files="*.png (99) and labels.csv (filename,class)",
        label_column="class",
        images_subdir="",
    ),
    "swedish_leaf": DatasetSpec(
        name="swedish_leaf",
        description="Swedish leaf silhouettes: 1125 images, 15 species x 75",
        n_images=1125,
        n_classes=15,
        classes=tuple(SWEDISH_SPECIES.values()),
        source=Source(
            url=(
                "https://github.com/mmssouza/swedish_png/archive/"
                "e8d36a87a7e1b2173ebc3bb1ecc2fb22ff65b191.zip"
            ),
            archive="zip",
            sha256=None,
            sha1=None,
            citation=(
                "O. Soederkvist, 'Computer vision classification of leaves from Swedish "
                "trees', MSc thesis, Linkoeping University, 2001"
            ),
            notes=(
                "the source holds full-resolution l<s>nr<NNN>.png silhouettes; fetch puts them "
                "in source_png_fullres/ and writes labels.csv. The 512-px png512/ copy is "
                "used when present"
            ),
        ),
        files=(
            "png512/l<s>nr<NNN>.png (1125; or source_png_fullres/) and labels.csv "
            "(filename,species,image,species_name,...)"
        ),
        label_column="species_name",
        images_subdir="png512",
        extra={"fallback_subdir": "source_png_fullres"},
    ),
    "ethz_shape": DatasetSpec(
        name="ethz_shape",
        description="ETHZ Shape Classes V1.2: 255 cluttered images, 5 classes, 289 objects",
        n_images=255,
        n_classes=5,
        classes=tuple(ETHZ_CLASSES),
        source=Source(
            url="http://www.vision.ee.ethz.ch/datasets/downloads/ethz_shape_classes_v12.tgz",
            archive="tar.gz",
            sha256=None,
            sha1="ae9b8fad2d170e098e5126ea9181d0843505a84b",
            citation=(
                "Ferrari, Tuytelaars & Van Gool, 'Object detection by contour segment "
                "networks', ECCV 2006"
            ),
            notes="the archive holds ETHZShapeClasses-V1.2/",
        ),
        files=(
            "ETHZShapeClasses-V1.2/<Class>/<image>.jpg, <image>_edges.tif, "
            "<image>_<class>.groundtruth, models/*.tif"
        ),
        label_column=None,
        images_subdir="ETHZShapeClasses-V1.2",
        loadable=False,
    ),
}


def get_spec(name: str) -> DatasetSpec:
    """Return the registry entry of a dataset.

    Parameters
    ----------
    name : str
        One of ``REGISTRY``'s keys (``mpeg7``, ``kimia99``, ``swedish_leaf``, ``ethz_shape``).

    Returns
    -------
    DatasetSpec

    Raises
    ------
    DatasetError
        If the name is unknown.
    """
    try:
        return REGISTRY[name]
    except (KeyError, TypeError):
        known = ", ".join(REGISTRY)
        raise DatasetError(f"unknown dataset {name!r}; known datasets: {known}") from None
