"""Hostile cases of output folders whose names are too long for the file system (run by
tests/cli/test_cli_hostile_writes.py with tests/hostile_cases.py's judge): a name of OUT's
path over NAME_MAX (255 bytes), OUT's name too long for the staging and lock names beside it,
or the whole path too long for the files inside (PATH_MAX, 4096 bytes). Every command that
writes a folder refuses them before it runs: exit 2, one line naming the path and what was
expected, nothing written. They failed late: calibrate after calibrating (its staging
folder), report and export half-way through their files, calibrate-many per dataset after
calibrating it, experiment after the sweep."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from hostile_cases import Case

from multieye.outputs.folder_names import INSIDE_BYTES, LOCK_BYTES, SIBLING_BYTES

__all__ = ["LONG_CASES", "LONG_NAME"]

#: OUT's name: within NAME_MAX, too long for ``<name>.multieye-tmp-<pid>-<hex>`` beside it.
LONG_NAME = "n" * 240


def _deep(root: Path, total: int) -> Path:
    """A path below ``root`` exactly ``total`` bytes long, of folders of at most 200 bytes."""
    path = root.resolve()
    while len(os.fsencode(str(path))) < total:
        left = total - len(os.fsencode(str(path))) - 1
        path = path / ("d" * min(200, max(left, 1)))
    assert len(os.fsencode(str(path))) == total
    return path


def _out(kind: str, root: Path) -> Path:
    """``name``: OUT's name too long for the names beside it; ``parent``: a folder above OUT
    over NAME_MAX; ``path``: a path of 4040 bytes, too long for the files inside."""
    return {"name": lambda: root / LONG_NAME,
            "parent": lambda: root / ("p" * 300) / "out",
            "path": lambda: _deep(root, 4040)}[kind]()


_EXPECTED = {"name": ("240 bytes long; expected at most 222 bytes", "NAME_MAX 255"),
             "parent": ("a folder name above the output folder is 300 bytes long; expected "
                        "at most 255 bytes",),
             "path": ("the output folder's path is 4040 bytes long; expected at most "
                      f"{4095 - SIBLING_BYTES - INSIDE_BYTES} bytes", "PATH_MAX 4096")}


def _calibrate(kind: str):
    def prepare(w):
        out = _out(kind, w.root)
        return ["calibrate", w.ds, "-o", out], out
    return prepare


def _into(command: str, *args: str):
    """``command`` on a calibration copied into a folder 4040 bytes deep."""
    def prepare(w):
        out = _deep(w.root, 4040)
        out.parent.mkdir(parents=True)
        for p in ("calibration.json", "details.json"):      # short names: they fit
            out.mkdir(exist_ok=True)
            shutil.copyfile(w.out / p, out / p)
        return [command, out, *args], out
    return prepare


def _many(w):
    root = _deep(w.root, 4040)
    return ["calibrate-many", w.ds, "--out-root", root, "--workers", "1"], root / "ds"


def _other(command: str, *args: str):
    def prepare(w):
        out = w.root / LONG_NAME if command == "demo" else _deep(w.root, 4060)
        return [command, *args, "-o", out], out
    return prepare


_LOCKED = f"expected at most {4095 - LOCK_BYTES - INSIDE_BYTES} bytes"
LONG_CASES = [
    *[Case(f"calibrate, OUT {kind} too long", "names", _calibrate(kind), named=_EXPECTED[kind])
      for kind in ("name", "parent", "path")],
    Case("calibrate-many, OUT_ROOT/ds too long", "names", _many,
         named=("ds: the output folder's path is 4043 bytes long",)),
    Case("report, OUT path too long", "names", _into("report"),
         named=("path is 4040 bytes long", _LOCKED, "the lock file beside it")),
    Case("export, OUT path too long", "names", _into("export", "--format", "camera-info"),
         named=("path is 4040 bytes long", _LOCKED)),
    Case("demo, OUT name too long", "names", _other("demo"), named=_EXPECTED["name"]),
    Case("experiment, OUT path too long", "names", _other("experiment", "noise", "--trials", "1"),
         named=("path is 4060 bytes long", _LOCKED)),
]
