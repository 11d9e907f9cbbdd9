"""shapetree.matching (work in progress)."""
