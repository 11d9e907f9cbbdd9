"""Shared test setup.

The benchmark datasets are read from ``$SHAPETREE_DATA``; when it is unset the tests use
``<repo>/../shared/datasets`` (where CI keeps them). In CI (``CI=true``) a missing data
directory is an error, never a reason to skip.

Caches (``$SHAPETREE_CACHE``: curves, distance blocks, ETHZ detections) go to a temporary
folder made for the session and removed after it, unless ``$SHAPETREE_CACHE`` is already
set (e.g. a CI cache that should persist): tests never write into the home folder.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DEFAULT_DATA = REPO.parent / "shared" / "datasets"

os.environ.setdefault("SHAPETREE_DATA", str(DEFAULT_DATA))
os.environ.setdefault("MPLBACKEND", "Agg")

#: The session's own cache folder (None when ``$SHAPETREE_CACHE`` was given).
SESSION_CACHE: Path | None = None
if not os.environ.get("SHAPETREE_CACHE", "").strip():
    SESSION_CACHE = Path(tempfile.mkdtemp(prefix="shapetree-test-cache-"))
    os.environ["SHAPETREE_CACHE"] = str(SESSION_CACHE)


def pytest_sessionstart(session: pytest.Session) -> None:
    data = Path(os.environ["SHAPETREE_DATA"])
    if os.environ.get("CI", "").lower() in ("1", "true", "yes") and not data.is_dir():
        raise pytest.UsageError(f"CI run without datasets: {data} does not exist")


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    if SESSION_CACHE is not None:
        shutil.rmtree(SESSION_CACHE, ignore_errors=True)


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """The benchmark data directory."""
    return Path(os.environ["SHAPETREE_DATA"])
