"""Shared fixtures: the public data sets in ../shared/data and seeded generators."""

from __future__ import annotations

import os
from pathlib import Path

# Small dense problems everywhere here: threaded BLAS only adds contention on 2 cores
# (a 144x144 solve took 0.2 s instead of milliseconds with OpenBLAS threads on a busy machine).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402 (after the BLAS variables: numpy reads them on import)
import pytest  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("MULTIEYE_SHARED_DATA", REPO.parent / "shared" / "data"))


@pytest.fixture
def shared_data() -> Path:
    """Path of ../shared/data; skips the test with a reason when it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"public data sets not found at {SHARED_DATA} (set MULTIEYE_SHARED_DATA)")
    return SHARED_DATA


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20221)
