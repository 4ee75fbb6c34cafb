"""Help texts that match what is written (issue 24, item 4): every ``--help`` ends with the
exit statuses its command can return, ``calibrate -o`` names the files a run writes, help
points to ``multieye docs`` (installed with the package) rather than to repository paths."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from click.testing import CliRunner

from multieye.cli import DOC_PAGES, main
from multieye.outputs.folder import KNOWN_FILES, MANIFEST

REPO = Path(__file__).resolve().parents[2]
COMMANDS = sorted(main.commands)


def _help(*args) -> str:
    res = CliRunner().invoke(main, [*args, "--help"], terminal_width=100)
    assert res.exit_code == 0, res.output
    return res.output


def _statuses(text: str) -> set[str]:
    block = text[text.index("Exit status:"):]
    return set(re.findall(r"^\s+(\d+|128\+N)\s", block, flags=re.M))


#: What each command can return besides signals: calibrate alone writes a result a
#: plausibility check may doubt (3); every command refuses bad input (2).
CAN_RETURN = {"calibrate": {"0", "2", "3"}, "calibrate-many": {"0", "2", "3"}}


@pytest.mark.parametrize("command", COMMANDS)
def test_every_help_ends_with_its_exit_statuses(command):
    text = _help(command)
    assert _statuses(text) == CAN_RETURN.get(command, {"0", "2"}) | {"128+N"}, text
    assert "docs/" not in text, "help points into the repository, which pip does not install"


def test_the_main_help_lists_every_status_and_the_docs_command():
    text = _help()
    assert _statuses(text) == {"0", "2", "3", "128+N"}
    assert "multieye docs rig-yaml" in text and "docs/" not in text


def test_calibrate_out_names_every_file_a_run_writes():
    text = " ".join(_help("calibrate").split())
    out_help = text[text.index("-o, --out"):text.index("--method")]
    top = {name.split("/")[0] + ("/" if "/" in name else "") for name in KNOWN_FILES
           if not name.startswith("export/")}
    for name in sorted(top | {"intrinsics/", MANIFEST}):
        assert name in out_help, (name, out_help)


def test_export_parent_frame_default_speaks_of_robot_frames():
    text = " ".join(_help("export").split())
    assert "base for pose: T_base_tool0" in text and "(body, or tool0)" in text


def test_docs_lists_and_prints_the_installed_pages():
    res = CliRunner().invoke(main, ["docs"])
    assert res.exit_code == 0
    assert [line.split()[0] for line in res.output.splitlines()] == list(DOC_PAGES)
    for name in DOC_PAGES:
        res = CliRunner().invoke(main, ["docs", name])
        assert res.exit_code == 0
        assert res.output == (REPO / "docs" / f"{name}.md").read_text(encoding="utf-8")
    res = CliRunner().invoke(main, ["docs", "rig.yaml"])
    assert res.exit_code == 2 and "rig-yaml" in res.output


def test_the_docs_ship_as_package_data():
    """The wheel's package data holds docs/*.md (src/multieye/docs links to docs/)."""
    text = (REPO / "pyproject.toml").read_text()
    assert '"docs/*.md"' in text
    link = REPO / "src" / "multieye" / "docs"
    assert link.resolve() == (REPO / "docs").resolve()
    assert {p.stem for p in (REPO / "docs").glob("*.md")} == set(DOC_PAGES)
