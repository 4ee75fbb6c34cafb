"""Where the data was: details.json's target points, residuals and lens uncertainty from a real
pipeline run, and the report's per-camera section and weak-motion diagnostics.

A small rendered dataset (2 cameras x 8 images, 640 x 480, tests/small_dataset.py) is
calibrated twice: with the intrinsics files it comes with (given, held fixed) and with
``model: pinhole-radtan`` instead (estimated with the rig).
"""

from __future__ import annotations

import dataclasses
import json
import re
import subprocess
import sys

import numpy as np
import pytest

from multieye.core import geometry as g
from multieye.core.lens import project_points, undistort_points
from multieye.io.calibration_record import CameraRecord
from multieye.io.run_details import read_run_details
from multieye.io.calibration_json import read_calibration
from multieye.outputs import figures as f
from multieye.outputs.details import image_points, projection_std_grid
from multieye.outputs.folder import foreign_files
from multieye.outputs.image_stats import (
    ImageFrame,
    arrow_scale,
    coverage,
    image_frame,
    mean_vectors,
    position_bins,
    radial_bins,
    stacked,
)
from multieye.outputs.report import load_details, write_report
from multieye.outputs import figure_workers
from multieye.outputs.figures_rig import rig_pngs
from multieye.outputs.report_draw import figure_jobs
from multieye.outputs.report_cameras import camera_figure_names
from multieye.outputs.report_images import image_folders
from multieye.outputs.write import write_outputs
from multieye.pipeline import calibrate, calibrate_rig
from small_dataset import render_small

from browser import embedded_figures, needs_chromium, plain_cells, probe


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """``{"given": (run, OUT), "model": (run, OUT)}`` on one rendered dataset."""
    tmp = tmp_path_factory.mktemp("where")
    render_small(tmp / "dataset")
    text = (tmp / "dataset" / "rig.yaml").read_text()
    (tmp / "dataset" / "rig_model.yaml").write_text(
        re.sub(r"intrinsics: (cam\d)\.yaml", "model: pinhole-radtan", text))
    out = {}
    for kind, rig in (("given", "rig.yaml"), ("model", "rig_model.yaml")):
        run = calibrate(tmp / "dataset" / rig, processes=1)
        write_outputs(run, tmp / kind)
        out[kind] = (run, tmp / kind)
    return out


# --------------------------------------------------------------------------- details.json


@pytest.mark.parametrize("kind", ["given", "model"])
def test_points_are_the_refined_rigs_residuals(runs, kind):
    run, out = runs[kind]
    details = read_run_details(out / "details.json")
    res = run.refinement.result
    for j, name in enumerate(run.paired):
        cam = details.camera(name)
        obs = run.paired[name].observations
        p = cam.points
        assert (p.source, p.image_size) == ("refined", (640, 480))
        assert p.n_points == p.kept == sum(len(o.image_points) for o in obs) == 8 * 54
        np.testing.assert_allclose(p.rms_px, res.image_rms_px[j], rtol=0, atol=5.1e-5)
        for i in (0, len(obs) - 1):          # a point projected independently
            T = g.inv(res.X[j]) @ res.T_world_mocap[j][i] @ res.Y   # eye-to-base
            P = obs[i].object_points @ T[:3, :3].T + T[:3, 3]
            expected = project_points(P, run.cameras[name].intrinsics) - obs[i].image_points
            np.testing.assert_allclose(p.residual_px[i], expected, atol=6e-4)
            np.testing.assert_allclose(p.uv[i], obs[i].image_points, atol=6e-3)
        every = np.concatenate(p.residual_px)
        assert np.sqrt(np.mean(np.sum(every ** 2, axis=1))) == pytest.approx(
            run.record.camera(name).residuals.reprojection_rms_px, rel=1e-3)


