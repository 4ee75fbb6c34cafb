"""The published robot sets of ../shared/data with the committed rig.yaml files of
docs/results/robot_sets/ (test helper shared by the real-data pipeline tests)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


COMMITTED = REPO / "docs" / "results" / "robot_sets"


SETS = {
    "open3dv_eih": ("open3dv_eih/input_EyeInHand", ()),
    "yizhong_eye_in_hand": ("yizhong_toolkit/sample_data/eye_in_hand_test_data", ()),
    "yizhong_eye_to_hand": ("yizhong_toolkit/sample_data/eye_to_hand_test_data",
                            ("yizhong_toolkit/sample_data/intrinsic_calib_grid_test_images",)),
}


def _link(src: Path, dst: Path) -> None:
    try:
        os.symlink(src, dst)
    except OSError:  # pragma: no cover - file systems without symlinks
        (shutil.copytree if src.is_dir() else shutil.copy)(src, dst)


def published_with_rig(shared: Path, out: Path, name: str) -> Path:
    """The published folder of ``name`` rebuilt under ``out`` (every file linked, same
    relative layout, so ``../`` paths in rig.yaml resolve) plus the committed files."""
    folder, others = SETS[name]
    dst = out / folder
    dst.mkdir(parents=True)
    for f in sorted((shared / folder).iterdir()):
        _link(f, dst / f.name)
    for other in others:
        (out / other).parent.mkdir(parents=True, exist_ok=True)
        _link(shared / other, out / other)
    for f in sorted((COMMITTED / name).iterdir()):
        shutil.copy(f, dst / f.name)
    return dst

