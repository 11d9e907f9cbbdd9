"""Benchmark datasets: MPEG-7, Kimia-99, Swedish leaf (silhouettes) and ETHZ Shape Classes.

Datasets are never shipped with the package. They live under :func:`data_dir`
(``$SHAPETREE_DATA``, default ``~/.cache/shapetree/datasets``), one folder per
dataset; :func:`fetch` downloads, verifies and installs them there, and
:func:`available` / :func:`format_available` report what is present.

:func:`load` turns a silhouette set into closed curves (cached on disk under
``$SHAPETREE_CACHE/curves``, default ``~/.cache/shapetree/curves``);
:func:`load_labels` reads only the file names and classes; :func:`load_ethz` lists the
ETHZ images with their edge maps and boxes, :func:`ethz_model_path` a class's model drawing.
"""

from shapetree.datasets._ethz import EthzImage, ethz_model_path, load_ethz
from shapetree.datasets._fetch import fetch
from shapetree.datasets._load import (
    DatasetInfo,
    ShapeDataset,
    available,
    format_available,
    load,
    load_labels,
)
from shapetree.datasets._registry import data_dir

__all__ = [
    "DatasetInfo",
    "EthzImage",
    "ShapeDataset",
    "available",
    "data_dir",
    "ethz_model_path",
    "fetch",
    "format_available",
    "load",
    "load_ethz",
    "load_labels",
]
