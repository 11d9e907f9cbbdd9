"""Numba's on-disk cache, made to notice an edit of *any* of shapetree's kernel sources.

The compiled kernels are cached (``njit(cache=True)``), and numba checks a cached entry
against the stamp of the one file that defines the jitted function. A kernel that calls a
jitted function of another module (``matching/_kernels.py`` inlines the triangle ``dif``
of ``geometry/_dif.py``) keeps its stale machine code when only that other module changes
(a documented limitation: numba issue #1833, "Cache invalidation fails to recognize
changes in symbols defined in a different file"). After an upgrade that changed only
``_dif.py``, costs would silently come from the old ``dif``.

:func:`install` puts, in front of numba's cache locators, a copy of each file-backed
locator (``NUMBA_CACHE_DIR``, the in-tree ``__pycache__``, the user-wide cache) that
answers only for functions defined inside this package and whose source stamp is numba's
own stamp together with :func:`kernel_sources_hash`, the SHA-256 of every module in
:data:`KERNEL_MODULES`. An edit of any of them makes every shapetree kernel's cached index
stale, so each is compiled again once (numba then overwrites the entry); functions of
other packages are located by numba's own classes, unchanged. Each module that defines a
cached kernel calls :func:`install` before its first ``njit``: numba chooses a function's
locator when the decorator runs.

It relies on ``numba.core.caching.CacheImpl._locator_classes`` (numba's hook for extra
locators). Should a numba release drop it, :func:`install` returns ``False`` and numba
caches as before.
"""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path
from typing import Any

__all__ = ["KERNEL_MODULES", "install", "kernel_sources_hash"]

#: The package root.
PACKAGE = Path(__file__).resolve().parent
#: Every module with a cached kernel, or a jitted function a cached kernel calls
#: (package-relative). ``tests/test_numba_cache.py`` checks that no module is missing.
KERNEL_MODULES = (
    "geometry/_dif.py",
    "matching/_kernels.py",
    "matching/_bound.py",
    "matching/_subcurves.py",
    "matching/_height.py",
    "detection/_stitch.py",
    "detection/_template.py",
    "detection/_boundary.py",
)


@functools.cache
def kernel_sources_hash() -> str:
    """Hex SHA-256 of the bytes of every module in :data:`KERNEL_MODULES`, in order."""
    h = hashlib.sha256()
    for rel in KERNEL_MODULES:
        h.update(rel.encode() + b"\0")
        h.update((PACKAGE / rel).read_bytes())
    return h.hexdigest()


def _ours(py_file: str) -> bool:
    try:
        return Path(py_file).resolve().is_relative_to(PACKAGE)
    except (OSError, ValueError):
        return False


def _wrapped(base: type) -> type:
    """``base`` answering only for this package, with the kernel sources in its stamp."""

    class Locator(base):  # type: ignore[misc, valid-type]
        _shapetree = True

        @classmethod
        def from_function(cls, py_func: Any, py_file: str) -> Any:
            if not _ours(py_file):
                return None
            return super().from_function(py_func, py_file)

        def get_source_stamp(self) -> Any:
            return (super().get_source_stamp(), kernel_sources_hash())

    Locator.__name__ = Locator.__qualname__ = f"Shapetree{base.__name__}"
    return Locator


def install() -> bool:
    """Register the locators (once per process). Returns whether they are in place."""
    try:
        from numba.core import caching

        classes = caching.CacheImpl._locator_classes
        bases = [
            caching.UserProvidedCacheLocator,
            caching.InTreeCacheLocator,
            caching.UserWideCacheLocator,
        ]
    except (ImportError, AttributeError):
        return False
    if any(getattr(c, "_shapetree", False) for c in classes):
        return True
    classes[:0] = [_wrapped(b) for b in bases if b in classes]
    return True
