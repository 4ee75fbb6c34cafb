"""numpy.f2py and numpy.testing made lazy modules (multieye.core.numpy_extras): SciPy's first
import no longer runs them, and whoever reads them later gets them whole.  Each case runs
in a fresh interpreter (the test session has imported both)."""

from __future__ import annotations

import subprocess
import sys
import textwrap


def _run(code: str) -> str:
    run = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    return run.stdout.strip()


def test_scipy_imports_without_running_numpy_f2py_and_testing():
    out = _run("""
        import sys
        import numpy
        from multieye.core.numpy_extras import defer_numpy_extras
        print(*defer_numpy_extras())
        import scipy.linalg, scipy.sparse, scipy.special
        print(*[m for m in ("numpy.f2py.f2py2e", "numpy.testing._private.utils",
                            "charset_normalizer", "numpy.ma.core", "numpy.polynomial.polynomial")
                if m in sys.modules] or ["none"])
    """)
    assert out.splitlines() == ["numpy.f2py numpy.testing numpy.ma numpy.polynomial", "none"]


def test_the_deferred_modules_load_whole_on_first_use():
    out = _run("""
        import numpy
        from multieye.core.numpy_extras import defer_numpy_extras
        defer_numpy_extras()
        import scipy.linalg
        import numpy.testing as nt
        from numpy.testing import assert_array_equal
        nt.assert_allclose([1.0, 2.0], [1.0, 2.0])
        assert_array_equal(numpy.arange(3), [0, 1, 2])
        try:
            nt.assert_allclose(1.0, 2.0)
        except AssertionError:
            print("raised")
        print(callable(numpy.f2py.run_main), numpy.testing is nt)
        print(numpy.ma.masked_invalid([1.0, numpy.nan]).count(),
              numpy.polynomial.Polynomial([1.0, 2.0])(1.0))
        import matplotlib.figure           # imports numpy.ma: whole, as usual
        print(matplotlib.figure.Figure().add_subplot().plot([1, 2])[0].get_ydata().sum())
        print(defer_numpy_extras())     # already imported: left alone
    """)
    assert out.splitlines() == ["raised", "True True", "1 3.0", "3", "()"]