def test_given_intrinsics_have_no_covariance_and_estimated_ones_do(runs):
    for name in ("cam0", "cam1"):
        given = read_run_details(runs["given"][1] / "details.json").camera(name)
        assert given.intrinsics_estimated is False
        assert given.intrinsics_covariance is None and given.projection_std is None
        run, out = runs["model"]
        cam = read_run_details(out / "details.json").camera(name)
        assert cam.intrinsics_estimated is True
        np.testing.assert_array_equal(cam.intrinsics_covariance,
                                      run.refinement.intrinsics_covariance[name])
        np.testing.assert_array_equal(cam.intrinsics.params, run.cameras[name].intrinsics.params)
        s = cam.projection_std
        assert s.std_px.shape == (24, 32)
        centre = s.std_px[10:14, 14:18]
        assert np.all(np.isfinite(centre)) and 0 < centre.max() < 1.0   # where the board was
        assert s.max_px > 5 * centre.max()                              # extrapolated corners
        assert s.mean_px < s.max_px


def test_projection_std_is_the_propagated_covariance(runs):
    """sqrt(tr(J C J^T) / 2) with J by finite differences of the projection of a fixed ray."""
    run, _ = runs["model"]
    intr = run.cameras["cam1"].intrinsics
    cov = run.refinement.intrinsics_covariance["cam1"]
    grid = projection_std_grid(intr, cov, columns=8)
    assert grid.std_px.shape == (6, 8)
    i, k = 1, 5
    ray = np.append(undistort_points([[grid.u[k], grid.v[i]]], intr)[0], 1.0)
    J = np.zeros((2, intr.params.size))
    for n in range(intr.params.size):
        h = 1e-6 * max(1.0, abs(intr.params[n]))
        up, down = intr.params.copy(), intr.params.copy()
        up[n] += h
        down[n] -= h
        J[:, n] = (project_points(ray[None], intr.with_params(up))[0]
                   - project_points(ray[None], intr.with_params(down))[0]) / (2 * h)
    assert grid.std_px[i, k] == pytest.approx(np.sqrt(np.trace(J @ cov @ J.T) / 2), rel=1e-4)
    # a diagonal covariance of the principal point only: exactly its standard deviation
    only_c = np.zeros_like(cov)
    only_c[2, 2] = only_c[3, 3] = 0.25
    np.testing.assert_allclose(projection_std_grid(intr, only_c, columns=4).std_px, 0.5,
                               rtol=1e-9)


def test_without_image_refinement_the_residuals_are_pnp(runs):
    run, _ = runs["given"]
    plain = calibrate_rig(run.rig, run.cameras, refine=False)
    for name, paired in plain.paired.items():
        p = image_points(plain, name)
        assert p.source == "pnp"
        np.testing.assert_allclose(p.rms_px, [o.rms_px for o in paired.observations], rtol=1e-9)


def test_points_are_subsampled_evenly_and_the_rms_counts_them_all(runs):
    run, _ = runs["given"]
    full = image_points(run, "cam0")
    part = image_points(run, "cam0", max_points=100)
    assert part.kept == 100 and part.n_points == full.n_points == 432
    assert [len(u) for u in part.uv] == [13, 12, 13, 12, 12, 13, 12, 13]
    np.testing.assert_array_equal(part.rms_px, full.rms_px)
    for u, v, r, s in zip(part.uv, full.uv, part.residual_px, full.residual_px):
        rows = [int(np.flatnonzero(np.all(v == x, axis=1))[0]) for x in u]
        np.testing.assert_array_equal(s[rows], r)


def test_the_residuals_are_each_images_own_projection(runs):
    """All images' points are projected at once: the same numbers as image by image."""
    run, _ = runs["given"]
    res, j = run.refinement.result, list(run.paired).index("cam1")
    p = image_points(run, "cam1")
    for i, o in enumerate(run.paired["cam1"].observations):
        T = g.inv(res.X[j]) @ res.T_world_mocap[j][i] @ res.Y
        own = project_points(o.object_points @ T[:3, :3].T + T[:3, 3],
                             res.intrinsics[j]) - o.image_points
        np.testing.assert_array_equal(p.residual_px[i], own)
        assert p.rms_px[i] == np.sqrt(np.nanmean(np.sum(own ** 2, axis=1)))


def test_details_json_stays_small(runs):
    for kind in ("given", "model"):
        out = runs[kind][1]
        size = (out / "details.json").stat().st_size
        assert size < 150_000, size                           # 2 x 432 points
        data = json.loads((out / "details.json").read_text())
        assert data["cameras"]["cam0"]["points"]["uv"][0][0] == [
            round(v, 2) for v in runs[kind][0].paired["cam0"].observations[0].image_points[0]]


# --------------------------------------------------------------------------- report.html


