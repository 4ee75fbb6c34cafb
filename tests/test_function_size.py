"""Every function of the package is short enough to read and takes few enough parameters to
call (docs/architecture.md, "Rules the suite enforces"): at most 100 lines (its docstring
counted) and 8 parameters (``self``/``cls`` not counted, ``*args`` and ``**kw`` counted as
one each); the stages of ``pipeline/run.py`` at most 60 lines.  Options that would take more
parameters go into a frozen dataclass taken as one argument (``Options``, ``RefineOptions``,
``ConsensusOptions``), its fields also accepted as keywords.
"""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "multieye"

MAX_LINES = 100
MAX_PARAMETERS = 8
MAX_STAGE_LINES = 60


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
