"""Where shapetree keeps its caches, and the fingerprint that keys them.

Caches (the retrieval engine's distance blocks, the ETHZ detection results) live under
:func:`cache_root`. Every cache key includes :func:`code_fingerprint`, a hash of the
package version *and* of the source of every module whose code changes a computed cost or
a detection. So a cache can never silently hand back results computed by other code: an
upgrade, a local edit or a bug fix in the matcher changes the fingerprint, and the old
entries are simply not found (they are recomputed, never reused). No hand-bumped
``"v": N`` counter is needed, and none can be forgotten.
"""

from __future__ import annotations

import functools
import hashlib
import os
from pathlib import Path

import shapetree

__all__ = [
    "FINGERPRINT_PACKAGES",
    "FINGERPRINT_SCOPES",
    "RETRIEVAL_CACHE_MODULES",
    "cache_root",
    "code_fingerprint",
]

#: Sub-packages whose source bytes enter :func:`code_fingerprint`: everything that can
#: change a matching cost or a detection (matching, shape-trees, geometry, curve
#: preparation, detection).
FINGERPRINT_PACKAGES: tuple[str, ...] = ("curves", "detection", "geometry", "matching", "tree")

#: The retrieval modules whose code decides what a cached distance block, a cached
#: neighbour list or a stored shape database holds: the engine (curve preparation, the
#: block computation), the pruned search (bounds, pruning, kept candidates) and the shape
#: database.  The rest of ``retrieval`` (protocols, scoring, re-ranking, the Dask
#: submission loop) reads those results and does not change them.
RETRIEVAL_CACHE_MODULES: tuple[str, ...] = (
    "retrieval/_engine.py",
    "retrieval/_index.py",
    "retrieval/_knn.py",
)

#: The sources of each :func:`code_fingerprint` scope (a sub-package, or one module as
#: ``"package/module.py"``): ``"all"`` (detection caches: matching and detection code)
#: and ``"matching"`` (what a matching cost and the retrieval caches built on it depend
#: on: distance blocks, neighbour lists, shape databases), so a change of the detection
#: code does not invalidate a distance cache or a database, a change of the engine does,
#: and a change of the retrieval engine does not invalidate a detection cache.
FINGERPRINT_SCOPES: dict[str, tuple[str, ...]] = {
    "all": FINGERPRINT_PACKAGES,
    "matching": ("curves", "geometry", "matching", "tree") + RETRIEVAL_CACHE_MODULES,
}


def cache_root() -> Path:
    """The cache folder: ``$SHAPETREE_CACHE`` if set and non-empty, else ``~/.cache/shapetree``.

    ``~`` is expanded in both. The folder is not created here.
    """
    env = os.environ.get("SHAPETREE_CACHE", "").strip()
    if env:
        return Path(env).expanduser()
    return Path("~/.cache/shapetree").expanduser()


def _sources(root: Path, entry: str) -> list[Path]:
    """The files of one scope entry: a package's ``*.py`` (sorted) or one module."""
    if entry.endswith(".py"):
        files = [root / entry] if (root / entry).is_file() else []
    else:
        files = sorted((root / entry).glob("*.py"), key=lambda p: p.name)
    if not files:
        raise RuntimeError(f"code_fingerprint: no sources found for {root / entry}")
    return files


def _fingerprint(version: str, root: Path, packages: tuple[str, ...] = FINGERPRINT_PACKAGES) -> str:
    """SHA-256 over ``version`` and the sources of ``packages``.

    ``packages`` holds sub-packages (all their ``*.py``) and single modules
    (``"package/module.py"``), taken in the given order, a package's files sorted by
    name; each file contributes its path relative to ``root``, its length and its bytes,
    so renames, moves and edits all count.
    """
    h = hashlib.sha256()
    h.update(b"shapetree-code-fingerprint\0")
    h.update(version.encode("utf-8") + b"\0")
    for pkg in packages:
        for f in _sources(root, pkg):
            data = f.read_bytes()
            rel = f.relative_to(root).as_posix().encode()
            h.update(rel + b"\0" + str(len(data)).encode("ascii") + b"\0")
            h.update(data)
    return h.hexdigest()


@functools.cache
def _cached_fingerprint(version: str, scope: str) -> str:
    return _fingerprint(version, Path(__file__).resolve().parent, FINGERPRINT_SCOPES[scope])


def code_fingerprint(scope: str = "all") -> str:
    """Hex SHA-256 of ``shapetree.__version__`` and the cost- and detection-relevant source.

    Parameters
    ----------
    scope : {"all", "matching"}
        ``"all"``: the bytes of every ``*.py`` in ``shapetree.matching``,
        ``shapetree.tree``, ``shapetree.geometry``, ``shapetree.curves`` and
        ``shapetree.detection`` (what a detection depends on); ``"matching"``: the same
        without ``detection`` and with the retrieval modules that fill the retrieval
        caches (:data:`RETRIEVAL_CACHE_MODULES`; what a matching cost and the retrieval
        caches depend on). Sorted, deterministic, computed once per process,
        version and scope.

    Key caches by it so that they can never silently reuse stale results after an upgrade
    or an edit of the code that produced them.
    """
    if scope not in FINGERPRINT_SCOPES:
        raise ValueError(f"scope must be one of {sorted(FINGERPRINT_SCOPES)}, got {scope!r}")
    return _cached_fingerprint(str(shapetree.__version__), scope)
