"""multieye: calibration of multi-camera rigs from a target tracked by motion capture or a robot,
or seen by cameras that overlap.

Every command is a thin layer over a library function a Python user can call directly.
Errors the user can fix (bad files, weak motion) print one line on stderr and exit with
status 2; a result exits with 0, or with 3 when a plausibility check doubts it (written all
the same, the cause named on stderr).  Heavy modules are imported inside the commands so that
``--help`` stays instant.
"""

from __future__ import annotations

import contextlib
import functools
import os
import signal
import sys
import threading
from pathlib import Path

import click

from multieye.core.collector import fewer_collections
from multieye.core.cpus import one_blas_thread
from multieye.core.version import __version__
from multieye.core.errors import CalibrationError
from multieye.core.errors import DatasetError
import textwrap
from importlib import import_module
from importlib.resources import files

EXIT_USER_ERROR = 2
#: The result is written, but a plausibility check doubts it (docs/conventions.md, section 8).
EXIT_IMPLAUSIBLE = 3


class Stopped(KeyboardInterrupt):
    """Raised by SIGTERM or SIGHUP, so that the work unwinds as on Ctrl-C: worker processes
    end and ``finally`` blocks remove temporary folders (docs/outputs.md, section 1)."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def _stop(signum, frame):
    raise Stopped(signum)


def _stop_on_signals() -> dict:
    """Install :func:`_stop` for SIGTERM and SIGHUP, and ignore SIGXFSZ (a write over the
    file-size limit is then an OSError naming the file, not a dead process); returns the
    handlers it replaced."""
    if threading.current_thread() is not threading.main_thread():   # handlers live there
        return {}
    previous = {sig: signal.signal(sig, _stop) for sig in
                (getattr(signal, n) for n in ("SIGTERM", "SIGHUP") if hasattr(signal, n))}
    if hasattr(signal, "SIGXFSZ"):
        previous[signal.SIGXFSZ] = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    return previous


def _shown(text: str) -> str:
    """``text`` for the terminal: bytes that were not UTF-8 in a path or a name (kept as
    surrogates, ``surrogateescape``) shown as U+FFFD instead of failing to print."""
    return text.encode("utf-8", "surrogateescape").decode("utf-8", "replace")


def _echo(text: str, err: bool = False) -> None:
    click.echo(_shown(text), err=err)


def _utf8_dataset(dataset: Path) -> None:
    """Refuse a dataset path with bytes that are not UTF-8: OpenCV, which opens the images and
    the FileStorage intrinsics by name, crashes on such a name (a segmentation fault)."""

    full = os.path.abspath(dataset)
    try:
        os.fsencode(full).decode("utf-8")
    except UnicodeDecodeError:
        raise DatasetError("the path holds bytes that are not UTF-8, which OpenCV cannot open: "
                           "rename the folder (or run from a folder whose path is UTF-8)",
                           path=full) from None


def _user_errors(fn):
    """Turn CalibrationError (and unreadable files) into one line on stderr and exit 2;
    SIGINT, SIGTERM and SIGHUP into one line and exit 128 + the signal number."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        previous = _stop_on_signals()
        try:
            return fn(*args, **kwargs)
        except KeyboardInterrupt as exc:
            signum = getattr(exc, "signum", signal.SIGINT)
            click.echo(f"multieye: stopped by {signal.Signals(signum).name}", err=True)
            sys.exit(128 + signum)
        except CalibrationError as exc:
            _echo(f"multieye: error: {exc}", err=True)
            sys.exit(EXIT_USER_ERROR)
        except OSError as exc:   # missing, unreadable or unwritable paths the user gave
            name = getattr(exc, "filename", None)
            if isinstance(name, (str, bytes)) and name:
                where = f"{os.fsdecode(name)}: "
            else:               # no file named (the file-size limit on a descriptor, ...)
                where = f"{name}: " if name not in (None, "") else ""
            _echo(f"multieye: error: {where}{exc.strerror or exc}", err=True)
            sys.exit(EXIT_USER_ERROR)
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, signal.SIG_DFL if handler is None else handler)

    return wrapper


