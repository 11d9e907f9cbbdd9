"""Exception types raised by shapetree.

Every error a user can provoke with bad input is a subclass of
:class:`ShapeTreeError` (itself a :class:`ValueError`), carries a message that
names the problem, and is turned into a one-line message by the CLI.
"""

from __future__ import annotations


class ShapeTreeError(ValueError):
    """Base class of all errors shapetree raises on bad input."""


class CurveError(ShapeTreeError):
    """A curve is unusable: wrong array shape, NaN/inf, too few distinct points, zero length."""


class ImageError(ShapeTreeError):
    """An image is unreadable, empty, blank, or has no foreground."""


class DatasetError(ShapeTreeError):
    """A dataset is missing, incomplete, or a file in it is bad."""
