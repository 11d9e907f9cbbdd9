"""shapetree.datasets (work in progress)."""