def _number_or_word(text: str) -> str | float:
    """``--time-offset``'s text as Options takes it: a number of seconds where it reads as
    one, else the word (``rig``, ``auto``, or what Options then refuses)."""
    try:
        return float(text)
    except ValueError:
        return text


def _progress_enabled() -> bool:
    return sys.stderr.isatty()


def _processes_note(processes: int | None) -> None:
    """A note when ``--processes`` asks for more workers than this process has CPUs (the
    detection starts at most that many, and at most one per image)."""
    if processes is None:
        return
    from multieye.imaging.batch import worker_count  # noqa: PLC0415 (heavy: OpenCV; instant start-up of multieye --help)

    used = worker_count(processes)
    if used < processes:
        click.echo(f"note: --processes {processes}: at most {used} detection process(es), "
                   f"the CPUs this process may use (and at most one per image)")


def _import_writers(report: bool = True) -> None:
    """The output writers imported (on a thread, while the workers detect the images); the
    report's figure modules only where the report is written."""
    for name in ("multieye.outputs.write", "multieye.outputs.summary",
                 "multieye.outputs.report_draw")[:None if report else 2]:
        import_module(name)


def _prestart_workers(processes: int | None, report: bool = True) -> None:
    """The detection's fork server started before this process imports numpy, OpenCV and the
    pipeline, so that the server's own imports of them run on the other core meanwhile
    (issue 21); it imports the figure modules once the detection is done, for both figure
    workers (:mod:`multieye.outputs.figure_workers`)."""
    from multieye.imaging.workers import prestart_workers  # noqa: PLC0415 (instant start-up of multieye --help; no OpenCV: the server imports it first)
    from multieye.outputs.figure_workers import PRELOAD  # noqa: PLC0415 (instant start-up of multieye --help; light: no numpy)

    prestart_workers(processes, preload=(PRELOAD,) if report else ())


#: What each exit status means (docs/conventions.md, section 8).
_EXIT_MEANINGS = {
    0: "success",
    EXIT_USER_ERROR: "bad input or a run that cannot succeed: one line on stderr, nothing "
                     "written",
    EXIT_IMPLAUSIBLE: "result written, but a plausibility check doubts it (the cause on "
                      "stderr and in calibration.json's warnings)",
}


def _exit_statuses(*codes: int, meanings: dict | None = None) -> str:
    """The ``Exit status`` epilog of a command's ``--help``: ``codes`` and their meaning,
    then the signal statuses every command shares."""

    meanings = {**_EXIT_MEANINGS, **(meanings or {})}
    rows = [(str(code), meanings[code]) for code in codes]
    rows.append(("128+N", "stopped by signal N (130: Ctrl-C)"))
    lines = []
    for code, text in rows:
        wrapped = textwrap.wrap(text, 68)
        lines += [f"  {code:<6} {wrapped[0]}"] + [f"  {'':<6} {w}" for w in wrapped[1:]]
    return "\b\nExit status:\n" + "\n".join(lines)


#: The pages of ``multieye docs`` (installed with the package, from the repository's docs/).
DOC_PAGES = {"rig-yaml": "rig.yaml, key by key: the input",
             "outputs": "what each command writes, key by key",
             "conventions": "frames, units, covariances, error metrics, exit statuses",
             "architecture": "the layers of the package, where a change goes",
             "recordings": "long recordings (image selection) and many datasets (engines)"}


@click.group(context_settings={"help_option_names": ["-h", "--help"]},
             epilog=_exit_statuses(0, EXIT_USER_ERROR, EXIT_IMPLAUSIBLE))
@click.version_option(__version__, prog_name="multieye")
def main():
    """Calibrate a multi-camera rig: extrinsics and lenses, from a target tracked by motion
    capture or a robot, or seen by cameras that overlap.

    \b
    Quick start:
      multieye demo -o demo_out          # render, calibrate and check a synthetic rig
      multieye demo --rig overlap -o o2  # ... cameras that overlap, no motion capture
      multieye check DATASET             # dry run: is DATASET/rig.yaml right?
      multieye calibrate DATASET -o OUT  # your rig: DATASET/rig.yaml
      multieye docs rig-yaml             # every key of rig.yaml; all pages: multieye docs
    """
    one_blas_thread()       # before numpy is imported: no BLAS threads spinning for nothing
    fewer_collections()     # Python's collector every 50,000 allocations, not 700


