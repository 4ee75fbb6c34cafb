"""The UTIAS 8-camera / 16-tag pose pairs: reader (format, errors, round trip) and a real joint
solve of all cameras and tags."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from multieye.core import geometry as g
from multieye.core.errors import DatasetError
from multieye.solvers.general import solve_general
from multieye.io.utias import COMBINED_DIR, read_pose_rows, read_utias_rwhec
from multieye.core.metrics import loop_residuals


def _row(T: np.ndarray) -> str:
    q = Rotation.from_matrix(T[:3, :3]).as_quat()           # x y z w
    return ",".join(f"{v:.17g}" for v in (q[3], q[0], q[1], q[2], *T[:3, 3]))


def _write_pair(folder: Path, tag: int, cam: int, A: np.ndarray, B: np.ndarray) -> None:
    for side, T in (("A", A), ("B", B)):
        (folder / f"tag_{tag}_cam_{cam}_{side}.csv").write_text(
            "".join(_row(t) + "\n" for t in T))


# --- reader, on written files ---------------------------------------------------------------

@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 6))
def test_rows_round_trip(tmp_path_factory, seed, n):
    rng = np.random.default_rng(seed)
    folder = tmp_path_factory.mktemp("utias")
    A = g.random_transforms(rng, n)
    B = g.random_transforms(rng, n)
    _write_pair(folder, 3, 1, A, B)
    _write_pair(folder, 12, 0, B[:1], A[:1])
    groups = read_utias_rwhec(folder)
    assert [(gr.x_name, gr.y_name) for gr in groups] == [("tag3", "cam1"), ("tag12", "cam0")]
    assert np.abs(groups[0].A - A).max() < 1e-12
    assert np.abs(groups[0].B - B).max() < 1e-12
    assert np.abs(groups[1].A - B[:1]).max() < 1e-12


def test_quaternion_is_read_scalar_first(tmp_path):
    f = tmp_path / "rows.csv"
    half = np.sqrt(0.5)
    f.write_text(f"{half},0,0,{half},1,2,3\n")            # qw qx qy qz: 90 degrees about z
    T = read_pose_rows(f)
    assert np.allclose(T[0], [[0, -1, 0, 1], [1, 0, 0, 2], [0, 0, 1, 3], [0, 0, 0, 1]])


@pytest.mark.parametrize("text, line, message", [
    ("1,0,0,0,1,2,3\n1,0,0,0,1,2\n", 2, "expected 7 entries per row"),
    ("1,0,0,0,1,2,3\n1,0,0,0,1,x,3\n", 2, "expected a number for ty"),
    ("2,0,0,0,1,2,3\n", 1, "unit norm"),
    ("1,0,0,0,nan,2,3\n", 1, "finite number for tx"),
])
def test_malformed_rows_name_file_and_line(tmp_path, text, line, message):
    f = tmp_path / "tag_0_cam_0_A.csv"
    f.write_text(text)
    with pytest.raises(DatasetError, match=message) as info:
        read_pose_rows(f)
    assert info.value.path == str(f) and info.value.line == line
    assert str(info.value).startswith(f"{f}:{line}: ")


def test_empty_file_is_an_error(tmp_path):
    f = tmp_path / "tag_0_cam_0_A.csv"
    f.write_text("\n")
    with pytest.raises(DatasetError, match="no poses"):
        read_pose_rows(f)


def test_unpaired_and_mismatched_files_are_errors(rng, tmp_path):
    T = g.random_transforms(rng, 3)
    _write_pair(tmp_path, 1, 2, T, T[:2])
    with pytest.raises(DatasetError, match="3 rows but tag_1_cam_2_B.csv has 2") as info:
        read_utias_rwhec(tmp_path)
    assert info.value.camera == "cam2"
    (tmp_path / "tag_1_cam_2_B.csv").unlink()
    with pytest.raises(DatasetError, match="tag_1_cam_2_A.csv has no matching _B.csv"):
        read_utias_rwhec(tmp_path)


def test_folder_without_pose_files_is_an_error(tmp_path):
    with pytest.raises(DatasetError, match="no tag_<T>_cam_<C>_A.csv"):
        read_utias_rwhec(tmp_path)
    with pytest.raises(DatasetError, match="expected the UTIAS data folder"):
        read_utias_rwhec(tmp_path / "missing")


# --- the real data --------------------------------------------------------------------------

@functools.lru_cache(maxsize=1)
def _read_once(folder: str):
    return tuple(read_utias_rwhec(folder))


@pytest.fixture
def utias_groups(shared_data):
    data = shared_data / "utias_rwhec"
    if not data.is_dir():
        pytest.skip(f"UTIAS data not found at {data}")
    return list(_read_once(str(data)))


def test_real_data_has_the_documented_pairs_and_rows(utias_groups, shared_data):
    # PROVENANCE.md: 73 pairs, 3230 rows, 8 cameras, 16 tags, these rows per camera.
    assert len(utias_groups) == 73
    assert sum(len(gr.A) for gr in utias_groups) == 3230
    per_camera = {}
    for gr in utias_groups:
        per_camera[gr.y_name] = per_camera.get(gr.y_name, 0) + len(gr.A)
    assert per_camera == {"cam0": 619, "cam1": 731, "cam2": 526, "cam3": 197, "cam4": 68,
                          "cam5": 383, "cam6": 384, "cam7": 322}
    tags = {int(gr.x_name[3:]) for gr in utias_groups}
    assert tags == {0, 1, 2, 6, 8, 11, 12, 13, 14, 15, 16, 18, 19, 20, 22, 23}
    # Row 1 of tag_0_cam_0_A.csv, converted here independently of the reader.
    first = np.loadtxt(shared_data / "utias_rwhec" / COMBINED_DIR / "tag_0_cam_0_A.csv",
                       delimiter=",", max_rows=1)
    R = Rotation.from_quat(first[[1, 2, 3, 0]]).as_matrix()
    assert np.abs(utias_groups[0].A[0, :3, :3] - R).max() < 1e-12
    assert np.array_equal(utias_groups[0].A[0, :3, 3], first[4:])


def test_real_joint_solve_fits_and_refinement_improves_it(utias_groups):
    def median_trans(sol):
        return np.median(np.concatenate([
            loop_residuals(gr.A, gr.B, sol.X[gr.x_name], sol.Y[gr.y_name])[1]
            for gr in utias_groups]))

    closed = solve_general(utias_groups)
    refined = solve_general(utias_groups, refine=True)
    assert set(closed.Y) == {f"cam{c}" for c in range(8)} and len(closed.X) == 16
    # The data set's own per-pair check found 1-3 cm; jointly the closed form is about 3 cm.
    assert median_trans(closed) < 0.04
    assert median_trans(refined) < median_trans(closed)
    # Every camera is estimated to a few millimetres and a fraction of a degree.
    for cam in refined.Y:
        cov = refined.covariance_of("Y", cam)
        assert np.sqrt(np.trace(cov[:3, :3])) < np.radians(1.0)
        assert np.sqrt(np.trace(cov[3:, 3:])) < 0.02


def test_real_held_out_pair_is_predicted(utias_groups):
    # tag0 seen by cam0 is left out; both unknowns stay linked through other pairs.
    k = next(i for i, gr in enumerate(utias_groups) if (gr.x_name, gr.y_name) == ("tag0", "cam0"))
    held = utias_groups[k]
    sol = solve_general(utias_groups[:k] + utias_groups[k + 1:])
    _, trans = loop_residuals(held.A, held.B, sol.X["tag0"], sol.Y["cam0"])
    assert np.median(trans) < 0.08
