"""A package's names imported on first use (multieye.core.lazy_names), as imaging, solvers
and pipeline use it."""

from __future__ import annotations

import subprocess
import sys

import pytest

from multieye.core.lazy_names import lazy_names


def test_each_lazy_package_gives_its_names_its_submodules_and_refuses_the_rest():
    import multieye.imaging as imaging
    import multieye.pipeline as pipeline
    import multieye.solvers as solvers
    from multieye.core.lens import project_points
    from multieye.pipeline.calibrate_dataset import calibrate
    from multieye.solvers.registry import solve

    assert pipeline.calibrate is calibrate and solvers.solve is solve
    assert imaging.project_points is project_points
    assert pipeline.run.__name__ == "multieye.pipeline.run"      # a submodule, by attribute
    assert {"calibrate", "calibrate_rig"} <= set(dir(pipeline))
    for package in (imaging, pipeline, solvers):
        with pytest.raises(AttributeError, match="no attribute 'not_a_name'"):
            _ = package.not_a_name


def test_a_name_is_imported_only_when_read():
    code = ("import sys, multieye.solvers as s; a = 'multieye.solvers.registry' in sys.modules; "
            "s.solve; print(a, 'multieye.solvers.registry' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "True"]


def test_a_missing_module_behind_a_name_is_not_hidden():
    getattr_, _ = lazy_names(__name__, {"gone": ".no_such_module_here"})
    with pytest.raises(ModuleNotFoundError):
        getattr_("gone")
