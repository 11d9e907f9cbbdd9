"""shapetree.demo (work in progress)."""
