"""Shared fixtures: where the repository's sample assets and ../shared/data live."""
from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SAMPLE_ASSETS = REPO / "sample_assets"
SHARED_DATA = REPO.parent / "shared" / "data"


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return REPO


@pytest.fixture(scope="session")
def sample_assets() -> Path:
    return SAMPLE_ASSETS


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """../shared/data; tests that need it skip with a reason when it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"{SHARED_DATA} not present")
    return SHARED_DATA


def run_cli(*args) -> int:
    """`usdface ARGS...` in this process; returns the exit code."""
    from usdface.cli import main

    return main([str(a) for a in args])


@pytest.fixture(scope="session")
def cli():
    """Run `usdface ARGS...` in-process; returns the exit code."""
    return run_cli