@pytest.mark.parametrize("kind", ["given", "model"])
def test_report_shows_every_camera_and_the_diagnostics(runs, kind):
    run, out = runs[kind]
    text = plain_cells((out / "report.html").read_text())
    assert '<section id="cameras"><h2>Cameras: intrinsics and where the target was seen' in text
    figures = embedded_figures(text)
    assert [n for n, _ in figures] == [        # page order
        "rig_3d.png", "rig_top.png", *(f"image_cam{j}_{k}.jpg" for j in (0, 1) for k in (1, 2, 3)),
        "residual_histograms.png", "residuals_over_time.png", "image_rms.png",
        "residuals_by_radius.png", "camera_cam0.png", "camera_cam1.png"]
    for name, data in figures:
        assert (out / "figures" / name).read_bytes() == data
    details = read_run_details(out / "details.json")
    for name in ("cam0", "cam1"):
        cam = details.camera(name)
        fx, fy = cam.intrinsics.params[:2]
        row = "estimated" if kind == "model" else "given"
        assert f'<td class="l">{row}</td><td>{fx:.2f}</td><td>{fy:.2f}</td>' in text
        worst = cam.names[int(np.nanargmax(cam.points.rms_px))]
        order = [cam.names[i] for i in np.argsort(-cam.points.rms_px)[:3]]   # worst first
        shown = re.findall(rf"<b>([^<]+)</b>: RMS [0-9.]+ px over \d+ points; residuals × "
                           rf"[0-9.e+]+ <span class=\"note\">\(also <code>figures/image_{name}_"
                           r"\d\.jpg", text)
        assert shown == order
        assert f"<td class=\"l\">{worst}</td><td>{np.nanmax(cam.points.rms_px):.3f}</td>" in text
        motion = run.record.motion_diagnostics[name]
        assert f"<td>{motion['rotation_range_deg']:.1f}</td>" in text
        assert f"<td>{motion['rotation_condition']:.3g}</td>" in text
        if kind == "model":
            sigma = np.sqrt(np.diag(cam.intrinsics_covariance))
            assert f'<td class="l">σ</td><td>{sigma[0]:.3f}</td><td>{sigma[1]:.3f}</td>' in text
            assert (f"over the image: mean {cam.projection_std.mean_px:.3g} px, max "
                    f"{cam.projection_std.max_px:.3g} px") in text
            at = run.record.camera(name).intrinsics.projection_std_px
            assert f"at the observed target points: mean {at[0]:.3g} px" in text
    if kind == "given":
        assert text.count("given in rig.yaml and held fixed") == 2
    assert "Not available" not in text
    assert '<a href="#cameras">Cameras</a>' in text


@needs_chromium
def test_report_with_estimated_intrinsics_renders_without_console_messages(runs, tmp_path):
    report = runs["model"][1] / "report.html"
    sizes, console = probe(report, tmp_path)
    assert console == []
    assert len(sizes) == 14 and all(w > 450 and h > 180 for w, h, _ in sizes[:2] + sizes[8:])
    assert all(w > 150 and h > 100 for w, h, _ in sizes[2:8])          # the drawn images


@pytest.mark.parametrize("kind", ["given", "model"])
def test_the_report_of_a_run_is_the_report_of_its_files(runs, tmp_path, kind):
    """``write_outputs`` makes the report from the record and details in memory; made again
    from calibration.json and details.json alone (``multieye report``, with the same image
    folders) it is the same page and the same figure bytes: nothing differs from the files."""
    run, src = runs[kind]
    out = tmp_path / "out"
    out.mkdir()
    for name in ("calibration.json", "details.json"):
        (out / name).write_bytes((src / name).read_bytes())
    write_report(out, shown_as=src, images=image_folders(run))
    assert (out / "report.html").read_text() == (src / "report.html").read_text()
    figures = {p.name: p.read_bytes() for p in (src / "figures").iterdir()}
    assert len(figures) >= 10
    assert {p.name: p.read_bytes() for p in (out / "figures").iterdir()} == figures


