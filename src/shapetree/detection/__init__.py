"""shapetree.detection (work in progress)."""
