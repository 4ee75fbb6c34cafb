"""details.json, the report figures and report.html, down to a real headless browser.

Most tests use in-memory runs of known frames (``test_export.make_run``: the pipeline's pairing
and solver on exact or noisy measurements).  The browser test renders a small demo-like
dataset (2 cameras, 8 images each, 640 x 480), runs the whole pipeline on it and loads the
report in Debian's chromium: no console message at all (the page has no script and a
Content-Security-Policy that turns any attempt to load something into a logged error), every
figure decodes at its PNG size, and the screenshot shows the figures' colours.
"""

from __future__ import annotations

import dataclasses
import html
import json
import os
import re
import shutil
import struct
from pathlib import Path

import numpy as np
import pytest
from multieye.core.errors import DatasetError, InputError
from multieye.core.metrics import loop_residuals, pose_row
from multieye.io import Trajectory
from multieye.io.run_details import (
    TRAJECTORY_MARGIN_S,
    read_run_details,
    run_details_from_dict,
    run_details_to_dict,
)
from multieye.outputs.details import write_run_details
from multieye.outputs.figures import outliers
from multieye.outputs.figures_rig import display_rotation, frustum_corners
from multieye.outputs.report import FIGURES, write_report
from multieye.outputs.report_images import image_folders
from multieye.outputs.write import write_outputs
from export_runs import NAMES, make_run

from browser import (chromium, embedded_figures, layout, needs_chromium, plain_cells, probe,
                     screenshot, screenshot_at)

SETUPS = ["eye-to-base", "eye-on-hand"]


def _png_size(data: bytes) -> tuple[int, int]:
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    return struct.unpack(">II", data[16:24])


def _image_size(data: bytes) -> tuple[int, int]:
    """Width and height of a PNG or JPEG."""
    if data[:3] == b"\xff\xd8\xff":
        from PIL import Image
        import io

        with Image.open(io.BytesIO(data)) as im:
            return im.size
    return _png_size(data)


# --------------------------------------------------------------------------- details.json


@pytest.mark.parametrize("setup", SETUPS)
def test_details_round_trip_is_exact(setup, tmp_path):
    run, _ = make_run(tmp_path, setup, noise=1e-3)
    diag = {"cam0": {"rotation_spread_deg": np.float64(12.5), "axes": np.array([1, 2]),
                     "weak": np.bool_(True), "nan": float("nan")}}
    written = write_run_details(tmp_path / "details.json", run, diagnostics=diag)
    back = read_run_details(tmp_path / "details.json")
    assert (back.setup, back.reference_camera) == (setup, "cam0")
    assert [c.name for c in back.cameras] == list(NAMES)
    for a, b in zip(back.cameras, written.cameras):
        assert a.names == b.names and a.trajectory == b.trajectory
        for key in ("T_world_cam", "stamps", "rot_deg", "trans_m", "rms_px", "T_world_target"):
            np.testing.assert_array_equal(getattr(a, key), getattr(b, key), err_msg=key)
        np.testing.assert_array_equal(a.intrinsics.K, b.intrinsics.K)
        np.testing.assert_array_equal(a.intrinsics.dist, b.intrinsics.dist)
        assert (a.intrinsics.width, a.intrinsics.height) == (640, 480)
    assert back.camera("cam0").diagnostics == {"rotation_spread_deg": 12.5, "axes": [1, 2],
                                               "weak": True, "nan": None}
    assert back.camera("front left").diagnostics == {}
    (t,) = back.trajectories
    np.testing.assert_array_equal(t.positions, written.trajectories[0].positions)
    assert t.pose == ("T_world_marker" if setup == "eye-to-base" else "T_world_body")
    assert (back.T_world_body_shown is None) == (setup == "eye-to-base")


