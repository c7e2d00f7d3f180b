"""Shared test fixtures."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

# One BLAS thread: tests check correctness, not speed, and small matrices on a shared
# 2-core machine are far slower with threads contending (and reductions stay identical).
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")


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
