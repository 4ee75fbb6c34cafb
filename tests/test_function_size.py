"""Every function of the package is short enough to read and takes few enough parameters to
call (docs/architecture.md, "Rules the suite enforces"): at most 100 lines (its docstring
counted) and 8 parameters (``self``/``cls`` not counted, ``*args`` and ``**kw`` counted as
one each); the stages of ``pipeline/run.py`` at most 60 lines.  Options that would take more
parameters go into a frozen dataclass taken as one argument (``Options``, ``RefineOptions``,
``ConsensusOptions``), its fields also accepted as keywords.

The setup and the camera names are not threaded through the package (issue 18): a function
gets them from the typed object it already has (the pipeline's ``Problem`` and its ``Rig``,
``Measurements``, ``ImageProblem``, a record, an options object, a mapping keyed by camera
name).  At most a handful of signatures take them as a parameter of their own (named
``setup`` / ``setup_name`` or ``names`` / ``camera_names``): the public entry points whose
array contract has them (``solve``, ``check_measurements``, ``refine_images``, the
simulators) and the few the parallel work still holds.
"""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "multieye"

MAX_LINES = 100
MAX_PARAMETERS = 8
MAX_STAGE_LINES = 60
#: Parameters that carry the setup string or a sequence of camera names, and how many
#: functions may take each kind at most.
THREADED = {"setup": ("setup", "setup_name"), "names": ("names", "camera_names")}
MAX_THREADED = 5


def _functions(path: Path):
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            yield node


def _parameters(fn: ast.FunctionDef) -> list[str]:
    a = fn.args
    names = [p.arg for p in a.posonlyargs + a.args + a.kwonlyargs]
    names += [p.arg for p in (a.vararg, a.kwarg) if p is not None]
    return [n for n in names if n not in ("self", "cls")]


def _lines(fn: ast.FunctionDef) -> int:
    return fn.end_lineno - fn.lineno + 1


def _where(path: Path, fn: ast.FunctionDef) -> str:
    return f"{path.relative_to(SRC.parent)}:{fn.lineno} {fn.name}"


def test_no_function_over_100_lines():
    long = [f"{_where(p, fn)} ({_lines(fn)} lines)" for p in sorted(SRC.rglob("*.py"))
            for fn in _functions(p) if _lines(fn) > MAX_LINES]
    assert long == []


def test_no_function_over_8_parameters():
    wide = [f"{_where(p, fn)} ({len(_parameters(fn))} parameters)"
            for p in sorted(SRC.rglob("*.py")) for fn in _functions(p)
            if len(_parameters(fn)) > MAX_PARAMETERS]
    assert wide == []


def _threaded(paths) -> dict[str, list[str]]:
    """Per kind of :data:`THREADED`, the functions with a parameter of that kind."""
    out: dict[str, list[str]] = {kind: [] for kind in THREADED}
    for p in paths:
        for fn in _functions(p):
            params = set(_parameters(fn))
            for kind, spellings in THREADED.items():
                if params & set(spellings):
                    out[kind].append(_where(p, fn) if p.is_relative_to(SRC)
                                     else f"{p.name}:{fn.lineno} {fn.name}")
    return out


def test_setup_and_camera_names_are_not_threaded_through_the_package():
    found = _threaded(sorted(SRC.rglob("*.py")))
    assert {k: v for k, v in found.items() if len(v) > MAX_THREADED} == {}, found


def test_pipeline_stages_are_short():
    path = SRC / "pipeline" / "run.py"
    long = [f"{_where(path, fn)} ({_lines(fn)} lines)" for fn in _functions(path)
            if _lines(fn) > MAX_STAGE_LINES]
    assert long == []


def test_the_checks_see_a_long_and_a_wide_function(tmp_path):
    """The measures above count what they claim: a function of 101 lines and one of 9
    parameters are found."""
    body = "\n".join(["    x = 0"] * 99)
    src = tmp_path / "m.py"
    src.write_text(f"def long():\n{body}\n    return x\n\n"
                   "def wide(self, a, b, c, d, e, f, g, *h, i, **j):\n    pass\n")
    fns = {fn.name: fn for fn in _functions(src)}
    assert _lines(fns["long"]) == 101
    assert len(_parameters(fns["wide"])) == 10


def test_the_count_of_threaded_parameters_sees_every_spelling(tmp_path):
    """``setup``, ``setup_name``, ``names`` and ``camera_names`` count, keyword-only and
    positional alike, once per function; other parameters do not."""
    src = tmp_path / "m.py"
    src.write_text("def a(setup, names): pass\n"
                   "def b(x, *, setup_name='eye-to-base'): pass\n"
                   "class C:\n    def c(self, camera_names=None, names=None): pass\n"
                   "def d(rig, problem, name): pass\n")
    found = _threaded([src])
    assert [w.rsplit(" ", 1)[1] for w in found["setup"]] == ["a", "b"]
    assert sorted(w.rsplit(" ", 1)[1] for w in found["names"]) == ["a", "c"]
