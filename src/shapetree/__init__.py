"""shapetree: hierarchical elastic matching of deformable 2-D shapes.

An implementation of Felzenszwalb & Schwartz, *Hierarchical Matching of
Deformable Shapes* (CVPR 2007).
"""

from shapetree._errors import CurveError, DatasetError, ImageError, ShapeTreeError

__version__ = "0.1.0"

__all__ = ["CurveError", "DatasetError", "ImageError", "ShapeTreeError", "__version__"]
