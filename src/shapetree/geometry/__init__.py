"""shapetree.geometry (work in progress)."""
