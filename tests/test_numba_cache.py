"""Numba's on-disk cache of the kernels notices an edit of any kernel source.

numba checks a cached kernel only against the file that defines it; ``_numba_cache``
adds the hash of every kernel module to the stamp. The end-to-end test runs three fresh
interpreters on one cache directory: the second reads the first one's machine code, the
third, where one other kernel module "changed" (its hash replaced), compiles again.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from shapetree import _numba_cache

SRC = Path(_numba_cache.__file__).resolve().parent


def test_every_module_with_a_cached_kernel_is_hashed() -> None:
    with_cache = sorted(
        p.relative_to(SRC).as_posix()
        for p in SRC.rglob("*.py")
        if "cache=True" in p.read_text(encoding="utf-8") and p.name != "_numba_cache.py"
    )
    assert with_cache and set(with_cache) <= set(_numba_cache.KERNEL_MODULES)
    assert all((SRC / m).is_file() for m in _numba_cache.KERNEL_MODULES)


def test_shapetree_kernels_use_the_stamped_locator() -> None:
    from shapetree.detection import _stitch
    from shapetree.geometry import _dif
    from shapetree.matching import _bound, _height, _kernels, _subcurves

    assert _numba_cache.install()  # idempotent: already installed by _dif
    h = _numba_cache.kernel_sources_hash()
    assert len(h) == 64
    for mod in (_dif, _kernels, _bound, _subcurves, _height, _stitch):
        jitted = [
            f for f in vars(mod).values() if getattr(getattr(f, "_cache", None), "_impl", None)
        ]
        assert jitted, mod.__name__
        for f in jitted:
            loc = f._cache._impl.locator
            assert type(loc).__name__.startswith("Shapetree"), (mod.__name__, f.__name__)
            assert loc.get_source_stamp()[1] == h


def test_other_packages_keep_numba_locators(tmp_path: Path) -> None:
    """A function outside the package is located by numba's own classes."""
    from numba.core import caching

    py = tmp_path / "elsewhere.py"
    py.write_text("def f():\n    return 1\n")
    ns: dict = {}
    exec(compile(py.read_text(), str(py), "exec"), ns)
    for cls in caching.CacheImpl._locator_classes:
        if getattr(cls, "_shapetree", False):
            assert cls.from_function(ns["f"], str(py)) is None


_RUN = """
import json, sys
from shapetree import _numba_cache
if sys.argv[1] != "same":
    # another kernel module's bytes, as after an edit of _dif.py alone
    _numba_cache.kernel_sources_hash = lambda: "0" * 64
from shapetree.detection._stitch import _dif
_dif(0j, 1 + 0j, 1j, 0j, 1 + 0j, 0.5 + 1j)
(sig,) = _dif.signatures
print(json.dumps({"hits": _dif.stats.cache_hits[sig], "misses": _dif.stats.cache_misses[sig]}))
"""


def test_a_changed_kernel_module_recompiles_its_callers(tmp_path: Path) -> None:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba"))

    def run(mode: str) -> dict:
        out = subprocess.run(
            [sys.executable, "-c", _RUN, mode], env=env, capture_output=True, text=True, check=True
        )
        return json.loads(out.stdout.strip().splitlines()[-1])

    first = run("same")
    assert first == {"hits": 0, "misses": 1}  # compiled and written
    assert run("same") == {"hits": 1, "misses": 0}  # read back
    assert run("changed") == {"hits": 0, "misses": 1}  # stale: compiled again