@pytest.mark.parametrize("setup", SETUPS)
def test_details_frames_are_the_true_frames_on_exact_data(setup, tmp_path):
    """Targets in the world, cameras where they really are (docs/conventions.md, section 2)."""
    run, truth = make_run(tmp_path, setup)
    details = write_run_details(tmp_path / "details.json", run)
    X, Y = truth["X"], truth["Y"]
    for j, cam in enumerate(details.cameras):
        assert cam.rot_deg.max() < 1e-6 and cam.trans_m.max() < 1e-9
        T_world_mocap = truth["T_world_mocap"][j]
        if setup == "eye-to-base":   # static cameras, the target moves with the marker
            np.testing.assert_allclose(cam.T_world_cam, X[j], atol=1e-9)
            np.testing.assert_allclose(cam.T_world_target, T_world_mocap @ Y, atol=1e-9)
        else:                        # static target, the cameras move with the body
            ref = truth["T_world_mocap"][0]     # the reference camera's middle image
            shown = ref[len(ref) // 2]
            np.testing.assert_allclose(details.T_world_body_shown, shown, atol=1e-12)
            np.testing.assert_allclose(cam.T_world_cam, shown @ X[j], atol=1e-9)
            np.testing.assert_allclose(cam.T_world_target, np.broadcast_to(Y, (len(cam.names), 4, 4)),
                                       atol=1e-9)
        # the stamps are the camera's, one per used image, in order
        assert len(cam.names) == len(T_world_mocap) and np.all(np.diff(cam.stamps) > 0)


def test_details_residuals_are_the_loop_residuals_of_the_record(tmp_path):
    run, _ = make_run(tmp_path, "eye-to-base", noise=2e-3)
    details = write_run_details(tmp_path / "details.json", run)
    for cam in run.record.cameras:
        p = run.paired[cam.name]
        rot, trans = loop_residuals(p.A, p.B, cam.X, run.record.Y)
        d = details.camera(cam.name)
        np.testing.assert_array_equal(d.rot_deg, rot)
        np.testing.assert_array_equal(d.trans_m, trans)
        assert d.rot_deg.mean() == pytest.approx(cam.residuals.e_R_deg, rel=1e-12)
        assert d.trans_m.max() == pytest.approx(cam.residuals.max_t_m, rel=1e-12)
        assert d.rot_deg.min() > 0
        np.testing.assert_allclose(d.rms_px, 0.1 + 0.01 * np.arange(len(d.names)))


def test_trajectory_is_clipped_to_the_images_and_subsampled(tmp_path):
    run, _ = make_run(tmp_path, "eye-to-base", mocap_per_image=40)
    mocap = run.cameras["cam0"].mocap
    # decoy samples long before and after the calibration (a marker lying on a table)
    early = 100.0 - 50.0 + 0.01 * np.arange(100)
    late = mocap.stamps[-1] + 60.0 + 0.01 * np.arange(100)
    stamps = np.concatenate([early, mocap.stamps, late])
    T = np.concatenate([np.broadcast_to(np.eye(4), (100, 4, 4)), mocap.T,
                        np.broadcast_to(np.eye(4), (100, 4, 4))])
    decoyed = Trajectory(stamps, T, "world", "marker")
    run = dataclasses.replace(run, cameras={n: dataclasses.replace(d, mocap=decoyed)
                                            for n, d in run.cameras.items()})
    details = write_run_details(tmp_path / "d.json", run, max_trajectory_points=25)
    (t,) = details.trajectories
    used = np.concatenate([c.stamps for c in details.cameras])
    lo, hi = used.min() - TRAJECTORY_MARGIN_S, used.max() + TRAJECTORY_MARGIN_S
    inside = (stamps >= lo) & (stamps <= hi)
    assert t.n_samples == inside.sum() == len(mocap.stamps)
    assert len(t.stamps) == 25
    assert t.stamps[0] == stamps[inside][0] and t.stamps[-1] == stamps[inside][-1]
    k = np.searchsorted(stamps, t.stamps)
    np.testing.assert_array_equal(t.positions, T[k, :3, 3])


def test_details_reader_names_file_camera_and_expectation(tmp_path):
    run, _ = make_run(tmp_path, "eye-to-base")
    data = json.loads(json.dumps(run_details_to_dict(write_run_details(tmp_path / "d.json", run))))
    path = tmp_path / "details.json"

    def fails(mutate, message):
        bad = json.loads(json.dumps(data))
        mutate(bad)
        path.write_text(json.dumps(bad))
        with pytest.raises(DatasetError, match=message):
            read_run_details(path)

    fails(lambda d: d.update(format="other"), r"details\.json: not a multieye details file")
    fails(lambda d: d.update(version=99), r"details version 99 is not supported; expected 1")
    fails(lambda d: d["cameras"]["cam0"]["measurements"].pop("rot_deg"),
          r"details\.json: camera cam0: missing key 'rot_deg' in measurements")
    fails(lambda d: d["cameras"]["cam0"]["measurements"]["trans_m"].pop(),
          r"camera cam0: measurements\.trans_m must have shape \(6\), got \(5,\)")
    fails(lambda d: d["cameras"]["front left"].update(trajectory=3),
          r"camera front left: trajectory must be an index into trajectories \(0\.\.0\), got 3")
    fails(lambda d: d["cameras"]["cam0"]["intrinsics"].update(width=-1),
          r"camera cam0: intrinsics\.width must be a positive integer or null, got -1")
    path.write_text("{\n  \"format\": ,\n}")
    with pytest.raises(DatasetError, match=r"details\.json:2: invalid JSON"):
        read_run_details(path)
    assert run_details_from_dict(data, path).camera("cam0").names == tuple(
        o.name for o in run.paired["cam0"].observations)          # the untouched dict is valid


def test_diagnostics_for_an_unknown_camera_are_refused(tmp_path):
    run, _ = make_run(tmp_path, "eye-to-base")
    with pytest.raises(InputError, match="diagnostics given for cameras not in the run: cam9"):
        write_run_details(tmp_path / "d.json", run, diagnostics={"cam9": {"x": 1}})
    with pytest.raises(InputError, match="diagnostics of camera cam0: object is not a JSON value"):
        write_run_details(tmp_path / "d.json", run, diagnostics={"cam0": {"x": object()}})
    assert not (tmp_path / "d.json").exists()


# --------------------------------------------------------------------------- figure helpers


@pytest.mark.parametrize("up", [[0, 0, 1], [0, 0, -1], [0, 1, 0], [0, -3, 0], [1, 0, 0],
                                [-1, 0, 0], [0.2, -0.9, 0.3]])
def test_display_rotation_is_a_rotation_that_puts_up_on_top(up):
    P, labels = display_rotation(up)
    assert np.linalg.det(P) == pytest.approx(1.0)
    np.testing.assert_array_equal(P @ P.T, np.eye(3))
    a = int(np.argmax(np.abs(up)))
    axis = np.zeros(3)
    axis[a] = np.sign(up[a])
    np.testing.assert_array_equal(P @ axis, [0, 0, 1])
    assert labels[2] == ("-" if up[a] < 0 else "") + "xyz"[a]


def test_frustum_corners_project_to_the_image_corners():
    from multieye.core.intrinsics import Intrinsics
    intr = Intrinsics(np.array([[400.0, 0, 300.2], [0, 410.0, 250.7], [0, 0, 1]]), width=640,
                      height=480)
    corners = frustum_corners(intr, 0.3)
    np.testing.assert_allclose(corners[:, 2], 0.3)
    pix = corners @ intr.K.T
    pix = pix[:, :2] / pix[:, 2:]
    np.testing.assert_allclose(pix, [[-0.5, -0.5], [639.5, -0.5], [639.5, 479.5], [-0.5, 479.5]],
                               atol=1e-9)


def test_outliers_flag_only_values_far_above_the_median():
    np.testing.assert_array_equal(outliers([1.0, 1.2, 0.9, 1.1, 3.5, 2.9]),
                                  [False, False, False, False, True, False])
    assert not outliers([0.0, 0.0, 0.0]).any()


# --------------------------------------------------------------------------- report.html


@pytest.fixture(scope="module")
def memory_out(tmp_path_factory):
    """An output folder from an in-memory noisy run, with a warning that needs escaping."""
    out = tmp_path_factory.mktemp("report")
    run, _ = make_run(out, "eye-to-base", noise=1e-3,
                      warnings=("cam0/x.png: corners <b>blurred</b> & dark",))
    write_outputs(run, out)
    write_run_details(out / "details.json", run,
                      diagnostics={n: {"rotation_spread_deg": 10.0 + j, "weak_axis": "z"}
                                   for j, n in enumerate(NAMES)})
    write_report(out)
    return out, run


def test_report_holds_tables_figures_and_reasons(memory_out):
    out, run = memory_out
    text = plain_cells((out / "report.html").read_text())
    figures = embedded_figures(text)
    # in-memory run: no target points, so no per-image figures; the rig first
    assert [n for n, _ in figures] == [n for n in FIGURES if n not in (
        "image_rms.png", "residuals_by_radius.png")]
    for name, png in figures:   # the files are the same figures
        assert (out / "figures" / name).read_bytes() == png
        w, h = _png_size(png)
        assert w > 450 and h > 180
    # the picture before the numbers: rig, then images, then the first table
    assert text.index('id="rig"') < text.index('id="images"') < text.index("<table")
    assert '<a href="#warnings">Warnings</a> <a href="#rig">Rig</a>' in text   # can wrap
    for cam in run.record.cameras:
        assert html.escape(cam.name) in text
        # as the report rounds them: no "-0.000" for a value a hair below zero
        tx, ty, tz, yaw, pitch, roll = (round(v, 4 if k < 3 else 3) + 0.0
                                        for k, v in enumerate(pose_row(cam.T_ref_cam)))
        assert f"<td>{tx:.4f}</td><td>{ty:.4f}</td><td>{tz:.4f}</td>" in text
        assert f"<td>{yaw:.3f}</td><td>{pitch:.3f}</td><td>{roll:.3f}</td>" in text
    assert text.count("target not detected") >= len(NAMES)
    assert "no motion capture" in text and "lonely.png" in text
    assert "corners &lt;b&gt;blurred&lt;/b&gt; &amp; dark" in text and "<b>blurred" not in text
    assert "rotation spread deg" in text and "<td>12</td>" in text
    # self-contained: nothing to fetch, no script, and a policy that forbids both
    assert "<script" not in text
    assert re.findall(r'(?:src|href)="(?!data:image/(?:png|jpeg);base64,|#)', text) == []
    assert "default-src 'none'" in text


def test_report_without_details_shows_what_calibration_json_has(memory_out, tmp_path):
    out, run = memory_out
    (tmp_path / "calibration.json").write_bytes((out / "calibration.json").read_bytes())
    shutil.copytree(out / "figures", tmp_path / "figures")  # an earlier report's figures
    text = plain_cells(write_report(tmp_path).read_text())
    assert [n for n, _ in embedded_figures(text)] == ["rig_3d.png", "rig_top.png"]
    assert sorted(p.name for p in (tmp_path / "figures").iterdir()) == ["rig_3d.png",
                                                                        "rig_top.png"]
    assert "this output folder does not have" in text
    # the weak-motion diagnostics come from calibration.json: shown without details.json too
    motion = run.record.motion_diagnostics[run.record.cameras[1].name]
    assert f"<td>{motion['rotation_range_deg']:.1f}</td>" in text
    assert "No target points: this output folder has no <code>details.json</code>" in text
    assert '<td class="l">given</td><td>500.00</td><td>501.00</td>' in text   # from calibration.json
    assert run.record.cameras[1].name in text and "lonely.png" in text


def test_details_of_another_run_are_left_out_with_a_note(memory_out, tmp_path):
    out, _ = memory_out
    (tmp_path / "calibration.json").write_bytes((out / "calibration.json").read_bytes())
    other, _ = make_run(tmp_path, "eye-to-base", names=("a", "b", "c"))
    write_run_details(tmp_path / "details.json", other)
    text = write_report(tmp_path).read_text()
    assert "details.json left out: it belongs to another run (cameras a, b, c instead of" in text
    assert len(embedded_figures(text)) == 2


def test_write_report_returns_the_page(memory_out):
    out, _ = memory_out
    assert (out / "report.html").stat().st_size > 0
    assert sorted(p.name for p in (out / "figures").iterdir()) == sorted(
        n for n in FIGURES if n not in ("image_rms.png", "residuals_by_radius.png"))


def test_report_needs_calibration_json(tmp_path):
    with pytest.raises(DatasetError, match=r"calibration\.json: calibration file not found"):
        write_report(tmp_path)
    assert not (tmp_path / "report.html").exists()


# --------------------------------------------------------------------------- in a browser


@pytest.fixture(scope="module")
def demo_report(tmp_path_factory):
    """The whole pipeline on a small rendered dataset, then the report."""
    from multieye.pipeline import calibrate
    from multieye.sim.dataset import DatasetSpec, render_dataset

    tmp = tmp_path_factory.mktemp("demo_report")
    spec = DatasetSpec(n_cameras=2, images_per_camera=8, width=640, height=480, processes=1)
    render_dataset(tmp / "dataset", spec, seed=2)
    run = calibrate(tmp / "dataset", processes=1)
    out = tmp / "out"      # not the dataset's folder: the outputs replace their folder whole
    write_outputs(run, out)
    write_run_details(out / "details.json", run,
                      diagnostics={"cam0": {"rotation_spread_deg": 31.2, "weak": False}})
    return write_report(out, images=image_folders(run))


@needs_chromium
def test_demo_report_renders_in_chromium_without_console_messages(demo_report, tmp_path):
    sizes, console = probe(demo_report, tmp_path)
    assert console == []
    figures = embedded_figures(demo_report.read_text())
    names = [n for n, _ in figures]
    assert names[:2] == ["rig_3d.png", "rig_top.png"]            # the rig first
    assert [n for n in names if n.endswith(".jpg")] == [
        f"image_cam{j}_{k}.jpg" for j in range(2) for k in (1, 2, 3)]
    files = [(demo_report.parent / "figures" / n).read_bytes() for n in names]
    assert files == [data for _, data in figures]
    assert [tuple(s[:2]) for s in sizes] == [_image_size(f) for f in files]  # every one decoded
    rgb, console = screenshot(demo_report, tmp_path)
    assert console == []                   # the page itself: no script, nothing blocked
    not_white = (rgb.min(axis=2) < 235).mean()
    colourful = (rgb.max(axis=2) - rgb.min(axis=2) > 80).mean()   # figure and camera colours
    assert not_white > 0.05, not_white
    assert colourful > 0.002, colourful


@needs_chromium
@pytest.mark.parametrize("width", [1280, 390])
def test_demo_report_fits_desktop_and_phone_widths(demo_report, tmp_path, width):
    """No sideways scrolling, figures wide enough to read, the rig before the first table."""
    page, console = layout(demo_report, tmp_path, width)
    assert console == []
    assert page["inner"] == width
    assert page["scroll"] <= page["inner"], page["scroll"]
    images = page["images"]
    assert len(images) == len(embedded_figures(demo_report.read_text()))
    for shown, _, natural, section in images:
        if section == "images":                        # the drawn images, several per row
            assert shown >= min(280, natural), (shown, natural)
        elif width < 500:                              # a phone: every figure full width
            assert shown >= min(350, natural) and shown >= page["main"] - 30, (shown, section)
        else:
            assert shown >= min(450, natural), (shown, section)
    rig_top = min(top for _, top, _, section in images if section == "rig")
    assert page["tables"] and rig_top < min(top for _, top in page["tables"])
    for table_width, _ in page["tables"]:
        assert table_width <= page["main"] + 0.5
    shot = tmp_path / f"report_{width}.png"
    assert screenshot_at(demo_report, shot, tmp_path, width, 2400) == []
    from PIL import Image

    with Image.open(shot) as im:
        assert im.size == (width, 2400)
    keep = os.environ.get("MULTIEYE_KEEP_SCREENSHOTS")
    if keep:                                           # for people who want to look at them
        shutil.copy(shot, Path(keep) / shot.name)


@needs_chromium
def test_browser_check_sees_script_errors_blocked_loads_and_broken_images(tmp_path):
    """The same checks on a page that is broken on purpose, so that they can fail."""
    page = tmp_path / "broken.html"
    page.write_text(
        "<!DOCTYPE html><html><head><meta charset=\"utf-8\"><meta http-equiv=\"Content-Security-"
        "Policy\" content=\"default-src 'none'; img-src data:; style-src 'unsafe-inline'\">"
        "</head><body><img src=\"data:image/png;base64,AAAA\"><img src=\"figures/none.png\">"
        "</body></html>")
    sizes, console = probe(page, tmp_path)
    assert [s[:2] for s in sizes] == [[0, 0], [0, 0]]
    assert any("violates the following Content Security Policy" in ln for ln in console)
    thrown = tmp_path / "thrown.html"
    thrown.write_text("<html><body><p>x</p><script>throw new Error('boom')</script></body></html>")
    _, console = chromium(thrown, tmp_path, "--dump-dom")
    assert any("Uncaught Error: boom" in ln for ln in console)
