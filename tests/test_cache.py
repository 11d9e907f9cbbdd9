"""shapetree._cache: cache folder and code fingerprint."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest

import shapetree
from shapetree import _cache
from shapetree._cache import FINGERPRINT_PACKAGES, cache_root, code_fingerprint


def test_cache_root_env_override(monkeypatch, tmp_path):
    monkeypatch.setenv("SHAPETREE_CACHE", str(tmp_path / "c"))
    assert cache_root() == tmp_path / "c"


def test_cache_root_expands_user(monkeypatch, tmp_path):
    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.setenv("SHAPETREE_CACHE", "~/mycache")
    assert cache_root() == tmp_path / "mycache"


@pytest.mark.parametrize("value", [None, "", "  "])
def test_cache_root_default(monkeypatch, tmp_path, value):
    monkeypatch.setenv("HOME", str(tmp_path))
    if value is None:
        monkeypatch.delenv("SHAPETREE_CACHE", raising=False)
    else:
        monkeypatch.setenv("SHAPETREE_CACHE", value)
    assert cache_root() == tmp_path / ".cache" / "shapetree"


def test_fingerprint_is_hex_sha256_and_deterministic():
    fp = code_fingerprint()
    assert re.fullmatch(r"[0-9a-f]{64}", fp)
    assert code_fingerprint() == fp
    src = Path(_cache.__file__).resolve().parent
    assert _cache._fingerprint(shapetree.__version__, src) == fp  # recomputed from scratch


def test_fingerprint_changes_with_version(monkeypatch):
    fp = code_fingerprint()
    monkeypatch.setattr(shapetree, "__version__", shapetree.__version__ + ".post1")
    assert code_fingerprint() != fp
    monkeypatch.undo()
    assert code_fingerprint() == fp


def test_fingerprint_changes_with_any_relevant_source(tmp_path):
    src = Path(_cache.__file__).resolve().parent
    for pkg in FINGERPRINT_PACKAGES:
        shutil.copytree(src / pkg, tmp_path / pkg, ignore=shutil.ignore_patterns("__pycache__"))
    base = _cache._fingerprint("1", tmp_path)
    for pkg in FINGERPRINT_PACKAGES:
        f = sorted((tmp_path / pkg).glob("*.py"))[-1]
        original = f.read_bytes()
        f.write_bytes(original + b"\n# edit\n")
        assert _cache._fingerprint("1", tmp_path) != base, pkg
        f.write_bytes(original)
    assert _cache._fingerprint("1", tmp_path) == base
    # a file outside the fingerprinted packages does not matter
    (tmp_path / "unrelated.py").write_text("x = 1\n")
    assert _cache._fingerprint("1", tmp_path) == base


def _copy_sources(dst: Path) -> None:
    src = Path(_cache.__file__).resolve().parent
    for pkg in (*FINGERPRINT_PACKAGES, "retrieval"):
        shutil.copytree(src / pkg, dst / pkg, ignore=shutil.ignore_patterns("__pycache__"))


def test_matching_scope_ignores_detection_sources(tmp_path):
    """A distance cache or shape database (scope "matching") survives an edit of the
    detection code; the "all" scope (detection caches) does not."""
    _copy_sources(tmp_path)
    scopes = _cache.FINGERPRINT_SCOPES
    before = {s: _cache._fingerprint("1", tmp_path, scopes[s]) for s in scopes}
    f = sorted((tmp_path / "detection").glob("*.py"))[0]
    f.write_bytes(f.read_bytes() + b"\n# edited\n")
    after = {s: _cache._fingerprint("1", tmp_path, scopes[s]) for s in scopes}
    assert after["matching"] == before["matching"]
    assert after["all"] != before["all"]
    g = sorted((tmp_path / "matching").glob("*.py"))[0]
    g.write_bytes(g.read_bytes() + b"\n# edited\n")
    assert _cache._fingerprint("1", tmp_path, scopes["matching"]) != before["matching"]
    assert code_fingerprint("matching") != code_fingerprint("all")
    with pytest.raises(ValueError, match="scope"):
        code_fingerprint("detection")


@pytest.mark.parametrize("module", _cache.RETRIEVAL_CACHE_MODULES)
def test_matching_scope_follows_the_retrieval_cache_modules(tmp_path, module):
    """An edit of the engine, the pruned search or the shape database (what fills the
    distance, neighbour and database caches) changes the "matching" scope, and leaves
    the detection caches' "all" scope alone."""
    _copy_sources(tmp_path)
    scopes = _cache.FINGERPRINT_SCOPES
    before = {s: _cache._fingerprint("1", tmp_path, scopes[s]) for s in scopes}
    f = tmp_path / module
    f.write_bytes(f.read_bytes() + b"\n# edited\n")
    assert _cache._fingerprint("1", tmp_path, scopes["matching"]) != before["matching"]
    assert _cache._fingerprint("1", tmp_path, scopes["all"]) == before["all"]


def test_scopes_ignore_retrieval_modules_that_only_read_results(tmp_path):
    """Protocols, scoring and re-ranking read cached costs; editing them recomputes
    nothing."""
    _copy_sources(tmp_path)
    scopes = _cache.FINGERPRINT_SCOPES
    before = {s: _cache._fingerprint("1", tmp_path, scopes[s]) for s in scopes}
    for name in ("_evaluate.py", "_protocols.py", "_rerank.py", "_dask.py"):
        f = tmp_path / "retrieval" / name
        f.write_bytes(f.read_bytes() + b"\n# edited\n")
    assert {s: _cache._fingerprint("1", tmp_path, scopes[s]) for s in scopes} == before


def test_a_missing_scope_module_is_an_error(tmp_path):
    _copy_sources(tmp_path)
    (tmp_path / "retrieval" / "_knn.py").unlink()
    with pytest.raises(RuntimeError, match="no sources"):
        _cache._fingerprint("1", tmp_path, _cache.FINGERPRINT_SCOPES["matching"])


def test_distance_cache_key_follows_the_matching_scope(monkeypatch) -> None:
    """The engine's block key changes with the matching code, not with the detection code
    alone (the documented purpose of the ``"matching"`` scope)."""
    from shapetree.matching import MatchConfig
    from shapetree.retrieval._engine import _cache_key

    curves = [np.c_[np.cos(t), np.sin(t)] for t in [np.linspace(0, 6, 20, endpoint=False)]]
    cfg = MatchConfig(n_points=20)
    key = _cache_key(curves, [curves], cfg)
    real = _cache._cached_fingerprint

    def edited(scope: str):
        def fp(version: str, s: str) -> str:
            return "0" * 64 if s == scope else real(version, s)

        return fp

    monkeypatch.setattr(_cache, "_cached_fingerprint", edited("all"))  # detection edited
    assert _cache_key(curves, [curves], cfg) == key
    monkeypatch.setattr(_cache, "_cached_fingerprint", edited("matching"))  # a kernel edited
    assert _cache_key(curves, [curves], cfg) != key