@main.command(epilog=_exit_statuses(0, EXIT_USER_ERROR, EXIT_IMPLAUSIBLE))
@click.argument("dataset", type=click.Path(path_type=Path))
@click.option("-o", "--out", "out_dir", type=click.Path(file_okay=False, path_type=Path),
              required=True,
              help="Output folder, replaced as one set: calibration.json, details.json, "
                   "camchain.yaml (when Kalibr can hold a camera), report.html, figures/, "
                   "intrinsics/ (estimated lenses) and .multieye-manifest.json "
                   "(multieye docs outputs).")
@click.option("--method", default="joint", show_default=True,
              help="Solver: joint, wang2022, shah, li, tabb-c1, tabb-c2.")
@click.option("--reference", default=None, help="Reference camera (default: the first).")
@click.option("--processes", type=click.IntRange(1), default=None,
              help="Detection processes (default, and at most: one per core this process "
                   "may use, one per image).")
@click.option("--no-refine", is_flag=True,
              help="Keep the closed form (no maximum-likelihood refinement, no uncertainty).")
@click.option("--no-robust", is_flag=True,
              help="Use every measurement (no consensus step that rejects outliers).")
@click.option("--time-offset", default="rig", show_default=True, metavar="rig|auto|SECONDS",
              help="Motion-capture clock minus camera clock: as rig.yaml says, estimated per "
                   "camera, or this many seconds for every camera.")
@click.option("--max-time-offset", type=click.FloatRange(min=0, min_open=True), default=0.5,
              show_default=True, metavar="SECONDS",
              help="With --time-offset auto: search offsets up to this many seconds either way.")
@click.option("--select", type=click.IntRange(3), default=300, show_default=True, metavar="N",
              help="A camera with more than N images keeps N, chosen by what they add to the "
                   "calibration (before decoding, from the motion capture; multieye docs "
                   "recordings).")
@click.option("--no-select", is_flag=True, help="Keep every image (no selection).")
@click.option("--no-report", is_flag=True,
              help="Write no report.html and figures/ (about a second less; 'multieye report "
                   "OUT' makes them later from OUT's files).")
@click.option("--engine", type=click.Choice(["local", "dask"]), default="local",
              show_default=True,
              help="Where detection runs: worker processes of this machine, or Dask "
                   "distributed (pip install \"multieye[distributed]\").")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="With --engine dask: a running scheduler whose workers see the image "
                   "paths; default a local cluster of --processes workers.")
