"""The shape-tree: hierarchical Bookstein description of a curve (paper §2, §2.1)."""

from shapetree.tree._shapetree import (
    SPLITS,
    ShapeTree,
    build_shape_tree,
    deform,
    reconstruct,
    with_coords,
)

__all__ = ["SPLITS", "ShapeTree", "build_shape_tree", "deform", "reconstruct", "with_coords"]
