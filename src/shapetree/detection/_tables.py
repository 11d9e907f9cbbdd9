"""Contour-vs-model tables (paper §4, stage 3), computed by the core kernel of §3.

For each image contour and each direction, ``T[s, L]`` is the cost of
deforming the open contour (its shape-tree) into the model's cyclic subcurve
from sample ``s`` forward ``L`` segments (``shapetree.matching.subcurve_table``).
The contour's root weight is 1 (``length_scale`` = the contour's own length),
so ``T`` is a pure shape cost, independent of the contour's size.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from shapetree._errors import ShapeTreeError
from shapetree.matching import prepare_target, subcurve_table

__all__ = ["contour_tables"]


def contour_tables(
    contours: Sequence[NDArray[np.float64]],
    model_points: NDArray[np.float64],
    *,
    weight: float = 1.0,
) -> NDArray[np.float64]:
    """Tables of every contour, in both directions, against every model subcurve.

    Parameters
    ----------
    contours : sequence of ndarray, each shape (n_i, 2)
        Open image contours (``x, y`` px), ``n_i >= 2``.
    model_points : ndarray, shape (m, 2)
        Closed model samples.
    weight : float
        Multiplier of every deformation term (default 1).

    Returns
    -------
    ndarray, shape (2 * len(contours), m, m), float64
        Row ``2 i`` is contour ``i`` as given, row ``2 i + 1`` reversed;
        entry ``[s, L]`` as described in the module docstring (column 0 is
        ``inf``).  A contour the kernel rejects (e.g. one passing twice
        through the same point) gets ``inf`` everywhere.  Cost:
        ``O(sum_i n_i * m^3)``.
    """
    target = prepare_target(np.asarray(model_points, dtype=np.float64), closed=True)
    m = len(model_points)
    out = np.empty((2 * len(contours), m, m))
    for i, c in enumerate(contours):
        c = np.asarray(c, dtype=np.float64)
        try:
            out[2 * i] = subcurve_table(c, target, weight=weight)
            out[2 * i + 1] = subcurve_table(np.ascontiguousarray(c[::-1]), target, weight=weight)
        except ShapeTreeError:
            # e.g. a contour through the same point twice: no shape-tree; never matched
            out[2 * i : 2 * i + 2] = np.inf
    out[:, :, 0] = np.inf
    return out
