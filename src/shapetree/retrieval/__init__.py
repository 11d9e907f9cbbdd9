"""All-pairs shape-tree distances (cached, resumable), the retrieval protocols of §5.1, and
optional re-ranking of a whole distance matrix (reported apart from the pairwise scores), and
:class:`ShapeIndex`, a prepared shape database on disk that the engine takes in place of curves.

Pictures of the results are drawn by :func:`shapetree.plotting.plot_retrieval_grid` and
:func:`shapetree.plotting.plot_bullseye_per_class`.
"""

from shapetree.retrieval._engine import combine, directed_costs, distance_matrix, search
from shapetree.retrieval._evaluate import EVAL_PARAMS, evaluate
from shapetree.retrieval._index import ShapeIndex
from shapetree.retrieval._knn import knn
from shapetree.retrieval._protocols import (
    bullseye,
    bullseye_per_class,
    kimia_ranks,
    nn_accuracy_splits,
    ranked_neighbours,
)
from shapetree.retrieval._rerank import tpg_rerank

__all__ = [
    "EVAL_PARAMS",
    "ShapeIndex",
    "bullseye",
    "bullseye_per_class",
    "combine",
    "directed_costs",
    "distance_matrix",
    "evaluate",
    "kimia_ranks",
    "knn",
    "nn_accuracy_splits",
    "ranked_neighbours",
    "search",
    "tpg_rerank",
]
