"""Geometry of point triples: Bookstein coordinates and the Procrustes ``dif`` (paper §2.1, §3)."""

from shapetree.geometry._bookstein import (
    bookstein,
    from_bookstein,
    helmert,
    outline_dif,
    procrustes_dif,
    triangle_dif,
)

__all__ = [
    "bookstein",
    "from_bookstein",
    "helmert",
    "outline_dif",
    "procrustes_dif",
    "triangle_dif",
]
