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

__all__ = ["FINGERPRINT_PACKAGES", "FINGERPRINT_SCOPES", "cache_root", "code_fingerprint"]

#: Sub-packages whose source bytes enter :func:`code_fingerprint`: everything that can
#: change a matching cost or a detection (matching, shape-trees, geometry, curve
#: preparation, detection).
FINGERPRINT_PACKAGES: tuple[str, ...] = ("curves", "detection", "geometry", "matching", "tree")

#: The packages of each :func:`code_fingerprint` scope: ``"all"`` (detection caches) and
#: ``"matching"`` (what a matching cost depends on: distance blocks, shape databases), so
#: a change of the detection code does not invalidate a distance cache or a database.
FINGERPRINT_SCOPES: dict[str, tuple[str, ...]] = {
    "all": FINGERPRINT_PACKAGES,
    "matching": ("curves", "geometry", "matching", "tree"),
}


def cache_root() -> Path:
    """The cache folder: ``$SHAPETREE_CACHE`` if set and non-empty, else ``~/.cache/shapetree``.

    ``~`` is expanded in both. The folder is not created here.
    """
    env = os.environ.get("SHAPETREE_CACHE", "").strip()
    if env:
        return Path(env).expanduser()
    return Path("~/.cache/shapetree").expanduser()


def _fingerprint(version: str, root: Path, packages: tuple[str, ...] = FINGERPRINT_PACKAGES) -> str:
    """SHA-256 over ``version`` and the ``*.py`` files of ``packages``.

    Files are taken in sorted order of their path relative to ``root``; each contributes
    its relative path, its length and its bytes, so renames, moves and edits all count.
    """
    h = hashlib.sha256()
    h.update(b"shapetree-code-fingerprint\0")
    h.update(version.encode("utf-8") + b"\0")
    for pkg in packages:
        files = sorted((root / pkg).glob("*.py"), key=lambda p: p.name)
        if not files:
            raise RuntimeError(f"code_fingerprint: no sources found in {root / pkg}")
        for f in files:
            data = f.read_bytes()
            rel = f"{pkg}/{f.name}".encode()
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
        ``shapetree.detection``; ``"matching"``: the same without ``detection`` (what a
        matching cost depends on). Sorted, deterministic, computed once per process,
        version and scope.

    Key caches by it so that they can never silently reuse stale results after an upgrade
    or an edit of the code that produced them.
    """
    if scope not in FINGERPRINT_SCOPES:
        raise ValueError(f"scope must be one of {sorted(FINGERPRINT_SCOPES)}, got {scope!r}")
    return _cached_fingerprint(str(shapetree.__version__), scope)