@_user_errors
def calibrate(dataset: Path, out_dir: Path, processes: int | None, **flags):
    """Calibrate the rig in DATASET (a folder with rig.yaml, or the rig.yaml itself).

    Closed form, consensus over measurements, then maximum-likelihood refinement with
    uncertainty.  Writes OUT/calibration.json (the result), OUT/details.json (the evidence,
    per image), OUT/camchain.yaml (Kalibr; a note names each camera it cannot hold),
    OUT/report.html with OUT/figures/, and OUT/intrinsics/<camera>.yaml for every lens
    estimated from the recording; prints a per-camera table.  rig.yaml: multieye docs
    rig-yaml; the files: multieye docs outputs.
    """
    report = not flags["no_report"]
    if flags["engine"] == "local" and flags["scheduler"] is None and os.path.exists(dataset):
        _prestart_workers(processes, report)
    # what the detection needs only: the rest is imported while the images are detected
    from multieye.pipeline import Options, calibrate as run_calibration  # noqa: PLC0415 (instant start-up of multieye --help)
    from multieye.outputs.folder import claim_output  # noqa: PLC0415 (instant start-up of multieye --help)
    from multieye.pipeline.calibrate_dataset import Hooks  # noqa: PLC0415 (instant start-up of multieye --help)
    from multieye.outputs.figure_workers import figure_workers  # noqa: PLC0415 (instant start-up of multieye --help; light: no numpy)
    from multieye.core.numpy_extras import defer_numpy_extras  # noqa: PLC0415 (instant start-up of multieye --help)

    defer_numpy_extras()    # numpy imported; SciPy's first import then skips numpy.f2py, .testing

    # Options checks every flag, once (an InputError: one line, exit 2, nothing written)
    options = Options(method=flags["method"], reference=flags["reference"],
                      refine=not flags["no_refine"], robust=not flags["no_robust"],
                      time_offset=_number_or_word(flags["time_offset"]),
                      max_time_offset=flags["max_time_offset"],
                      select=None if flags["no_select"] else flags["select"])
    _utf8_dataset(dataset)
    _processes_note(processes)
    drawing = figure_workers(processes) if report else contextlib.nullcontext()
    with claim_output(out_dir, inputs=[dataset]), drawing as workers:
        run = run_calibration(dataset, options, processes=processes,
                              progress=_progress_enabled(), engine=flags["engine"],
                              scheduler=flags["scheduler"],
                              hooks=Hooks(meanwhile=functools.partial(_import_writers, report),
                                          on_detected=workers.start_early if report else None))
        from multieye.outputs.write import write_outputs  # noqa: PLC0415 (imported while the images were detected, _import_writers)
        from multieye.outputs.summary import calibration_table, timings_line  # noqa: PLC0415 (imported while the images were detected, likewise)

        written = write_outputs(run, out_dir, processes=processes, workers=workers,
                                report=report)
    _echo(calibration_table(run.record))
    for name, data in run.cameras.items():
        if data.selection is not None:
            _echo(f"selected: {data.selection.line(name)}")
    for note in written.notes:
        _echo(f"note: {note}")
    _echo("wrote " + ", ".join(str(p) for p in written.paths))
    _echo(timings_line(written.timings))
    for doubt in run.doubts:
        _echo(f"multieye: written, but implausible: {doubt.message}", err=True)
    if run.doubts:
        sys.exit(EXIT_IMPLAUSIBLE)


@main.command("calibrate-many", epilog=_exit_statuses(0, EXIT_USER_ERROR, EXIT_IMPLAUSIBLE,
                                                       meanings={
    0: "every dataset calibrated",
    EXIT_USER_ERROR: "a dataset failed (its line on stderr; the others are written), or bad "
                     "options",
    EXIT_IMPLAUSIBLE: "every dataset written, a plausibility check doubts one or more"}))
@click.argument("datasets", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--out-root", type=click.Path(file_okay=False, path_type=Path), required=True,
              help="Folder of the output folders: OUT_ROOT/<dataset folder name>, each as "
                   "calibrate -o writes it.")
@click.option("--engine", type=click.Choice(["local", "dask"]), default="local",
              show_default=True,
              help="Where the calibrations run: worker processes of this machine, or Dask "
                   "distributed (pip install \"multieye[distributed]\").")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="With --engine dask: a running scheduler (tcp://host:8786) whose workers see "
                   "the same paths; default a local cluster, closed at the end.")
@click.option("--workers", type=click.IntRange(1), default=None,
              help="Calibrations at once (local processes or local Dask workers; default one "
                   "per core).")
@click.option("--method", default="joint", show_default=True,
              help="Solver: joint, wang2022, shah, li, tabb-c1, tabb-c2.")
@click.option("--no-refine", is_flag=True, help="Keep the closed form.")
@click.option("--no-robust", is_flag=True, help="Use every measurement (no consensus).")
@click.option("--time-offset", default="rig", show_default=True, metavar="rig|auto|SECONDS",
              help="Motion-capture clock minus camera clock, for every dataset.")
@click.option("--select", type=click.IntRange(3), default=300, show_default=True, metavar="N",
              help="Images kept per camera above N, as for calibrate.")
