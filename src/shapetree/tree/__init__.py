"""shapetree.tree (work in progress)."""
