"""shapetree.retrieval (work in progress)."""