@click.option("--no-select", is_flag=True, help="Keep every image.")
@_user_errors
def calibrate_many_command(datasets: tuple[Path, ...], out_root: Path, **flags):
    """Calibrate every DATASET, each into OUT_ROOT/<its folder name>.

    Each calibration is one task (the local process pool, or Dask distributed with
    --engine dask), written under the rules of calibrate -o; a failing dataset does not
    stop the others.  Prints one line per dataset as it finishes; the exit status is the
    worst of them.  multieye docs recordings.
    """
    from multieye.many import calibrate_many, worst_status  # noqa: PLC0415 (instant start-up of multieye --help)
    from multieye.pipeline.options import Options  # noqa: PLC0415 (instant start-up of multieye --help)

    for d in datasets:
        _utf8_dataset(d)
    # Options checks every flag, once (an InputError: one line, exit 2, nothing written)
    options = Options(method=flags["method"], refine=not flags["no_refine"],
                      robust=not flags["no_robust"],
                      time_offset=_number_or_word(flags["time_offset"]),
                      select=None if flags["no_select"] else flags["select"])
    if flags["scheduler"] is not None and flags["engine"] != "dask":
        raise click.BadParameter("a scheduler needs --engine dask", param_hint="--scheduler")

    def done(o):
        line = f"{o.dataset}: " + {0: "ok", 3: "written, but implausible", 2: "error"}[o.status]
        line += f" ({o.seconds:.1f} s) -> {o.out}" if o.status != 2 else f": {o.message}"
        line += f"; {o.headline}" if o.headline else ""
        if o.status == 3:
            line += f": {o.message}"
        _echo(line, err=o.status != 0)

    result = calibrate_many(datasets, out_root, options, engine=flags["engine"],
                            scheduler=flags["scheduler"], workers=flags["workers"], on_done=done)
    _echo(f"{sum(o.status != 2 for o in result.outcomes)} of {len(result.outcomes)} datasets "
          f"written ({result.engine} engine)")
    status = worst_status([o.status for o in result.outcomes])
    if status:
        sys.exit(status)


@main.command(epilog=_exit_statuses(0, EXIT_USER_ERROR, meanings={
    0: "calibrating can run (warnings included)",
    EXIT_USER_ERROR: "calibrating would fail (one line per reason on stderr), or bad input"}))
@click.argument("dataset", type=click.Path(path_type=Path))
@click.option("--sample", type=click.IntRange(1), default=20, show_default=True,
              help="Images per camera, evenly spaced, searched for the target (more, from "
                   "the rest, while fewer than 3 show it, up to 10 x N per camera).")
@click.option("--processes", type=click.IntRange(1), default=None,
              help="Detection processes (default, and at most: one per core this process "
                   "may use, one per image).")
@_user_errors
def check(dataset: Path, sample: int, processes: int | None):
    """Dry run: what calibrating DATASET would find, and what would go wrong.

    Reads rig.yaml and the motion capture, detects the target in a sample of each camera's
    images and pairs them with the motion capture, without solving.  Prints a table per
    camera and the problems; when a camera's images show no target, says what they hold
    and what to write in rig.yaml.  Writes nothing.
    """
    from multieye.pipeline.dry_run import check_dataset  # noqa: PLC0415 (instant start-up of multieye --help)
    from multieye.outputs.summary import check_table  # noqa: PLC0415 (instant start-up of multieye --help)

    _utf8_dataset(dataset)
    _processes_note(processes)
    result = check_dataset(dataset, sample=sample, processes=processes)
    _echo(check_table(result))
    for note in result.notes:
        _echo(f"note: {note}")
    for reason in result.reasons:
        _echo(f"multieye: calibrating would fail: {reason}", err=True)
    for reason in () if result.reasons else result.doubts:
        _echo(f"multieye: calibrating may fail: {reason}", err=True)
    if not result.ok:
        sys.exit(EXIT_USER_ERROR)


@main.command(epilog=_exit_statuses(0, EXIT_USER_ERROR))
@click.option("-o", "--out", "out_dir", type=click.Path(file_okay=False, path_type=Path),
              default=Path("demo_out"), show_default=True,
              help="Output folder: dataset/ and the files of calibrate -o.")
