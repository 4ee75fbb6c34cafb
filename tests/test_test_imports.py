"""Test modules share helpers through helper modules (tests/*.py without the test_ prefix) or
fixtures, never by importing another test module or the ``tests`` package: such an import only
resolves when pytest runs from the repository root (issue 32), and collecting a test module
twice runs its tests twice. The helpers' folder goes on sys.path in conftest.py alone: a test
module that puts it there itself makes the others' imports work only when it is collected first
(``--import-mode=importlib`` on one file failed to collect)."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

TESTS = Path(__file__).resolve().parent
IMPORTERS = {"import_module", "__import__", "spec_from_file_location", "run_path", "run_module",
             "SourceFileLoader", "importorskip"}


def _called_name(node: ast.Call) -> str:
    func = node.func
    return func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")


def _imported_modules(path: Path) -> list[tuple[int, str]]:
    """(line, module) for every import of ``path``: statements (``from a import b`` gives ``a``
    and ``a.b``; relative ones start with a dot) and calls that import by a string
    (importlib.import_module, __import__, spec_from_file_location, runpy, importorskip), a
    file name given as its module name; ``sys.path`` and ``site.addsitedir`` as ``sys.path``."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            head = "." * node.level + (node.module or "")
            found += [(node.lineno, head)] if node.module else []
            found += [(node.lineno, f"{head}.{alias.name}" if node.module
                       else head + alias.name) for alias in node.names]
        elif isinstance(node, ast.Call) and _called_name(node) in IMPORTERS:
            found += [(node.lineno, c.value.removesuffix(".py").replace("/", ".").replace("\\", "."))
                      for c in ast.walk(node) if isinstance(c, ast.Constant) and isinstance(c.value, str)]
        elif (isinstance(node, ast.Attribute) and node.attr == "path"
              and getattr(node.value, "id", "") == "sys") or (
                isinstance(node, ast.Call) and _called_name(node) == "addsitedir"):
            found.append((node.lineno, "sys.path"))
    return found


def _offending(module: str, conftest: bool = False) -> bool:
    if module == "sys.path":
        return not conftest
    if module.startswith("."):                        # tests is no package: relative never resolves
        return True
    parts = [p for p in module.split(".") if p]
    return bool(parts) and (parts[0] == "tests" or any(p.startswith("test_") for p in parts))


def test_no_test_module_imports_a_test_module_or_the_tests_package():
    bad = [f"{path.relative_to(TESTS)}:{line}: imports {module}"
           for path in sorted(TESTS.rglob("*.py")) if "data" not in path.relative_to(TESTS).parts
           for line, module in _imported_modules(path) if _offending(module, path.name == "conftest.py")]
    assert not bad, "shared test helpers belong in a helper module or a fixture:\n" + "\n".join(bad)


def test_the_guard_sees_each_form_of_the_import(tmp_path):
    sample = tmp_path / "test_sample.py"
    sample.write_text(
        "import tests.imaging.helpers\nfrom tests.imaging.test_x import f\n"
        "from test_export import make_run\nfrom . import test_y\nimport test_z\n"
        "from tests import small_dataset\nfrom imaging import test_w\nfrom .wall_rig import g\n"
        "import importlib, runpy, sys, site\nimportlib.import_module('tests.cli')\n"
        "__import__('test_v')\nimportlib.util.spec_from_file_location('m', 'imaging/test_u.py')\n"
        "runpy.run_path(str(Path(__file__).parent / 'test_t.py'))\n"
        "sys.path.insert(0, '..')\nsite.addsitedir('..')\n"
        "from export_runs import make_run\nimport numpy\nimport os.path\n"
        "pytest.importorskip('yaml')\nimportlib.import_module('multieye.cli')\n")
    offending = sorted({m for _, m in _imported_modules(sample) if _offending(m)})
    assert offending == sorted({
        "tests.imaging.helpers", "tests.imaging.test_x", "tests.imaging.test_x.f", "test_export",
        "test_export.make_run", ".test_y", "test_z", "tests", "tests.small_dataset", "imaging.test_w",
        ".wall_rig", ".wall_rig.g", "sys.path", "tests.cli", "test_v", "imaging.test_u", "test_t"})
    assert not any(_offending(m, conftest=True) for m in ("sys.path", "export_runs", "numpy"))


def test_one_test_file_collects_from_another_folder_in_every_import_mode(tmp_path):
    """pytest started elsewhere on single test files that use helper modules (no test module
    collected before them puts anything on sys.path): every mode collects them."""
    files = [str(TESTS / f) for f in ("outputs/test_export_mrcal.py", "optimize/test_clusters.py")]
    env = {**os.environ, "PYTHONPATH": str(TESTS.parent / "src")}
    for mode in ("prepend", "importlib"):
        res = subprocess.run([sys.executable, "-m", "pytest", "-q", "--co", "-p", "no:cacheprovider",
                              f"--import-mode={mode}", "--rootdir", str(tmp_path), *files],
                             cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
        assert res.returncode == 0 and " collected" in res.stdout, (mode, res.stdout[-2000:])
