"""Basalt's calibration JSON as an intrinsics file (multieye.io.basalt): each camera type
projects as Basalt's own formulas (Usenko et al. 2018) say, a camera is chosen by name or
index, and what cannot be read is refused at its line."""

from __future__ import annotations

import json

import numpy as np
import pytest

from multieye.core.errors import DatasetError
from multieye.core.lens import project_points
from multieye.io.intrinsics_files import read_intrinsics

CAMS = [
    ("ds", {"fx": 349.7, "fy": 348.7, "cx": 365.9, "cy": 249.3, "xi": -0.24, "alpha": 0.567}),
    ("eucm", {"fx": 460.1, "fy": 459.2, "cx": 366.0, "cy": 249.5, "alpha": 0.63, "beta": 1.04}),
    ("kb4", {"fx": 286.6, "fy": 286.5, "cx": 422.3, "cy": 395.2, "k1": -0.0068, "k2": 0.045,
             "k3": -0.0435, "k4": 0.0084}),
    ("unified", {"fx": 280.0, "fy": 279.0, "cx": 376.0, "cy": 240.0, "alpha": 0.6}),
    ("pinhole", {"fx": 458.6, "fy": 457.3, "cx": 367.2, "cy": 248.4}),
]


def _write(tmp_path, cams, resolution=True):
    doc = {"value0": {
        "T_imu_cam": [{"px": 0.0, "py": 0.0, "pz": 0.0, "qx": 0.0, "qy": 0.0, "qz": 0.0,
                       "qw": 1.0} for _ in cams],
        "intrinsics": [{"camera_type": t, "intrinsics": p} for t, p in cams],
        **({"resolution": [[752, 480] for _ in cams]} if resolution else {}),
        "vignette": [], "imu_update_rate": 200.0, "cam_time_offset_ns": 0}}
    path = tmp_path / "calibration.json"
    path.write_text(json.dumps(doc, indent=4))
    return path


def _basalt_project(kind: str, p: dict, X: np.ndarray) -> np.ndarray:
    """Basalt's projection of each camera type, written from the double sphere paper."""
    x, y, z = X.T
    if kind == "ds":
        d1 = np.sqrt(x * x + y * y + z * z)
        d2 = np.sqrt(x * x + y * y + (p["xi"] * d1 + z) ** 2)
        den = p["alpha"] * d2 + (1 - p["alpha"]) * (p["xi"] * d1 + z)
    elif kind in ("eucm", "unified"):
        beta = p.get("beta", 1.0)
        d = np.sqrt(beta * (x * x + y * y) + z * z)
        den = p["alpha"] * d + (1 - p["alpha"]) * z
    elif kind == "kb4":
        r = np.hypot(x, y)
        th = np.arctan2(r, z)
        d = th * (1 + p["k1"] * th**2 + p["k2"] * th**4 + p["k3"] * th**6 + p["k4"] * th**8)
        return np.column_stack([p["fx"] * d * x / r + p["cx"], p["fy"] * d * y / r + p["cy"]])
    else:
        den = z
    return np.column_stack([p["fx"] * x / den + p["cx"], p["fy"] * y / den + p["cy"]])


@pytest.mark.parametrize("k", range(len(CAMS)))
def test_each_camera_type_projects_as_basalt_does(tmp_path, rng, k):
    path = _write(tmp_path, CAMS)
    intr = read_intrinsics(path, f"cam{k}")
    kind, p = CAMS[k]
    assert (intr.width, intr.height) == (752, 480)
    X = rng.normal(size=(200, 3)) * [1, 1, 0.3] + [0, 0, 1.5]    # ahead, up to ~60 degrees
    np.testing.assert_allclose(project_points(X, intr), _basalt_project(kind, p, X),
                               rtol=0, atol=1e-9)
    by_index = read_intrinsics(path, str(k))                      # the index alike
    assert by_index.model == intr.model and np.array_equal(by_index.params, intr.params)


def test_one_camera_needs_no_choice_and_several_do(tmp_path):
    one = read_intrinsics(_write(tmp_path, CAMS[:1], resolution=False))
    assert one.model == "double-sphere" and one.width is None
    with pytest.raises(DatasetError, match=r"calibration.json:\d+: value0.intrinsics: the file "
                       r"holds 5 cameras \(0 to 4\); choose one with intrinsics: \{file: "
                       r"calibration.json, camera: cam0\}"):
        read_intrinsics(_write(tmp_path, CAMS))
    with pytest.raises(DatasetError, match=r"camera 'cam7': the file holds cameras cam0 to cam4"):
        read_intrinsics(_write(tmp_path, CAMS), "cam7")
    # a rig camera named cam2 takes the file's cam2, as with a Kalibr camchain
    assert read_intrinsics(_write(tmp_path, CAMS), prefer="cam2").model == "fisheye"


@pytest.mark.parametrize("cam, message", [
    (("fov", {"fx": 1.0, "fy": 1.0, "cx": 1.0, "cy": 1.0, "w": 0.9}),
     r"value0.intrinsics.0.camera_type: Basalt camera_type 'fov' is not supported; expected ds, "
     "eucm, kb4, pinhole, unified"),
    (("ds", {"fx": 349.7, "fy": 348.7, "cx": 365.9, "cy": 249.3, "xi": -0.24}),
     r"value0.intrinsics.0.intrinsics.alpha: expected a number, got None"),
    (("ds", {"fx": 349.7, "fy": 348.7, "cx": 365.9, "cy": 249.3, "xi": -0.24, "alpha": 0.5,
             "beta": 1.0}), r"intrinsics.beta: not a key multieye reads"),
    (("unified", {"fx": 280.0, "fy": 279.0, "cx": 376.0, "cy": 240.0, "alpha": 1.0}),
     r"unified alpha must be in \[0, 1\), got 1.0"),
])
def test_what_cannot_be_read_is_refused_at_its_line(tmp_path, cam, message):
    with pytest.raises(DatasetError, match=message) as e:
        read_intrinsics(_write(tmp_path, [cam]))
    assert e.value.line is not None and e.value.line > 1
