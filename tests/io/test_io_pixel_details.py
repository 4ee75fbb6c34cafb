"""details.json per camera: target points and residuals, the intrinsics' covariance and the
projection-uncertainty grid; round trip, files without them, refusals, and the document."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from multieye.core.errors import DatasetError
from multieye.core.intrinsics import Intrinsics
from multieye.io.pixel_details import ImagePoints, ProjectionStd, plain, rounded
from multieye.io.run_details import (
    CameraDetails,
    RunDetails,
    TrajectoryDetails,
    read_run_details,
    run_details_to_dict,
    write_details,
)

DOC = Path(__file__).resolve().parents[2] / "docs" / "outputs.md"


def _details(extra: bool = True) -> RunDetails:
    rng = np.random.default_rng(4)
    n = 3
    intr = Intrinsics(np.array([[500.0, 0, 320], [0, 501, 240], [0, 0, 1]]),
                      [-0.2, 0.05, 1e-4, -2e-4, 0.01], "pinhole", 640, 480)
    kw = {}
    if extra:
        uv = (rng.uniform(0, 640, (5, 2)), np.zeros((0, 2)), rng.uniform(0, 480, (4, 2)))
        res = tuple(rng.normal(0, 0.3, u.shape) for u in uv)
        res[2][1] = np.nan                      # a point whose projection is not defined
        A = rng.normal(size=(9, 9))
        grid = np.abs(rng.normal(size=(3, 4)))
        grid[0, 0] = np.nan                     # a corner outside the invertible range
        kw = dict(points=ImagePoints("refined", (640, 480), 12, uv, res,
                                     np.array([0.31, np.nan, 0.27])),
                  intrinsics_estimated=True, intrinsics_covariance=A @ A.T * 1e-4,
                  projection_std=ProjectionStd(np.array([80.0, 240, 400, 560]),
                                               np.array([80.0, 240, 400]), grid))
    cam = CameraDetails("cam0", np.eye(4), intr, 0, ("a.png", "b.png", "c.png"),
                        np.arange(n, dtype=float), np.zeros(n), np.zeros(n), np.zeros(n),
                        np.tile(np.eye(4), (n, 1, 1)), {}, **kw)
    traj = TrajectoryDetails("T_world_marker", np.arange(4.0), np.zeros((4, 3)), 4)
    return RunDetails("eye-to-base", "cam0", (cam,), (traj,))


def _equal(a, b):
    np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_points_covariance_and_grid_round_trip(tmp_path):
    details = _details()
    write_details(tmp_path / "details.json", details)
    (back,) = read_run_details(tmp_path / "details.json").cameras
    (cam,) = details.cameras
    p, q = back.points, cam.points
    assert (p.source, p.image_size, p.n_points, p.kept) == ("refined", (640, 480), 12, 9)
    for a, b in zip(p.uv, q.uv):
        _equal(a, np.round(b, 2))
    for a, b in zip(p.residual_px, q.residual_px):
        _equal(a, np.round(b, 3))                 # NaN stays NaN (written as null)
    assert p.uv[1].shape == (0, 2) and np.isnan(p.residual_px[2][1]).all()
    _equal(p.rms_px, q.rms_px)
    assert back.intrinsics_estimated is True
    _equal(back.intrinsics_covariance, cam.intrinsics_covariance)   # full precision
    _equal(back.projection_std.u, cam.projection_std.u)
    _equal(back.projection_std.std_px, np.round(cam.projection_std.std_px, 4))
    assert back.projection_std.mean_px == pytest.approx(cam.projection_std.mean_px, abs=1e-4)
    assert back.projection_std.max_px == pytest.approx(np.nanmax(cam.projection_std.std_px),
                                                       abs=1e-4)
    data = json.loads((tmp_path / "details.json").read_text())
    entry = data["cameras"]["cam0"]
    assert entry["intrinsics"]["parameters"] == ["fx", "fy", "cx", "cy", "k1", "k2", "p1",
                                                 "p2", "k3"]
    assert entry["points"]["residual_px"][2][1] == [None, None]
    assert entry["projection_std"]["std_px"][0][0] is None


def test_given_intrinsics_say_so_without_covariance(tmp_path):
    details = _details(extra=False)
    cam = details.cameras[0]
    details = RunDetails(details.setup, details.reference_camera,
                         (CameraDetails(**{**cam.__dict__, "intrinsics_estimated": False}),),
                         details.trajectories)
    write_details(tmp_path / "details.json", details)
    data = json.loads((tmp_path / "details.json").read_text())["cameras"]["cam0"]
    assert data["intrinsics"]["estimated"] is False
    assert "covariance" not in data["intrinsics"] and "points" not in data
    back = read_run_details(tmp_path / "details.json").cameras[0]
    assert back.intrinsics_estimated is False and back.intrinsics_covariance is None


def test_files_without_the_new_keys_still_read(tmp_path):
    data = run_details_to_dict(_details())
    entry = data["cameras"]["cam0"]
    for key in ("points", "projection_std"):
        entry.pop(key)
    for key in ("estimated", "parameters", "covariance"):
        entry["intrinsics"].pop(key)
    (tmp_path / "details.json").write_text(json.dumps(data))
    (cam,) = read_run_details(tmp_path / "details.json").cameras
    assert (cam.points, cam.intrinsics_estimated, cam.intrinsics_covariance,
            cam.projection_std) == (None, None, None, None)
    assert cam.names == ("a.png", "b.png", "c.png")


@pytest.mark.parametrize("mutate, message", [
    (lambda c: c["points"].update(source="guess"), r"points\.source must be one of refined, pnp"),
    (lambda c: c["points"]["uv"].pop(), r"points\.uv must be a list with one entry per "
                                        r"measurement \(3\)"),
    (lambda c: c["points"]["residual_px"][0].pop(),
     r"points\.residual_px\[0\] must have one row per point of points\.uv\[0\] \(5\), got 4"),
    (lambda c: c["points"]["uv"][2].__setitem__(0, [1.0, None]), r"points\.uv\[2\] must be "
                                                                 r"finite numbers"),
    (lambda c: c["points"].update(n_points=3), r"points\.n_points must be an integer >= 9"),
    (lambda c: c["points"].update(image_size=[640]), r"points\.image_size must be \[width, "
                                                     r"height\]"),
    (lambda c: c["points"]["rms_px"].pop(), r"points\.rms_px must have shape \(3\)"),
    (lambda c: c["intrinsics"].update(covariance=[[1.0]]),
     r"intrinsics\.covariance must have shape \(9 x 9\)"),
    (lambda c: c["intrinsics"].update(estimated="yes"), r"intrinsics\.estimated must be true "
                                                        r"or false"),
    (lambda c: c["projection_std"]["std_px"].pop(), r"projection_std\.std_px must have shape "
                                                    r"\(3 x 4\)"),
    (lambda c: c["projection_std"]["std_px"][1].__setitem__(1, -1.0),
     r"projection_std\.std_px must not be negative"),
])
def test_malformed_new_keys_are_refused_with_file_and_camera(tmp_path, mutate, message):
    data = run_details_to_dict(_details())
    mutate(data["cameras"]["cam0"])
    path = tmp_path / "details.json"
    path.write_text(json.dumps(data))
    with pytest.raises(DatasetError, match=r"details\.json: camera cam0: " + message):
        read_run_details(path)


def test_rounded_is_compact_and_keeps_nan_as_null():
    assert rounded([1.23456, float("nan")], 2) == [1.23, None]
    assert rounded(np.array([[0.0004, -2.5]]), 3) == [[0.0, -2.5]]
    assert rounded(float("inf"), 2) is None
    assert json.dumps(rounded([123.456789], 2)) == "[123.46]"


def test_plain_gives_every_float_at_full_precision_and_nan_or_inf_as_null():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(3, 4, 4)) * 10.0 ** rng.integers(-20, 20, size=(3, 4, 4))
    a[1, 2, 3], a[2, 0, 0], a[0, 1, 1] = np.nan, np.inf, -0.0

    def by_element(x):      # the reference: one element at a time
        x = np.asarray(x, dtype=np.float64)
        if x.ndim == 0:
            return float(x) if np.isfinite(x) else None
        return [by_element(y) for y in x]

    for x in (a, a[0], a[0, 0], a[1], a[0, 0, 0], a[2, 0, 0], np.zeros((0, 4, 4)),
              [1, 2], 7):
        got = plain(x)
        assert got == by_element(x)
        assert json.dumps(got) == json.dumps(by_element(x))     # -0.0 and types too
    assert plain(a)[0][1][1] == 0.0 and str(plain(a)[0][1][1]) == "-0.0"
    assert type(plain(np.float32(0.1))) is float and plain(np.float32(0.1)) == float(np.float32(0.1))


def test_outputs_doc_names_every_new_details_key():
    data = run_details_to_dict(_details())
    entry = data["cameras"]["cam0"]
    keys = ({"points", "projection_std"} | set(entry["points"]) | set(entry["projection_std"])
            | {"estimated", "parameters", "covariance"})
    section = re.split(r"^## \d+\. ", DOC.read_text(), flags=re.M)[3]
    assert section.startswith("`details.json`")
    assert sorted(k for k in keys if f"`{k}`" not in section) == []