def test_camera_figures_of_an_earlier_report_are_removed(runs, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    for name in ("calibration.json", "details.json"):
        (out / name).write_bytes((runs["given"][1] / name).read_bytes())
    (out / "figures").mkdir()
    (out / "figures" / "camera_gone.png").write_bytes(b"old")
    (out / "figures" / "notes.txt").write_text("mine")
    (out / "figures" / "rig.png").write_bytes(b"old")                # an earlier version's
    (out / "figures" / "image_gone_1.jpg").write_bytes(b"old")
    write_report(out)
    assert sorted(p.name for p in (out / "figures").iterdir()) == [
        "camera_cam0.png", "camera_cam1.png", "image_rms.png", "notes.txt",
        "residual_histograms.png", "residuals_by_radius.png", "residuals_over_time.png",
        "rig_3d.png", "rig_top.png"]
    # a folder whose manifest predates the per-camera figures may still be replaced
    assert foreign_files(out) == ["figures/notes.txt"]


# --------------------------------------------------------------------------- helpers


def test_camera_figure_names_are_safe_and_distinct():
    cameras = [CameraRecord(n, None, np.eye(4), 3)
               for n in ("cam0", "front left", "front_left", "a/b", "rear<&>")]
    assert camera_figure_names(cameras) == {
        "cam0": "camera_cam0.png", "front left": "camera_front_left.png",
        "front_left": "camera_front_left_2.png", "a/b": "camera_a_b.png",
        "rear<&>": "camera_rear___.png"}


def test_image_statistics():
    frame = ImageFrame(640, 480, True, 320.0, 240.0)
    uv = np.array([[10.0, 10], [630, 470], [320, 240], [321, 241], [322, 242]])
    res = np.array([[0.3, 0.4], [0.0, 1.0], [0.1, 0.0], [0.0, 0.1], [0.1, 0.0]])
    assert coverage(uv, frame) == 3 / 16
    edges, rms, med, count = radial_bins(uv, res, frame, bins=4)
    assert edges[-1] == pytest.approx(np.hypot(320.5, 240.5))
    assert count.tolist() == [3, 0, 0, 2]
    assert rms[0] == pytest.approx(0.1) and np.isnan(rms[1])
    assert rms[3] == pytest.approx(np.sqrt((0.25 + 1.0) / 2))
    cells, n = position_bins(uv, res, frame, columns=4, min_points=1)
    assert cells.shape == (3, 4) and n.sum() == 5 and n[1, 2] == 3
    assert cells[0, 0] == pytest.approx(0.5) and np.isnan(cells[0, 1])
    at, mean, n = mean_vectors(uv, res, frame, columns=4, min_points=2)
    np.testing.assert_allclose(at, [[399.5, 239.5]])           # the one cell with 3 points
    np.testing.assert_allclose(mean, [[0.2 / 3, 0.1 / 3]])
    assert n.tolist() == [3]
    key, magnify = arrow_scale(res, frame)
    assert key == 1.0 and magnify == pytest.approx(0.06 * 640)
    assert arrow_scale(res * 0.03, frame)[0] == 0.02


def test_eye_on_hand_points_are_the_refined_rigs_residuals(tmp_path):
    """inv(X) @ inv(M_i) @ Y: the refined rig's residuals in the other setup too."""
    from multieye.io import Rig, Trajectory
    from multieye.pipeline import CameraData, Observation
    from multieye.sim.images import simulate_images

    sc = simulate_images(7, n_cameras=2, images=6, setup="eye-on-hand")
    stamps, poses, cameras = [], [], {}
    for j in range(2):
        t = 100.0 + 10 * j + 0.5 * np.arange(6)
        stamps.append(t)
        poses.append(sc.mocap[j])
        obs = tuple(Observation(name=f"{ti:.1f}.png", stamp=float(ti), T_cam_target=T,
                                rms_px=0.3, object_points=sc.object_points, image_points=u)
                    for ti, T, u in zip(t, sc.T_cam_target[j], sc.image_points[j]))
        cameras[f"cam{j}"] = (obs, sc.intrinsics[j])
    mocap = Trajectory(np.concatenate(stamps), np.concatenate(poses), "world", "body")
    data = {n: CameraData(name=n, intrinsics=intr, observations=obs, rejected=(), n_inputs=6,
                          mocap=mocap, time_offset=0.0, time_tolerance=0.01)
            for n, (obs, intr) in cameras.items()}
    run = calibrate_rig(Rig(path=tmp_path / "rig.yaml", setup="eye-on-hand", cameras={}), data)
    assert run.refinement.kind == "images"
    for j, name in enumerate(run.paired):
        p = image_points(run, name)
        assert p.source == "refined"
        np.testing.assert_allclose(p.rms_px, run.refinement.result.image_rms_px[j], rtol=1e-9)
        assert 0.2 < np.nanmedian(p.rms_px) < 0.6                    # 0.3 px per coordinate


@pytest.mark.skipif(figure_workers.worker_count(2) == 0, reason="figure workers need two cores")
def test_figures_drawn_by_a_worker_are_the_same(runs, tmp_path, monkeypatch):
    """Workers or this process: the same figures, the same page (the cameras' figures drawn
    on one figure reused, in one batch per worker)."""
    monkeypatch.setattr(figure_workers, "_free_core", lambda: True)    # whatever the load
    sizes = []
    real_pool = figure_workers.worker_pool

    def counted(size, **kwargs):
        sizes.append(size)
        return real_pool(size, **kwargs)
    monkeypatch.setattr(figure_workers, "worker_pool", counted)
    src = runs["model"][1]
    rec = read_calibration(src / "calibration.json")
    details, _ = load_details(src, rec)
    assert sum(job[1] is f.camera_png for job in figure_jobs(rec, details)) >= 2
    pages = {}
    for processes in (1, 2):
        out = tmp_path / f"p{processes}" / "out"
        out.mkdir(parents=True)
        for name in ("calibration.json", "details.json"):
            (out / name).write_bytes((src / name).read_bytes())
        page = write_report(out, processes=processes)
        pages[processes] = (page.read_text().replace(str(out), "OUT"),
                            {p.name: p.read_bytes() for p in (out / "figures").iterdir()})
    assert sizes == [2]                 # two workers drew with processes=2, none with 1
    assert pages[1] == pages[2]


@pytest.mark.parametrize("free, processes", [(False, 2), (False, None), (True, 1)])
def test_no_figure_worker_on_a_busy_machine_or_with_one_process(monkeypatch, free, processes):
    """No core free (the refinement would lose a share of its core, and a worker only adds
    its imports) or ``processes=1``: no worker starts, early or late; this process draws."""
    monkeypatch.setattr(figure_workers, "_free_core", lambda: free)
    with figure_workers.figure_workers(processes) as workers:
        workers.start_early()
        workers.start()
        assert workers.pool is None and workers.size == 0


def test_no_figure_worker_late_when_none_could_start_early(monkeypatch):
    """A machine busy when the detection ended and free when the figures are handed over:
    still no worker (each would import matplotlib itself beside this process's writing,
    instead of the fork server once); without the early start, a free core at the outputs
    starts them."""
    answers = iter([False, True])
    monkeypatch.setattr(figure_workers, "_free_core", lambda: next(answers))
    with figure_workers.figure_workers(2) as workers:
        workers.start_early()
        workers.start()
        assert workers.pool is None and workers.size == 0
    if figure_workers.worker_count(2) == 0:
        return                          # one core: never a worker
    monkeypatch.setattr(figure_workers, "_free_core", lambda: True)
    with figure_workers.figure_workers(2) as workers:
        workers.start()
        assert workers.size == 2


def test_camera_figures_drawn_on_one_figure_are_the_same_as_alone(runs):
    """A camera's figure drawn after another's on the figure reused is the figure drawn
    alone: nothing of the camera before is left."""
    src = runs["model"][1]
    rec = read_calibration(src / "calibration.json")
    details, _ = load_details(src, rec)
    cams = [details.camera(c.name) for c in rec.cameras]
    colours = f.camera_colours(len(cams))
    alone = []
    for c, col in zip(cams, colours):
        f._camera_canvas.cache_clear()          # a figure of its own
        alone.append(f.camera_png(c, col))
    assert len(set(alone)) == len(cams)
    assert f.camera_pngs(cams[::-1], colours[::-1]) == alone[::-1]
    assert [f.camera_png(c, col) for c, col in zip(cams, colours)] == alone


# --------------------------------------------------------------------------- what is drawn


def _drawn(monkeypatch) -> list:
    """The matplotlib figures that the figure functions encode next, in order."""
    from multieye.outputs import figures_rig

    figs, encode = [], f._png

    def keep(fig):
        figs.append(fig)
        return encode(fig)
    monkeypatch.setattr(f, "_png", keep)
    monkeypatch.setattr(figures_rig, "_png", keep)
    return figs


def _texts(fig) -> list[str]:
    """Every visible text of a figure: titles, labels, tick labels, annotations, legends."""
    from matplotlib.quiver import QuiverKey
    from matplotlib.text import Text

    texts = [*fig.findobj(Text), *(key.text for key in fig.findobj(QuiverKey))]
    return [t.get_text() for t in texts if t.get_visible() and t.get_text()]


def test_figures_carry_their_statistics_and_labels(runs, monkeypatch):
    """Cheaper figures (fewer ticks, text without hinting, one canvas for the cameras) still
    say the same: per camera its name in its colour and its statistics, the axis labels, the
    numbered worst images, the colour bar's label, the rig's camera labels."""
    import matplotlib

    src = runs["model"][1]
    rec = read_calibration(src / "calibration.json")
    details, _ = load_details(src, rec)
    colours = f.camera_colours(len(details.cameras))
    figs = _drawn(monkeypatch)
    hinting = matplotlib.rcParams["text.hinting"]
    f.residual_histograms_png(details)
    f.residuals_over_time_png(details)
    f.image_rms_png(details)
    f.radial_png(details)
    assert matplotlib.rcParams["text.hinting"] == hinting       # set while drawing only
    hist, over_time, rms, radial = (_texts(fig) for fig in figs)
    for cam, colour in zip(details.cameras, colours):
        for values, unit in ((cam.rot_deg, "°"), (cam.trans_m * 1e3, " mm")):
            stats = (f"n={values.size}  median {np.median(values):.3g}{unit}  mean "
                     f"{np.mean(values):.3g}{unit}  max {np.max(values):.3g}{unit}")
            assert stats in hist
        for fig in figs[:3]:          # the lanes' names, in the cameras' colours
            names = [t for t in fig.axes[0].texts if t.get_text() == cam.name]
            assert len(names) == 1 and names[0].get_color() == colour
            assert names[0].get_fontweight() == "bold"
        assert cam.name in radial                                  # the legend
    for title in ("rotation residual (deg): histogram per camera",
                  "translation residual (mm): histogram per camera"):
        assert title in hist
    hi = max(float(np.max(c.rot_deg)) for c in details.cameras)
    assert (f"time since the camera's first used image (s); full lane = {hi:.3g}°"
            in over_time)
    assert rms.count("1") >= len(details.cameras) and "3" in rms      # worst, numbered
    assert "RMS residual (px)" in radial
    for fig in figs[:2]:          # ticks across: at most 6 in view, numbers at round steps
        for ax in fig.axes:
            lo, hi = ax.get_xlim()
            shown = [x for x in ax.get_xticks() if lo <= x <= hi]
            assert 3 <= len(shown) <= 6, shown
    figs.clear()
    cam = details.cameras[0]
    f.camera_png(cam, colours[0])
    texts = _texts(figs[0])
    _, res = stacked(cam)
    rms_px = float(np.sqrt(np.nanmean(np.sum(res ** 2, axis=1))))
    assert cam.name in texts
    assert any(f"RMS {rms_px:.3f} px" in t for t in texts)
    assert any("px (arrows ×" in t for t in texts)                 # the arrows' key
    assert "σ (px)" in texts                                        # the colour bar's label
    figs.clear()
    rig = rig_pngs(rec, details)
    assert len(figs) == 2 and sorted(rig.pngs) == ["rig_3d.png", "rig_top.png"]
    for fig in figs:
        texts = _texts(fig)
        for c in rec.cameras:
            assert any(t.startswith(c.name) for t in texts)
        assert sum(t.endswith("(m)") for t in texts) >= 2           # the axes' names


def test_log_colour_bar_ticks_are_plain_numbers(runs, monkeypatch):
    """A projection σ spanning decades is drawn on a log scale whose ticks are numbers at
    1, 2 and 5 times a power of ten, without mathtext (``10^k``) or minor ticks."""
    src = runs["model"][1]
    rec = read_calibration(src / "calibration.json")
    details, _ = load_details(src, rec)
    cam = details.cameras[0]
    ps = cam.projection_std
    spread = np.geomspace(0.05, 30.0, ps.std_px.size).reshape(ps.std_px.shape)
    cam = dataclasses.replace(cam, projection_std=dataclasses.replace(ps, std_px=spread))
    figs = _drawn(monkeypatch)
    f.camera_png(cam)
    bar = figs[0].axes[-1]                                          # the colour bar's axes
    assert bar.get_yscale() == "log"
    lo, hi = sorted(bar.get_ylim())
    ticks = [(x, t.get_text()) for x, t in zip(bar.get_yticks(), bar.get_yticklabels())
             if lo <= x <= hi]
    assert len(ticks) >= 5
    for x, text in ticks:
        assert "$" not in text and float(text) == pytest.approx(x)
        assert round(x / 10 ** np.floor(np.log10(x)), 6) in (1.0, 2.0, 5.0)
    assert {1.0, 10.0} <= {x for x, _ in ticks}
    assert len(bar.yaxis.get_minorticklocs()) == 0
    # the figure reused by a camera drawn next, on a linear scale: as if drawn alone
    linear = dataclasses.replace(details.cameras[1], projection_std=None)
    frames = [image_frame(c) for c in (cam, linear)]
    assert {(fr.width, fr.height) for fr in frames} == {(frames[0].width, frames[0].height)}
    after_log = f.camera_png(linear)
    assert figs[-1].axes[-1].get_yscale() == "linear"
    f._camera_canvas.cache_clear()
    assert f.camera_png(linear) == after_log


def test_warm_up_loads_matplotlib_and_freezes_what_it_made():
    """After :func:`~multieye.outputs.figures_rig.warm_up` the figure modules' imports are
    done and the objects made so far are out of the garbage collector's full collections
    (what a figure worker forked after it inherits)."""
    code = ("import gc, sys\nfrom multieye.outputs.figures_rig import warm_up\n"
            "before = gc.get_freeze_count()\nwarm_up()\n"
            "print(before, gc.get_freeze_count(), 'matplotlib.figure' in sys.modules, "
            "'mpl_toolkits.mplot3d' in sys.modules)")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr
    before, after, figure, axes3d = run.stdout.split()
    assert int(before) == 0 and int(after) > 10_000
    assert figure == axes3d == "True"


def test_wide_lens_rows_and_projection_grid():
    """The report's lens line and table name a wide-angle model and its parameters; the
    projection's standard deviation covers the rays beyond 90 degrees a wide lens sees."""
    from multieye.core.intrinsics import Intrinsics
    from multieye.outputs.report_cameras import _lens_note, intrinsics_table

    lens = Intrinsics(K=[[250.0, 0, 320], [0, 250.0, 240], [0, 0, 1]], dist=[0.3, 0.6],
                      model="double-sphere", width=640, height=480)
    html = intrinsics_table(lens, True, np.diag([1.0, 1.0, 0.5, 0.5, 1e-4, 1e-4]))
    assert re.search(r">xi<.*>alpha<", html)
    assert "0.30000" in html and "0.60000" in html
    assert _lens_note(None, None, lens, False, None).startswith("Lens double-sphere, 640 x 480")
    grid = projection_std_grid(lens, np.diag([1.0, 1.0, 0.5, 0.5, 1e-4, 1e-4]), columns=16)
    corner = grid.std_px[0, 0]               # its ray is beyond 90 degrees: not NaN any more
    assert np.isfinite(corner) and corner > 0


def test_report_table_shows_small_lens_parameters_not_as_zero():
    """The report's lens table: a parameter below 1e-3 (EUCM beta near 0, a small p2) in
    significant digits, not 0.00000 as if it were absent (issue 33, item 1)."""
    from multieye.core.intrinsics import Intrinsics
    from multieye.outputs.report_cameras import intrinsics_table

    K = [[300.5, 0, 320], [0, 300.25, 240], [0, 0, 1]]
    html = intrinsics_table(Intrinsics(K, [0.6, 1e-12], "eucm", 640, 480), False, None)
    assert "1.000e-12" in html and "0.60000" in html
    html = intrinsics_table(Intrinsics(K, [-0.2, 0.05, 1e-3, -2e-4], "pinhole"), False, None)
    assert "-2.000e-04" in html and "-0.20000" in html and "0.00100" in html
