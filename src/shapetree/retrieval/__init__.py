"""All-pairs shape-tree distances (cached, resumable), the retrieval protocols of §5.1, and
optional re-ranking of a whole distance matrix (reported apart from the pairwise scores)."""

from shapetree.retrieval._engine import (
    SYMMETRIZE,
    DistanceParams,
    combine,
    directed_costs,
    distance_matrix,
    mirror_curve,
)
from shapetree.retrieval._evaluate import (
    DATASET_DEFAULTS,
    EVAL_PARAMS,
    PAPER_TABLES,
    evaluate,
    format_table,
    machine_info,
    protocol_score,
)
from shapetree.retrieval._figures import plot_bullseye_per_class, plot_retrieval_grid
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
    "DATASET_DEFAULTS",
    "EVAL_PARAMS",
    "PAPER_TABLES",
    "RERANK_DEFAULTS",
    "SYMMETRIZE",
    "DistanceParams",
    "bullseye",
    "bullseye_per_class",
    "bullseye_per_query",
    "combine",
    "directed_costs",
    "distance_matrix",
    "evaluate",
    "format_table",
    "machine_info",
    "kimia_ranks",
    "knn_affinity",
    "mirror_curve",
    "nn_accuracy_splits",
    "plot_bullseye_per_class",
    "plot_retrieval_grid",
    "protocol_score",
    "ranked_neighbours",
    "tpg_rerank",
]
