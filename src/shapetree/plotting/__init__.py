"""shapetree.plotting (work in progress)."""
