"""Benchmark datasets: MPEG-7, Kimia-99, Swedish leaf (silhouettes) and ETHZ Shape Classes.

Datasets are never shipped with the package. They live under :func:`data_dir`
(``$SHAPETREE_DATA``, default ``~/.cache/shapetree/datasets``), one folder per
dataset; :func:`fetch` downloads, verifies and installs them there, and
:func:`available` / :func:`format_available` report what is present.

:func:`load` turns a silhouette set into closed curves (cached on disk under
``$SHAPETREE_CACHE/curves``, default ``~/.cache/shapetree/curves``);
:func:`load_ethz` lists the ETHZ images with their edge maps and boxes.
"""

from shapetree.datasets._ethz import EthzImage, ethz_model_path, ethz_root, load_ethz
from shapetree.datasets._fetch import fetch
from shapetree.datasets._load import (
    DatasetInfo,
    ShapeDataset,
    available,
    dataset_path,
    format_available,
    load,
    load_labels,
)
from shapetree.datasets._registry import (
    REGISTRY,
    DatasetSpec,
    Source,
    cache_dir,
    data_dir,
    get_spec,
)

__all__ = [
    "REGISTRY",
    "DatasetInfo",
    "DatasetSpec",
    "EthzImage",
    "ShapeDataset",
    "Source",
    "available",
    "cache_dir",
    "data_dir",
    "dataset_path",
    "ethz_model_path",
    "ethz_root",
    "fetch",
    "format_available",
    "get_spec",
    "load",
    "load_ethz",
    "load_labels",
]
