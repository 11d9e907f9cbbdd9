"""Geometry of point triples: Bookstein coordinates and the Procrustes ``dif`` (paper §2.1, §3).

``dif`` is computed in one place, the compiled functions of :mod:`shapetree.geometry._dif`
(also used by the matching kernel and the stitching DP, all compiled with its fast-math
flag set ``_dif.FASTMATH``). A triangle or point set whose points all coincide has zero
size and no shape: its ``dif`` against anything is :data:`DEGENERATE_DIF` ``= 1``, the
maximum of the squared full Procrustes distance. :func:`hyperbolic_dif` is the
pseudo-hyperbolic ``dif`` of the matching option ``dif="hyperbolic"`` (Poincaré half-plane,
:func:`poincare_distance`; footnote 2 of the paper).
"""

from shapetree.geometry._bookstein import (
    bookstein,
    from_bookstein,
    helmert,
    hyperbolic_dif,
    outline_dif,
    poincare_distance,
    procrustes_dif,
    triangle_dif,
)
from shapetree.geometry._dif import DEGENERATE_DIF

__all__ = [
    "DEGENERATE_DIF",
    "bookstein",
    "from_bookstein",
    "helmert",
    "hyperbolic_dif",
    "outline_dif",
    "poincare_distance",
    "procrustes_dif",
    "triangle_dif",
]
