"""Shared fixtures: the public data sets in ../shared/data and seeded generators.

The test modules' shared helpers are the modules beside this file (tests/*.py without the
test_ prefix). This folder goes on sys.path here, once, so that ``from small_dataset import
render_small`` resolves however pytest is started: from any folder, on one file or the whole
suite, with ``--import-mode=importlib`` (which puts no test folder on sys.path) or ``--rootdir``
elsewhere. No test module touches sys.path itself (tests/test_test_imports.py).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

HELPERS = str(Path(__file__).resolve().parent)
if HELPERS not in sys.path:
    sys.path.insert(0, HELPERS)

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
