"""Many closed models against one target in a single kernel call (the retrieval hot path).

:func:`match_cost` pays a few tens of microseconds of Python per call, as much as a banded
matching itself at ``n = 40``. :class:`ModelStack` lays the shape-trees of many models of
the same size out as stacked arrays once, and :meth:`ModelStack.costs` then computes ψ of
all of them against a target with one call of :func:`._kernels.closed_costs`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from shapetree._errors import ShapeTreeError
from shapetree.matching._kernels import closed_costs, finite_or_inf
from shapetree.matching._match import MatchParams, _bands, _buffers, _check_pair
from shapetree.matching._prepare import Model, Target

__all__ = ["ModelStack"]


class ModelStack:
    """Closed models with equal numbers of points and shape-trees, stacked for the kernel.

    Parameters
    ----------
    models : sequence of Model
        From :func:`prepare_model`; all closed, all with the same number of points and of
        shape-trees, and the same ``length_power``.
    m : int
        Number of points of the targets they will be matched against (the bands of the
        pruned mode depend on it).
    params : MatchParams, optional
    dtype : {numpy.float64, numpy.float32}
        Precision of the tables; targets must be prepared with the same ``dtype``.

    Notes
    -----
    ``costs(target)[i]`` equals ``match_cost(models[i], target, params)`` (to rounding):
    the same kernel fills the same tables, only the Python loop around it is gone.
    """

    def __init__(
        self,
        models: Sequence[Model],
        m: int,
        params: MatchParams | None = None,
        dtype: type = np.float64,
    ) -> None:
        self.params = params or MatchParams()
        models = list(models)
        if not models:
            raise ShapeTreeError("ModelStack needs at least one model")
        first = models[0]
        n, n_trees = first.points.shape[0], len(first.trees)
        for mod in models:
            if not mod.closed:
                raise ShapeTreeError("ModelStack takes closed models only")
            if mod.points.shape[0] != n or len(mod.trees) != n_trees:
                raise ShapeTreeError(
                    "ModelStack needs models with equal numbers of points and shape-trees "
                    f"(got {mod.points.shape[0]} points / {len(mod.trees)} trees, "
                    f"expected {n} / {n_trees})"
                )
            if mod.length_power != first.length_power:
                raise ShapeTreeError("ModelStack needs models with the same length_power")
            if mod.dif != self.params.dif:
                raise ShapeTreeError(
                    f"ModelStack got a model prepared for dif={mod.dif!r} with parameters "
                    f"for dif={self.params.dif!r}"
                )
        self.models = models
        self.m = int(m)
        self.n_models, self.n_trees = len(models), n_trees
        tds = [td for mod in models for td in mod.trees]
        bands = [_bands(td, self.m, self.params.band) for td in tds]
        self.dtype = np.dtype(dtype)
        per_tree = [td.kernel_arrays(self.dtype) for td in tds]

        def stack(name: str) -> np.ndarray:
            return np.ascontiguousarray(np.stack([getattr(td, name) for td in tds]))

        self._arrays = (
            stack("left_tab"),
            stack("right_tab"),
            *(np.ascontiguousarray(np.stack(col)) for col in zip(*per_tree)),
            np.ascontiguousarray(np.stack([b[0] for b in bands])),
            np.ascontiguousarray(np.stack([b[1] for b in bands])),
            np.array([td.table_of_root(td.tree.roots[0], 0) for td in tds], dtype=np.int64),
            np.array([td.table_of_root(td.tree.roots[1], 1) for td in tds], dtype=np.int64),
        )
        self._n_tables = tds[0].n_tables

    def _table_workspace(self, target: Target) -> np.ndarray:
        """Check that ``target`` fits this stack (dif, size, precision) and return this
        thread's table workspace for it."""
        _check_pair(self.models[0], target, self.params)
        name = type(self).__name__
        if target.n_points != self.m:
            raise ShapeTreeError(
                f"this {name} was built for targets of {self.m} points, got {target.n_points}"
            )
        if target.tri.dtype != self.dtype:
            raise ShapeTreeError(
                f"this {name} runs in {self.dtype}; prepare the target with that dtype "
                f"(got {target.tri.dtype})"
            )
        return _buffers(self._n_tables, self.m, self.dtype)

    def costs(self, target: Target) -> np.ndarray:
        """ψ(model_i, target) for every model (its shape-trees combined by
        ``params.combine_trees``: the minimum, or the mean).

        Parameters
        ----------
        target : Target
            Closed, with ``m`` points (see the constructor).

        Returns
        -------
        ndarray, shape (n_models,)
        """
        tab = self._table_workspace(target)
        out = np.empty(self.n_models * self.n_trees, dtype=self.dtype)
        closed_costs(
            *self._arrays,
            target.tri,
            target.deg,
            target.base_table(self.params.dif),
            target.blen,
            self.params.kernel_occlusion,
            self.params.segment_weight,
            tab,
            out,
            self.params.hyper,
        )
        best = self.params.combine_trees(finite_or_inf(out.reshape(self.n_models, self.n_trees)))
        return np.maximum(best, 0.0)  # inf: no admissible matching
