"""Shared test setup.

The benchmark datasets are read from ``$SHAPETREE_DATA``; when it is unset the tests use
``<repo>/../shared/datasets`` (where CI keeps them). In CI (``CI=true``) a missing data
directory is an error, never a reason to skip.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DEFAULT_DATA = REPO.parent / "shared" / "datasets"

os.environ.setdefault("SHAPETREE_DATA", str(DEFAULT_DATA))
# keep test caches out of the user's home
os.environ.setdefault("MPLBACKEND", "Agg")


def pytest_sessionstart(session: pytest.Session) -> None:
    data = Path(os.environ["SHAPETREE_DATA"])
    if os.environ.get("CI", "").lower() in ("1", "true", "yes") and not data.is_dir():
        raise pytest.UsageError(f"CI run without datasets: {data} does not exist")


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """The benchmark data directory."""
    return Path(os.environ["SHAPETREE_DATA"])
