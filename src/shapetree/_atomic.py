"""Atomic file output: write to a temporary file beside the target, then rename.

A reader (or a later run) never sees a half-written file: either the old content or the
new one. This module is the package's only implementation of it; every picture, JSON
record, CSV and cache file shapetree writes goes through :func:`atomic_open`,
:func:`atomic_write_bytes` or :func:`atomic_write_text`.

The temporary file is created with ``os.open(tmp, O_CREAT | O_EXCL | O_WRONLY, 0o666)``
under a random name, so the process umask applies to it exactly as to any normally
created file, and the final file gets the usual mode (e.g. 0644 under umask 022). The
umask is never read or changed: ``os.umask`` is process-wide, and the usual trick of
calling ``os.umask(0)`` to read it briefly makes every file created meanwhile by another
thread (the retrieval engine writes its cache from worker threads) world-writable.
"""

from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Iterator
from pathlib import Path
from typing import IO

__all__ = ["atomic_open", "atomic_write_bytes", "atomic_write_text"]

_FLAGS = os.O_CREAT | os.O_EXCL | os.O_WRONLY | getattr(os, "O_CLOEXEC", 0)
_FLAGS |= getattr(os, "O_BINARY", 0)  # Windows: no newline translation at the fd level
_MODES = {"wb": "wb", "w": "w", "wt": "w"}


def _create_temp(parent: Path, name: str) -> tuple[int, Path]:
    """Create a new, empty, uniquely named file in ``parent``; return its fd and path."""
    stem = name[:200]  # keep the temporary name under NAME_MAX
    for _ in range(100):
        tmp = parent / f".{stem}.{secrets.token_hex(8)}.tmp"
        try:
            return os.open(tmp, _FLAGS, 0o666), tmp
        except FileExistsError:
            continue
    raise FileExistsError(f"could not create a temporary file for {name!r} in {parent}")


def _fsync_dir(folder: Path) -> None:
    """Flush a folder entry (the rename) to disk; best effort (not possible on Windows)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


@contextlib.contextmanager
def atomic_open(
    path: str | os.PathLike[str],
    mode: str = "wb",
    *,
    fsync: bool = False,
    encoding: str = "utf-8",
    newline: str | None = None,
) -> Iterator[IO]:
    """Open a temporary file next to ``path``; on success it replaces ``path``.

    On any exception (including ``KeyboardInterrupt``) the temporary file is removed and
    ``path`` is left untouched. Concurrent writers (threads or processes) each get their
    own temporary file; the last one to finish wins, and no reader ever sees a mixture.

    Parameters
    ----------
    path : path-like
        Final file name (its folder is created if needed).
    mode : {"wb", "w", "wt"}
        Binary or text output.
    fsync : bool, default False
        Flush the data (and then the folder entry) to disk before returning, so the file
        survives a crash of the machine, not only of the process. Costs a disk sync.
    encoding : str, default "utf-8"
        Text mode only.
    newline : str or None
        Text mode only, as for :func:`open` (``""`` for the :mod:`csv` module).

    Yields
    ------
    file object
        Write to it; do not close it yourself.
    """
    if mode not in _MODES:
        raise ValueError(f"atomic_open: mode must be 'wb', 'w' or 'wt', not {mode!r}")
    p = Path(path)
    parent = p.parent if str(p.parent) else Path(".")
    parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = _create_temp(parent, p.name)
    try:
        text = {} if "b" in mode else {"encoding": encoding, "newline": newline}
        try:
            fh = os.fdopen(fd, _MODES[mode], **text)
        except BaseException:
            os.close(fd)
            raise
        with fh:
            yield fh
            if fsync:
                fh.flush()
                os.fsync(fh.fileno())
        os.replace(tmp, p)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    if fsync:
        _fsync_dir(parent)


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes, *, fsync: bool = True) -> Path:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_open`); returns ``path``.

    ``fsync`` defaults to True: bytes are typically cache or result files that must be
    complete after a crash. Pass ``fsync=False`` for throw-away output.
    """
    p = Path(path)
    with atomic_open(p, "wb", fsync=fsync) as fh:
        fh.write(data)
    return p


def atomic_write_text(
    path: str | os.PathLike[str],
    text: str,
    *,
    fsync: bool = False,
    encoding: str = "utf-8",
) -> Path:
    """Write ``text`` to ``path`` atomically (see :func:`atomic_open`); returns ``path``.

    Newlines are written as ``"\\n"`` on every platform.
    """
    p = Path(path)
    with atomic_open(p, "w", fsync=fsync, encoding=encoding, newline="") as fh:
        fh.write(text)
    return p
