"""Hostile and unlucky cases of the write side (issue 19): names used as paths, links followed
on write, and input that used to end in a traceback.

Each :class:`Case` builds its input in a fresh folder beside a *sentinel* folder of files that
are not multieye's, runs one command, and :func:`run_case` reports the exit status, the
lines on stderr, and what changed outside ``OUT`` (and in ``OUT`` for a refused run).  Used by
``tests/cli/test_cli_hostile_writes.py`` (every case asserted) and by
``benchmarks/hostile_cases.py`` (the figures of docs/results/hostile_input.md).
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import stat
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from click.testing import CliRunner
from pose_dataset import write_pose_dataset

from multieye.cli import main

#: Runs the command line after a fault injected in the process (see ``ENOSPC``).
_MAIN = "from multieye.cli import main\nmain(prog_name='multieye')\n"

#: Fault injection: the third file multieye writes atomically fails with ENOSPC half-way.
ENOSPC = """
import errno, os
import multieye.io.atomic as _atomic
_real_fdopen, _count = _atomic.os.fdopen, [0]
class _Full:
    def __init__(self, f): self._f = f
    def write(self, data):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    def __getattr__(self, name): return getattr(self._f, name)
    def __enter__(self): return self
    def __exit__(self, *a): return self._f.__exit__(*a)
def _fdopen(fd, *a, **k):
    f = _real_fdopen(fd, *a, **k)
    if not set(a[0] if a else k.get("mode", "r")) & set("wax+"):
        return f                      # files read (regular_files opens them the same way)
    _count[0] += 1
    return _Full(f) if _count[0] == 3 else f
