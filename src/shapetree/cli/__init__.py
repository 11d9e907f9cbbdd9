"""shapetree.cli (work in progress)."""
