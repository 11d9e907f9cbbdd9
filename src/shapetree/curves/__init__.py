"""shapetree.curves (work in progress)."""