@click.option("--seed", type=int, default=0, show_default=True)
@click.option("--rig", type=click.Choice(["surround", "overlap"]), default="surround",
              show_default=True,
              help="surround: 4 cameras that do not overlap, a motion-captured board, lenses "
                   "known; overlap: 3 cameras that see the board together, no motion "
                   "capture, every lens unknown (what Kalibr and mrcal calibrate).")
@_user_errors
def demo(out_dir: Path, seed: int, rig: str):
    """Render a synthetic rig, calibrate it and compare with ground truth.

    OUT/dataset is a complete dataset (rig.yaml, images, intrinsics or lens models, mocap.txt
    for the surround rig, ground_truth.json) that `multieye calibrate OUT/dataset -o ...` also
    accepts.
    """
    from multieye.demo import run_demo, run_overlap_demo  # noqa: PLC0415 (instant start-up of multieye --help)

    run = run_overlap_demo if rig == "overlap" else run_demo
    result = run(out_dir, seed=seed, progress=_progress_enabled())
    _echo(result.text)


@main.command(epilog=_exit_statuses(0, EXIT_USER_ERROR))
@click.argument("out_dir", type=click.Path(file_okay=False, path_type=Path))
@_user_errors
def report(out_dir: Path):
    """Write OUT/report.html (and OUT/figures/*.png) from a calibration in OUT.

    Reads OUT/calibration.json and, when present, OUT/details.json.
    """
    from multieye.outputs.folder import claim_output  # noqa: PLC0415 (instant start-up of multieye --help)
    from multieye.outputs.report import write_report  # noqa: PLC0415 (instant start-up of multieye --help)

    with claim_output(out_dir, replace=False):
        _echo(str(write_report(out_dir)))


EXPORT_FORMATS = ("kalibr", "opencv", "urdf", "tf-static", "json", "camera-info", "mrcal")


@main.command(epilog=_exit_statuses(0, EXIT_USER_ERROR))
@click.argument("out_dir", type=click.Path(file_okay=False, path_type=Path))
@click.option("--format", "fmt", type=click.Choice(EXPORT_FORMATS), required=True,
              help="kalibr camchain, OpenCV FileStorage, URDF fragment, ROS 2 static "
                   "transform publisher arguments, compact JSON, one ROS camera_info "
                   "YAML per camera, or one mrcal .cameramodel per camera.")
@click.option("--parent-frame", default=None,
              help="Name of the base frame in urdf, tf-static and opencv [default: the frame "
                   "the cameras are calibrated in, named as in rig.yaml's mocap pose: the "
                   "fixed frame for eye-to-base (world, or base for pose: T_base_tool0), the "
                   "tracked frame for eye-on-hand (body, or tool0)].")
@click.option("--child-frame", default=None,
              help="Stem of each camera's frames, {camera} standing for its name: "
                   "<stem>_link and <stem>_optical_frame [default: {camera}].")
@_user_errors
def export(out_dir: Path, fmt: str, parent_frame: str | None, child_frame: str | None):
    """Export the calibration in OUT to another tool's format (into OUT/export/).

    The files and their frames: multieye docs outputs (section 6).
    """
    from multieye.outputs.export import export as run_export  # noqa: PLC0415 (instant start-up of multieye --help)
    from multieye.outputs.folder import claim_output  # noqa: PLC0415 (instant start-up of multieye --help)

    notes: list[str] = []
    with claim_output(out_dir, replace=False):
        for p in run_export(out_dir, fmt, notes=notes, parent_frame=parent_frame,
                            child_frame=child_frame):
            _echo(str(p))
    for note in notes:
        _echo(f"note: {note}", err=True)


@main.command(epilog=_exit_statuses(0, EXIT_USER_ERROR))
@click.argument("name", type=click.Choice(["noise", "cameras", "measurements", "timing", "refine"]))
@click.option("--trials", type=click.IntRange(1), default=100, show_default=True,
              help="Monte Carlo trials per parameter value.")