_atomic.os.fdopen = _fdopen
"""


@dataclass
class Work:
    """The folder of one case: ``ds`` (a dataset), ``out`` (a calibrated output folder),
    ``sentinel`` (files that are not multieye's)."""

    root: Path
    ds: Path
    out: Path
    sentinel: Path


@dataclass(frozen=True)
class Case:
    """One hostile case.

    ``prepare(work)`` edits the work folder and returns the command's arguments and the
    output folder the command may change (None: ``work.out``).  ``expect``: the exit
    statuses that are clean outcomes; ``named``: texts the error line must hold.
    """

    name: str
    kind: str                   # "names", "links" or "tracebacks"
    prepare: Callable
    expect: tuple[int, ...] = (2,)
    named: tuple[str, ...] = ()
    subprocess: bool = False
    fsize: int | None = None    # RLIMIT_FSIZE of the process, bytes
    prelude: str = ""           # Python run before the command line (fault injection)
    check: Callable | None = None   # extra check of a successful run: check(work, out) -> str
    #: report and export write into OUT file by file (each atomically, no set): a write
    #: failing half-way leaves the files before it new
    out_may_change: bool = False


@dataclass
class Outcome:
    case: Case
    code: int
    stdout: str
    stderr: str
    outside_changed: list[str] = field(default_factory=list)
    out_changed: bool = False
    problem: str | None = None

    @property
    def clean(self) -> bool:
        """A clean outcome: an expected status, one line on error, no traceback, nothing
        outside OUT touched, OUT untouched on error, and the case's own check passed."""
        return self.problem is None


# --------------------------------------------------------------------------- building


def make_template(folder: Path) -> tuple[Path, Path]:
    """A pose dataset and its calibrated output folder (built once, copied per case)."""
    ds = folder / "ds"
    ds.mkdir(parents=True)
    write_pose_dataset(ds)
    out = folder / "out"
    res = CliRunner().invoke(main, ["calibrate", str(ds), "-o", str(out)])
    assert res.exit_code == 0, res.output
    return ds, out


def make_work(root: Path, template: tuple[Path, Path]) -> Work:
    root.mkdir(parents=True, exist_ok=True)
    ds, out = root / "ds", root / "out"
    shutil.copytree(template[0], ds)
    shutil.copytree(template[1], out)
    sentinel = root / "sentinel"
    (sentinel / "dir").mkdir(parents=True)
    (sentinel / "victim.txt").write_text("not multieye's\n")
    (sentinel / "dir" / "inner.txt").write_text("not multieye's either\n")
    (sentinel / "camera_cam0.png").write_bytes(b"a user's picture")
    (sentinel / "rig.png").write_bytes(b"another picture")
    (sentinel / "calibration.json").write_text((out / "calibration.json").read_text())
    return Work(root, ds, out, sentinel)


def snapshot(root: Path) -> dict[str, tuple]:
    """Every entry under ``root`` (links not followed): kind, content or target, link count."""
    found = {}
    for folder, dirs, files in os.walk(root):
        for name in dirs + files:
            p = Path(folder, name)
            rel = p.relative_to(root).as_posix()
            st = p.lstat()
            if stat.S_ISLNK(st.st_mode):
                found[rel] = ("link", os.readlink(p))
            elif stat.S_ISDIR(st.st_mode):
                found[rel] = ("dir", stat.S_IMODE(st.st_mode))
            elif stat.S_ISREG(st.st_mode):
                found[rel] = ("file", p.read_bytes(), st.st_nlink, st.st_mtime_ns)
            else:
                found[rel] = ("other", stat.S_IFMT(st.st_mode))
    return found


def _inside(rel: str, out_rel: str) -> bool:
    return rel == out_rel or rel.startswith(out_rel + "/")


def run_case(case: Case, work: Work) -> Outcome:
    """Prepare, run and judge one case (see :attr:`Outcome.clean`)."""
    args, out = case.prepare(work)
    out = work.out if out is None else out
    out_rel = Path(os.path.realpath(out.parent), out.name).relative_to(
        os.path.realpath(work.root)).as_posix()
    before = snapshot(work.root)
    if case.subprocess or case.fsize is not None or case.prelude:
        def limit():
            if case.fsize is not None:
                resource.setrlimit(resource.RLIMIT_FSIZE, (case.fsize, resource.RLIM_INFINITY))
        proc = subprocess.run([sys.executable, "-c", case.prelude + _MAIN,
                               *[a if isinstance(a, bytes) else str(a) for a in args]],
                              capture_output=True, cwd=work.root, preexec_fn=limit,
                              timeout=300)
        code = proc.returncode
        stdout = proc.stdout.decode("utf-8", "replace")
        stderr = proc.stderr.decode("utf-8", "replace")
    else:
        res = CliRunner().invoke(main, [str(a) for a in args])
        code, stdout, stderr = res.exit_code, res.stdout, res.stderr
        if res.exception is not None and not isinstance(res.exception, SystemExit):
            stderr += f"\nTraceback (in process): {res.exception!r}"
    after = snapshot(work.root)
    outcome = Outcome(case, code, stdout, stderr)
    outcome.outside_changed = sorted(
        k for k in set(before) | set(after)
        if not _inside(k, out_rel) and before.get(k) != after.get(k))
    outcome.out_changed = any(before.get(k) != after.get(k) for k in set(before) | set(after)
                              if _inside(k, out_rel))
    outcome.problem = _judge(case, outcome, work, out)
    return outcome


def _judge(case: Case, o: Outcome, work: Work, out: Path) -> str | None:
    if "Traceback" in o.stderr or "Traceback" in o.stdout:
        return "traceback: " + o.stderr[-300:]
    if o.code not in case.expect:
        return f"exit status {o.code}, expected {case.expect}: {o.stderr.strip()[-300:]}"
    if o.outside_changed:
        return f"changed outside OUT: {', '.join(o.outside_changed[:5])}"
    if o.code == 2:
        lines = o.stderr.strip().splitlines()
        if len(lines) != 1 or not lines[0].startswith("multieye: error: "):
            return f"not one error line: {o.stderr!r}"
        missing = [t for t in case.named if t not in lines[0]]
        if missing:
            return f"error line does not name {missing}: {lines[0]}"
        if o.out_changed and not case.out_may_change:
            return "refused, but OUT changed"
    elif case.check is not None:
        return case.check(work, out)
    return None


# --------------------------------------------------------------------------- cases: names


def _rig_name(new: str, old: str = "cam1", also: tuple[str, str] | None = None):
    """Rename camera ``old`` of the dataset's rig.yaml (an explicit YAML key, double-quoted:
    a plain key holds at most 1024 characters)."""
    def prepare(w: Work):
        rig = w.ds / "rig.yaml"
        text = rig.read_text().replace(f"  {old}:", f"  ? {json.dumps(new)}\n  :")
        if also is not None:
            text = text.replace(f"  {also[0]}:", f"  ? {json.dumps(also[1])}\n  :")
        rig.write_text(text)
        return ["calibrate", w.ds, "-o", w.out], None
    return prepare


def _json_names(names: tuple[str, str], *args: str, command: str = "export"):
    """Rename the two cameras of OUT/calibration.json and OUT/details.json."""
    def prepare(w: Work):
        names_ = [str(w.sentinel / n[1:]) if n.startswith("@") else n for n in names]
        for file in ("calibration.json", "details.json"):
            data = json.loads((w.out / file).read_text())
            data["cameras"] = dict(zip(names_, data["cameras"].values()))
            if file == "calibration.json" or "reference_camera" in data:
                data["reference_camera"] = names_[0]
            (w.out / file).write_text(json.dumps(data))
        return [command, w.out, *args], None
    return prepare


def _files_inside(folder: str, count: int):
    def check(w: Work, out: Path) -> str | None:
        found = sorted(p.name for p in (out / folder).iterdir())
        return None if len(found) == count else f"{folder} holds {found}"
    return check


NAME_CASES = [
    Case("rig name ../../x", "names", _rig_name("../../x"), named=("rig.yaml:", "holds '/'")),
    Case("rig name absolute path", "names", _rig_name("/tmp/multieye-hostile-x"),
         named=("rig.yaml:", "holds '/'")),
    Case("rig name a/b", "names", _rig_name("a/b"), named=("rig.yaml:",)),
    Case("rig name a\\b", "names", _rig_name("a\\b"), named=("rig.yaml:", "holds")),
    Case("rig name .", "names", _rig_name("."), named=("rig.yaml:", "starts with '.'")),
    Case("rig name ..", "names", _rig_name(".."), named=("rig.yaml:",)),
    Case("rig name .hidden", "names", _rig_name(".hidden"), named=("rig.yaml:",)),
    Case("rig name x..y", "names", _rig_name("x..y"), named=("rig.yaml:", "'..'")),
    Case("rig name 5000 characters", "names", _rig_name("c" * 5000),
         named=("rig.yaml:", "5000 characters")),
    Case("rig name 101 characters", "names", _rig_name("c" * 101), named=("rig.yaml:",)),
    Case("rig name 67 x 3-byte characters", "names", _rig_name("\u20ac" * 67),
         named=("rig.yaml:", "bytes")),
    Case("rig name NUL", "names", _rig_name("cam\x001"), named=("rig.yaml:",)),
    Case("rig name tab", "names", _rig_name("cam\t1"), named=("rig.yaml:",)),
    Case("rig name escape sequence", "names", _rig_name("\x1b[31mred"), named=("rig.yaml:",)),
    Case("rig name line break", "names", _rig_name("cam\n1"), named=("rig.yaml:",)),
    Case("rig name leading space", "names", _rig_name(" cam1"), named=("rig.yaml:",)),
    Case("rig name trailing space", "names", _rig_name("cam1 "), named=("rig.yaml:",)),
    Case("rig name colon", "names", _rig_name("c:1"), named=("rig.yaml:",)),
    Case("rig name only case differs", "names", _rig_name("CAM0"),
         named=("rig.yaml:", "one file with camera 'cam0'")),
    Case("rig names NFC / NFD", "names",
         _rig_name("cafe\u0301", also=("cam0", "caf\u00e9")), named=("rig.yaml:",)),
    Case("rig name bidi override", "names", _rig_name("cam\u202e1"), named=("rig.yaml:",)),
    Case("export camera-info, names ../../x and an absolute path", "names",
         _json_names(("../../victim", "@victim.txt"), "--format", "camera-info"), expect=(0,),
         check=_files_inside("export/camera_info", 2)),
    Case("export camera-info, names a/b and a_b (one file)", "names",
         _json_names(("a/b", "a_b"), "--format", "camera-info"), named=("'a/b'", "'a_b'")),
    Case("export camera-info, names Cam and cam (one file on macOS)", "names",
         _json_names(("Cam", "cam"), "--format", "camera-info"), named=("'Cam'", "'cam'")),
    Case("export camera-info, 5000-character name", "names",
         _json_names(("c" * 5000, "cam1"), "--format", "camera-info"), expect=(0,),
         check=_files_inside("export/camera_info", 2)),
    Case("export camera-info, names . and ..", "names",
         _json_names((".", ".."), "--format", "camera-info"), expect=(0,),
         check=_files_inside("export/camera_info", 2)),
    Case("export urdf, name ../../x", "names",
         _json_names(("../../x", "cam1"), "--format", "urdf"), expect=(0,),
         check=_files_inside("export", 1)),
    Case("report, names ../../x and an absolute path", "names",
         _json_names(("../../victim", "@dir/inner"), command="report"), expect=(0,)),
]


# --------------------------------------------------------------------------- cases: links


def _link(rel: str, target: str, command: str = "calibrate", *args: str,
          remove: bool = True, kind: str = "symlink"):
    """Put a link (or another kind of entry) at ``rel`` (relative to the work folder, OUT
    spelled ``out``) pointing at ``target`` (relative to the sentinel folder)."""
    def prepare(w: Work):
        where = w.root / rel
        where.parent.mkdir(parents=True, exist_ok=True)
        if remove and (where.exists() or where.is_symlink()):
            shutil.rmtree(where) if where.is_dir() and not where.is_symlink() else where.unlink()
        if kind == "symlink":
            where.symlink_to(w.sentinel / target)
        elif kind == "hardlink":
            os.link(w.sentinel / target, where)
        elif kind == "fifo":
            os.mkfifo(where)
        elif kind == "folder":
            where.mkdir()
        command_args = {"calibrate": ["calibrate", w.ds, "-o", w.out],
                        "report": ["report", w.out],
                        "export": ["export", w.out, *args]}[command]
        return command_args, None
    return prepare


def _leftover(kind: str):
    """OUT missing, and a link named like a killed run's staging or backup folder beside it,
    pointing at the sentinel folder: recovery must neither follow nor rename it."""
    def prepare(w: Work):
        shutil.rmtree(w.out)
        (w.root / f"out.multieye-{kind}-1-abcd1234").symlink_to(w.sentinel)
        return ["calibrate", w.ds, "-o", w.out], None
    return prepare


def _linked_parent(w: Work):
    (w.root / "real").mkdir()
    (w.root / "parent").symlink_to(w.root / "real")
    return ["calibrate", w.ds, "-o", w.root / "parent" / "out"], w.root / "real" / "out"


def _has_calibration(w: Work, out: Path) -> str | None:
    return None if (out / "calibration.json").is_file() else "no calibration.json"


LOCK = "out.multieye-lock"
LINK_CASES = [
    Case("lock file a link to a file (calibrate)", "links", _link(LOCK, "victim.txt"),
         named=("multieye-lock", "symbolic link")),
    Case("lock file a link to a file (report)", "links", _link(LOCK, "victim.txt", "report"),
         named=("multieye-lock",)),
    Case("lock file a link to a file (export)", "links",
         _link(LOCK, "victim.txt", "export", "--format", "json"), named=("multieye-lock",)),
    Case("lock file a dangling link", "links", _link(LOCK, "new.txt"),
         named=("multieye-lock",)),
    Case("lock file a hard link to a file", "links",
         _link(LOCK, "victim.txt", kind="hardlink"), named=("multieye-lock", "hard links")),
    Case("lock file a FIFO", "links", _link(LOCK, "", kind="fifo"),
         named=("multieye-lock", "not a file")),
    Case("lock file a folder", "links", _link(LOCK, "", kind="folder"),
         named=("multieye-lock",)),
    Case("OUT a link to a folder (calibrate)", "links", _link("out", "dir"),
         named=("out", "symbolic link")),
    Case("OUT a link to a folder (report)", "links", _link("out", "dir", "report"),
         named=("symbolic link",)),
    Case("OUT a link to a folder (export)", "links",
         _link("out", "dir", "export", "--format", "camera-info"), named=("symbolic link",)),
    Case("OUT a dangling link", "links", _link("out", "nowhere"), named=("symbolic link",)),
    Case("OUT/figures a link (report)", "links", _link("out/figures", "", "report"),
         named=("figures", "symbolic link")),
    Case("OUT/figures a link (calibrate)", "links", _link("out/figures", ""),
         named=("figures",)),
    Case("OUT/export a link (export json)", "links",
         _link("out/export", "", "export", "--format", "json"), named=("export",)),
    Case("OUT/export a link (export camera-info)", "links",
         _link("out/export", "", "export", "--format", "camera-info"), named=("export",)),
    Case("OUT/export/camera_info a link", "links",
         _link("out/export/camera_info", "dir", "export", "--format", "camera-info"),
         named=("camera_info",)),
    Case("OUT/intrinsics a link (calibrate)", "links", _link("out/intrinsics", "dir"),
         named=("intrinsics",)),
    Case("OUT/report.html a link (report)", "links",
         _link("out/report.html", "victim.txt", "report"), named=("report.html",)),
    Case("OUT/figures/rig.png a link (report)", "links",
         _link("out/figures/rig.png", "rig.png", "report"), named=("rig.png",)),
    Case("OUT/figures/camera_old.png a link to remove (report)", "links",
         _link("out/figures/camera_old.png", "camera_cam0.png", "report"),
         named=("camera_old.png",)),
    Case("OUT/calibration.json a link (report)", "links",
         _link("out/calibration.json", "calibration.json", "report"),
         named=("calibration.json",)),
    Case("OUT/export/urdf a link (export urdf)", "links",
         _link("out/export/cameras.urdf", "victim.txt", "export", "--format", "urdf"),
         named=("cameras.urdf",)),
    Case("leftover staging folder a link", "links", _leftover("tmp"), expect=(0,),
         check=_has_calibration),
    Case("leftover backup folder a link, OUT missing", "links", _leftover("old"),
         expect=(0,), check=_has_calibration),
    Case("folder above OUT a link (allowed)", "links", _linked_parent, expect=(0,),
         check=_has_calibration),
]


# --------------------------------------------------------------------------- cases: tracebacks


def _bytes_out(command: str, *args: str):
    """OUT named with a byte that is not UTF-8."""
    def prepare(w: Work):
        out = Path(os.fsdecode(bytes(w.root) + b"/o\xffut"))
        if command != "calibrate":
            shutil.copytree(w.out, out)
        argv = {"calibrate": ["calibrate", w.ds, "-o", out], "report": ["report", out],
                "export": ["export", out, *args]}[command]
        return [os.fsencode(str(a)) for a in argv], out
    return prepare


def _bytes_dataset(w: Work):
    ds = Path(os.fsdecode(bytes(w.root) + b"/d\xfe\xffs"))
    shutil.copytree(w.ds, ds)
    return [b"calibrate", os.fsencode(ds), b"-o", os.fsencode(w.out)], None


def _bytes_image(w: Work):
    """A rendered dataset (2 cameras x 4 images) with an image and another file whose names
    hold bytes that are not UTF-8."""
    from multieye.sim.dataset import DatasetSpec, render_dataset

    ds = w.root / "images"
    render_dataset(ds, DatasetSpec(n_cameras=2, images_per_camera=4, width=320, height=240,
                                   processes=1), seed=2)
    first = sorted((ds / "cam0").iterdir())[0]
    os.rename(first, os.fsdecode(os.fsencode(first)[:-6] + b"\xff.png"))
    (ds / "cam1" / os.fsdecode(b"notes\xfe.txt")).write_text("not an image")
    return ["calibrate", ds, "-o", w.out, "--processes", "1"], None


def _calibration_text(text: str | bytes, command: str = "report", *args: str,
                      file: str = "calibration.json"):
    def prepare(w: Work):
        data = text.encode() if isinstance(text, str) else text
        (w.out / file).write_bytes(data)
        return ([command, w.out, *args] if command != "calibrate"
                else ["calibrate", w.ds, "-o", w.out]), None
    return prepare


def _calibration_value(path: tuple, value, command: str = "report", *args: str):
    def prepare(w: Work):
        data = json.loads((w.out / "calibration.json").read_text())
        here = data
        for key in path[:-1]:
            here = here[key]
        here[path[-1]] = value
        (w.out / "calibration.json").write_text(json.dumps(data))
        return [command, w.out, *args], None
    return prepare


def _command(command: str, *args: str):
    def prepare(w: Work):
        return ({"calibrate": ["calibrate", w.ds, "-o", w.out], "report": ["report", w.out],
                 "export": ["export", w.out, *args]}[command]), None
    return prepare


def _no_lock_and_untouched(w: Work, out: Path) -> str | None:
    left = [p.name for p in w.root.iterdir() if ".multieye-" in p.name]
    return f"left beside OUT: {left}" if left else None


NESTED = "[" * 100_000 + "]" * 100_000
TRACEBACK_CASES = [
    Case("OUT path not UTF-8 (calibrate)", "tracebacks", _bytes_out("calibrate"),
         expect=(0,), subprocess=True, check=_has_calibration),
    Case("OUT path not UTF-8 (report)", "tracebacks", _bytes_out("report"), expect=(0,),
         subprocess=True),
    Case("OUT path not UTF-8 (export camera-info)", "tracebacks",
         _bytes_out("export", "--format", "camera-info"), expect=(0,), subprocess=True),
    Case("dataset path not UTF-8 (OpenCV crashed on it)", "tracebacks", _bytes_dataset,
         subprocess=True, named=("not UTF-8", "d\ufffd\ufffds")),
    Case("image file name not UTF-8", "tracebacks", _bytes_image, expect=(0, 2),
         subprocess=True, named=("\ufffd",)),
    Case("calibration.json nested 100000 deep (report)", "tracebacks",
         _calibration_text(NESTED), named=("calibration.json", "nested")),
    Case("calibration.json nested 100000 deep (export)", "tracebacks",
         _calibration_text(NESTED, "export", "--format", "json"), named=("calibration.json",)),
    Case("calibration.json nested objects (report)", "tracebacks",
         _calibration_text('{"a":' * 50_000 + "1" + "}" * 50_000), named=("calibration.json",)),
    Case("details.json nested 100000 deep (export kalibr)", "tracebacks",
         _calibration_text(NESTED, "export", "--format", "kalibr", file="details.json"),
         named=("details.json",)),
    Case("calibration.json truncated", "tracebacks",
         _calibration_text('{"setup": "eye-to-base", "cameras": {'), named=("calibration.json",)),
    Case("calibration.json binary", "tracebacks", _calibration_text(bytes(range(256))),
         named=("calibration.json",)),
    Case("calibration.json empty", "tracebacks", _calibration_text(""),
         named=("calibration.json",)),
    Case("calibration.json a list", "tracebacks", _calibration_text("[1, 2, 3]"),
         named=("calibration.json",)),
    Case("calibration.json setup a list", "tracebacks", _calibration_value(("setup",), [1]),
         named=("calibration.json",)),
    Case("calibration.json covariance of text", "tracebacks",
         _calibration_value(("cameras", "cam0", "covariance"), [["x"] * 6] * 6),
         named=("calibration.json",)),
    Case("calibration.json integer beyond float", "tracebacks",
         _calibration_value(("cameras", "cam0", "T_world_cam"), [[10 ** 400] * 4] * 4,
                            "export", "--format", "urdf"), named=("calibration.json",)),
    Case("calibration.json cameras a string", "tracebacks",
         _calibration_value(("cameras",), "cam0", "export", "--format", "tf-static"),
         named=("calibration.json",)),
    Case("file-size limit 0 (calibrate)", "tracebacks", _command("calibrate"), fsize=0,
         named=("multieye-lock", "File too large", "ulimit -f")),
    Case("file-size limit 0 (report)", "tracebacks", _command("report"), fsize=0,
         named=("File too large",)),
    Case("file-size limit 0 (export)", "tracebacks",
         _command("export", "--format", "camera-info"), fsize=0, named=("File too large",)),
    Case("file-size limit 3000 bytes (calibrate)", "tracebacks", _command("calibrate"),
         fsize=3000, named=("out/", "File too large")),
    Case("disk full on the third file (calibrate)", "tracebacks", _command("calibrate"),
         prelude=ENOSPC, named=("out/", "No space left on device", "disk is full")),
    Case("disk full on the third file (report)", "tracebacks", _command("report"),
         prelude=ENOSPC, named=("out/figures/", "No space left on device"),
         out_may_change=True),
]

CASES = NAME_CASES + LINK_CASES + TRACEBACK_CASES
