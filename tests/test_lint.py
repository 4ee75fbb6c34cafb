"""The linter's rules (pyproject.toml, [tool.ruff]) hold on src and tests, and every import
left inside a function says why it is there."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def test_ruff_passes_on_src_and_tests():
    pytest.importorskip("ruff", reason="ruff is in the test extra: pip install -e '.[test]'")
    res = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", "src", "tests"],
                         cwd=REPO, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stdout + res.stderr


def test_every_import_inside_a_function_gives_its_reason():
    """``# noqa: PLC0415`` (ruff's import-outside-top-level) is followed by the reason: an
    optional or heavy dependency, or instant start-up."""
    bare = []
    for path in sorted((REPO / "src").rglob("*.py")):
        for n, line in enumerate(path.read_text().splitlines(), 1):
            m = re.search(r"#\s*noqa:\s*PLC0415\b(.*)$", line)
            if m and len(re.findall(r"[a-z]{2,}", m.group(1))) < 2:
                bare.append(f"{path.relative_to(REPO)}:{n}")
    assert bare == []