@click.option("--seed", type=int, default=0, show_default=True)
@click.option("-o", "--out", "out_dir", type=click.Path(file_okay=False, path_type=Path),
              default=Path("experiments"), show_default=True, help="Output folder.")
@_user_errors
def experiment(name: str, trials: int, seed: int, out_dir: Path):
    """Reproduce a synthetic experiment of the paper (section V-B), or `refine`.

    noise, cameras, measurements, timing: the paper's pose-level sweeps over all solvers,
    OUT/NAME.csv (param, method, trial, e_R_deg, e_t_m, rel_rot_err_deg, rel_trans_err_m,
    time_s, failure) and OUT/NAME.png.  refine: image-level simulation over pixel noise, closed form against
    the maximum-likelihood refinement and the Cramer-Rao bound.
    """
    from multieye.outputs.folder import claim_output  # noqa: PLC0415 (instant start-up of multieye --help)

    # held as every command that writes into a folder holds it (refused while a calibration
    # writes there: issue 32)
    with claim_output(out_dir, replace=False):
        if name == "refine":
            from multieye.experiments.refine_sweep import run_refine_experiment  # noqa: PLC0415 (instant start-up of multieye --help)

            paths = run_refine_experiment(trials=trials, seed=seed, out_dir=out_dir,
                                          progress=_progress_enabled())
            _echo("wrote " + " and ".join(str(p) for p in paths))
            return
        from multieye.experiments.sweeps import run_experiment  # noqa: PLC0415 (instant start-up of multieye --help)

        out = run_experiment(name, trials=trials, seed=seed, out_dir=out_dir,
                             progress=_progress_enabled())
    _echo(f"wrote {out.csv_path} and {out.png_path}")
    if out.result.failures:
        _echo(f"{out.result.failures} solves refused the data (NaN rows, column failure): "
              f"{out.result.failure_summary()}")


@main.command(epilog=_exit_statuses(0, EXIT_USER_ERROR, meanings={
    EXIT_USER_ERROR: "no such page"}))
@click.argument("name", required=False, type=click.Choice(sorted(DOC_PAGES)))
def docs(name: str | None):
    """Print a documentation page, installed with the package (Markdown).

    Without NAME, list the pages: rig-yaml (the input, key by key), outputs (what each
    command writes), conventions (frames, units, exit statuses), architecture.
    """

    if name is None:
        width = max(map(len, DOC_PAGES))
        for page, what in DOC_PAGES.items():
            click.echo(f"{page:<{width}}  {what}  (multieye docs {page})")
        return
    click.echo((files("multieye") / "docs" / f"{name}.md").read_text(encoding="utf-8"),
               nl=False)


if __name__ == "__main__":  # pragma: no cover
    main()


def run() -> None:
    """The ``multieye`` command and ``python -m multieye``: :func:`main`, then a quick exit.

    Once a command has ended, its files are written and closed, and the exit functions have
    run (multiprocessing's helpers stopped and collected, :func:`multieye.imaging.workers.
    stop_helpers`), the interpreter's own teardown frees every module one by one: about
    0.2 s after a calibration with numpy, SciPy, OpenCV and matplotlib loaded, for nothing a
    user needs.  So the standard streams are flushed and the process ends there with the
    command's status.  Where a thread other than this one still runs, or the command ended
    by an exception other than ``SystemExit``, the interpreter ends as usual.
    """
    import atexit  # noqa: PLC0415 (only this entry point ends the process itself)

    try:
        main()                       # standalone: every ending raises SystemExit
    except SystemExit as exc:
        code = exc.code
    else:                            # pragma: no cover - click always raises SystemExit
        code = 0
    if not isinstance(code, int) or any(t is not threading.main_thread() and t.is_alive()
                                        and not t.daemon for t in threading.enumerate()):
        sys.exit(code)               # a message, or a thread to wait for: the usual way
    atexit._run_exitfuncs()          # noqa: SLF001 (what the interpreter would run next)
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a reader gone (| head) or a closed stream
            code = code or 120         # what the interpreter exits with when flushing fails
    os._exit(code)
