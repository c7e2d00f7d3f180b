"""Shared test fixtures."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO_ROOT.parent / "shared" / "data"


@pytest.fixture(scope="session")
def utias_folder() -> Path:
    """The real UTIAS MRCLAM dataset 1 beside the clone; skips when it is absent."""
    folder = SHARED_DATA / "utias-mrclam1"
    if not (folder / "Robot1_Odometry.dat").is_file():
        pytest.skip(
            f"real UTIAS data not found at {folder} (it lives in ../shared/data beside the clone)"
        )
    return folder
