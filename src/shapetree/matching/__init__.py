"""Elastic matching by dynamic programming over the shape-tree (paper §3, eq. 1).

The compiled kernel lives in :mod:`shapetree.matching._kernels`; the slow, literal
reference used as the test oracle lives in :mod:`shapetree.matching._reference`.
"""

from shapetree.matching._match import (
    MatchParams,
    MatchResult,
    match,
    match_cost,
    match_prepared,
    subcurve_table,
)
from shapetree.matching._prepare import Model, Target, prepare_model, prepare_target
from shapetree.matching._reference import (
    reference_correspondence,
    reference_match_cost,
    reference_subcurve_table,
)

__all__ = [
    "MatchParams",
    "MatchResult",
    "Model",
    "Target",
    "match",
    "match_cost",
    "match_prepared",
    "prepare_model",
    "prepare_target",
    "reference_correspondence",
    "reference_match_cost",
    "reference_subcurve_table",
    "subcurve_table",
]
