"""Test modules share helpers through helper modules (tests/*.py without the test_ prefix) or
fixtures, never by importing another test module or the ``tests`` package: such an import only
resolves when pytest runs from the repository root (issue 32), and collecting a test module
twice runs its tests twice."""

from __future__ import annotations

import ast
from pathlib import Path

TESTS = Path(__file__).resolve().parent


def _imported_modules(path: Path) -> list[tuple[int, str]]:
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.append((node.lineno, node.module))
        elif isinstance(node, ast.ImportFrom):              # relative: from . import test_x
            found += [(node.lineno, "." + (node.module or alias.name)) for alias in node.names]
    return found


def _offending(module: str) -> bool:
    parts = module.lstrip(".").split(".")
    return parts[0] == "tests" or any(p.startswith("test_") for p in parts)


def test_no_test_module_imports_a_test_module_or_the_tests_package():
    bad = [f"{path.relative_to(TESTS)}:{line}: imports {module}"
           for path in sorted(TESTS.rglob("*.py")) if "data" not in path.relative_to(TESTS).parts
           for line, module in _imported_modules(path) if _offending(module)]
    assert not bad, "shared test helpers belong in a helper module or a fixture:\n" + "\n".join(bad)


def test_the_guard_sees_each_form_of_the_import(tmp_path):
    sample = tmp_path / "test_sample.py"
    sample.write_text("import tests.imaging.helpers\nfrom tests.imaging.test_x import f\n"
                      "from test_export import make_run\nfrom . import test_y\nimport test_z\n"
                      "from export_runs import make_run\nimport numpy\n")
    assert [m for _, m in _imported_modules(sample) if _offending(m)] == [
        "tests.imaging.helpers", "tests.imaging.test_x", "test_export", ".test_y", "test_z"]
