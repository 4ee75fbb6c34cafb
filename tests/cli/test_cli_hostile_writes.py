"""Hostile and unlucky input on the write side (issue 19, items 1 and 4): every case of
``tests/hostile_cases.py`` ends with an expected exit status, one error line naming what is
wrong, no traceback, nothing changed outside ``OUT`` (a sentinel folder of files that are
not multieye's, the lock, staging and backup names beside ``OUT``: snapshot before and
after), and ``OUT`` unchanged when the command is refused; and an output folder whose names are too
long for the file system, refused by every writing command before it runs (long_out_cases).
"""

from __future__ import annotations

import os

import pytest
from hostile_cases import CASES, make_template, make_work, run_case, snapshot
from long_out_cases import LONG_CASES

from multieye.outputs import folder as folder_mod


@pytest.fixture(scope="module")
def template(tmp_path_factory):
    return make_template(tmp_path_factory.mktemp("hostile-template"))


@pytest.mark.parametrize("case", CASES + LONG_CASES, ids=[c.name for c in CASES + LONG_CASES])
def test_hostile_case(case, template, tmp_path):
    work = make_work(tmp_path / "work", template)
    outcome = run_case(case, work)
    assert outcome.clean, (outcome.problem, outcome.code, outcome.stderr)
    assert not folder_mod._HELD                         # the lock let go in this process
    assert not [p.name for p in work.root.iterdir()
                if ".multieye-lock" in p.name and not p.is_symlink()
                and not case.name.startswith("lock file")], "lock file left behind"


def test_sentinel_snapshot_sees_a_change_through_a_link(template, tmp_path):
    """The judge is not blind: a write through a link into the sentinel is found."""
    work = make_work(tmp_path / "work", template)
    before = snapshot(work.root)
    (work.root / "link").symlink_to(work.sentinel / "victim.txt")
    with open(work.root / "link", "a") as f:
        f.write("x")
    after = snapshot(work.root)
    assert before["sentinel/victim.txt"] != after["sentinel/victim.txt"]


def test_every_class_has_cases():
    kinds = {c.kind for c in CASES}
    assert kinds == {"names", "links", "tracebacks"}
    assert sum(c.expect == (2,) for c in CASES) >= 50


@pytest.mark.skipif(not hasattr(os, "O_NOFOLLOW"), reason="needs O_NOFOLLOW")
def test_link_swapped_in_during_report_is_refused(template, tmp_path, monkeypatch):
    """A link put in place of OUT/figures after the checks at the start (a race) is found
    by the writer, which walks OUT with O_NOFOLLOW: nothing lands in the sentinel."""
    import shutil

    from multieye.outputs import report as report_mod
    from multieye.core.errors import DatasetError

    work = make_work(tmp_path / "work", template)
    real = report_mod.report_html

    def swap_then_render(*args, **kwargs):
        shutil.rmtree(work.out / "figures")
        (work.out / "figures").symlink_to(work.sentinel)
        return real(*args, **kwargs)

    monkeypatch.setattr(report_mod, "report_html", swap_then_render)
    before = snapshot(work.sentinel)
    with pytest.raises(DatasetError, match="figures: is a symbolic link"):
        report_mod.write_report(work.out)
    assert snapshot(work.sentinel) == before
