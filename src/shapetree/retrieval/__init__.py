"""All-pairs shape-tree distances (cached, resumable) and the retrieval protocols of §5.1."""

from shapetree.retrieval._engine import (
    DistanceParams,
    combine,
    directed_costs,
    distance_matrix,
    mirror_curve,
)
from shapetree.retrieval._protocols import (
    bullseye,
    bullseye_per_class,
    bullseye_per_query,
    kimia_ranks,
    nn_accuracy_splits,
    ranked_neighbours,
)

__all__ = [
    "DistanceParams",
    "bullseye",
    "bullseye_per_class",
    "bullseye_per_query",
    "combine",
    "directed_costs",
    "distance_matrix",
    "kimia_ranks",
    "mirror_curve",
    "nn_accuracy_splits",
    "ranked_neighbours",
]
