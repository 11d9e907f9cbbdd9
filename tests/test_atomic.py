"""shapetree._atomic: the one atomic file writer."""

from __future__ import annotations

import os
import stat
import sys
import threading

import pytest

from shapetree import _atomic
from shapetree._atomic import atomic_open, atomic_write_bytes, atomic_write_text


@pytest.fixture
def no_umask(monkeypatch):
    """Fail the test if anything calls os.umask (it is process-wide, racy with threads)."""

    def boom(*args, **kwargs):
        raise AssertionError("os.umask must never be called")

    monkeypatch.setattr(os, "umask", boom)


def _leftovers(folder):
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp"))


def test_writes_bytes_and_text(tmp_path, no_umask):
    atomic_write_bytes(tmp_path / "a.bin", b"\x00\x01")
    assert (tmp_path / "a.bin").read_bytes() == b"\x00\x01"
    atomic_write_text(tmp_path / "sub" / "b.txt", "héllo\nworld\n")  # folder created
    assert (tmp_path / "sub" / "b.txt").read_bytes() == "héllo\nworld\n".encode()
    with atomic_open(tmp_path / "c.txt", "w") as fh:
        fh.write("x")
    assert (tmp_path / "c.txt").read_text() == "x"
    with atomic_open(tmp_path / "d.bin", fsync=True) as fh:
        fh.write(b"y")
    assert (tmp_path / "d.bin").read_bytes() == b"y"
    assert _leftovers(tmp_path) == []


def test_replaces_existing_file(tmp_path):
    p = tmp_path / "f.json"
    p.write_text("old")
    atomic_write_text(p, "new")
    assert p.read_text() == "new"


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX permissions")
@pytest.mark.parametrize("umask", [0o022, 0o027, 0o077])
def test_mode_follows_umask(tmp_path, monkeypatch, umask):
    old = os.umask(umask)
    try:
        with monkeypatch.context() as m:
            m.setattr(os, "umask", lambda *a: (_ for _ in ()).throw(AssertionError("umask")))
            atomic_write_bytes(tmp_path / "a", b"1")
            atomic_write_text(tmp_path / "b", "2")
            with atomic_open(tmp_path / "c", "w") as fh:
                fh.write("3")
    finally:
        os.umask(old)
    for name in "abc":
        assert stat.S_IMODE((tmp_path / name).stat().st_mode) == 0o666 & ~umask, name


def test_exception_leaves_target_and_no_temp(tmp_path, no_umask):
    p = tmp_path / "keep.txt"
    p.write_text("original")
    with pytest.raises(RuntimeError, match="half"):
        with atomic_open(p, "w") as fh:
            fh.write("half-written")
            fh.flush()
            raise RuntimeError("half")
    assert p.read_text() == "original"
    assert _leftovers(tmp_path) == []
    # a new target is not created at all
    with pytest.raises(KeyboardInterrupt):
        with atomic_open(tmp_path / "new.bin") as fh:
            fh.write(b"x")
            raise KeyboardInterrupt
    assert not (tmp_path / "new.bin").exists()
    assert sorted(x.name for x in tmp_path.iterdir()) == ["keep.txt"]


def test_failed_rename_removes_temp(tmp_path, monkeypatch):
    p = tmp_path / "t.bin"

    def fail(src, dst):
        raise OSError("disk gone")

    monkeypatch.setattr(_atomic.os, "replace", fail)
    with pytest.raises(OSError, match="disk gone"):
        atomic_write_bytes(p, b"data")
    assert list(tmp_path.iterdir()) == []


def test_bad_mode(tmp_path):
    with pytest.raises(ValueError, match="mode"):
        with atomic_open(tmp_path / "x", "a"):
            pass
    assert list(tmp_path.iterdir()) == []


def test_concurrent_writers_do_not_interfere(tmp_path, no_umask):
    """Threads writing the same and different targets: every file ends complete, no temp left."""
    n_threads, rounds, size = 8, 25, 64 * 1024
    shared = tmp_path / "shared.bin"
    errors = []
    barrier = threading.Barrier(n_threads)

    def worker(k):
        try:
            barrier.wait()
            payload = bytes([k]) * size
            for r in range(rounds):
                atomic_write_bytes(shared, payload, fsync=False)
                with atomic_open(tmp_path / f"own_{k}.txt", "w") as fh:
                    fh.write(f"{k}:{r}\n" * 1000)
        except BaseException as e:  # pragma: no cover - reported below
            errors.append(e)

    threads = [threading.Thread(target=worker, args=(k,)) for k in range(n_threads)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []
    data = shared.read_bytes()
    assert len(data) == size and len(set(data)) == 1  # one writer's complete payload
    for k in range(n_threads):
        assert (tmp_path / f"own_{k}.txt").read_text() == f"{k}:{rounds - 1}\n" * 1000
    assert _leftovers(tmp_path) == []


def test_no_other_atomic_writer_in_owned_modules():
    """The package's atomic writes go through _atomic: no private mkstemp/umask copies."""
    import shapetree.datasets._load as load
    import shapetree.detection._files as files
    import shapetree.plotting._save as save

    for mod in (files, load, save):
        src = open(mod.__file__, encoding="utf-8").read()
        for word in ("mkstemp", "os.umask", "os.replace"):
            assert word not in src, (mod.__name__, word)
