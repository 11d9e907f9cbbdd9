"""The shape-tree: hierarchical Bookstein description of a curve (paper §2, §2.1)."""

from shapetree.tree._shapetree import (
    SPLITS,  # noqa: F401  (not public: matching._prepare still imports it from here)
    ShapeTree,
    build_shape_tree,
    deform,
    reconstruct,
)

__all__ = ["ShapeTree", "build_shape_tree", "deform", "reconstruct"]
