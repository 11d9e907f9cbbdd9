"""All-pairs shape-tree distances (cached, resumable), the retrieval protocols of §5.1, and
optional re-ranking of a whole distance matrix (reported apart from the pairwise scores)."""

from shapetree.retrieval._engine import combine, directed_costs, distance_matrix
from shapetree.retrieval._evaluate import EVAL_PARAMS, evaluate
from shapetree.retrieval._protocols import (
    bullseye,
    bullseye_per_class,
    bullseye_per_query,
    kimia_ranks,
    nn_accuracy_splits,
    ranked_neighbours,
)
from shapetree.retrieval._rerank import RERANK_DEFAULTS, knn_affinity, tpg_rerank

__all__ = [
    "EVAL_PARAMS",
    "RERANK_DEFAULTS",
    "bullseye",
    "bullseye_per_class",
    "bullseye_per_query",
    "combine",
    "directed_costs",
    "distance_matrix",
    "evaluate",
    "kimia_ranks",
    "knn_affinity",
    "nn_accuracy_splits",
    "ranked_neighbours",
    "tpg_rerank",
]
