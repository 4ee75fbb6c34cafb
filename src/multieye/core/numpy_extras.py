"""numpy's subpackages that multieye does not use loaded on first use in a command's process.

SciPy 1.15 and later (its vendored ``array_api_compat``) copy every public name of numpy
when any SciPy subpackage is first imported (``scipy._lib._util``, which ``scipy.linalg``,
``scipy.sparse`` and ``scipy.special`` import): ``hasattr(numpy, name)`` for each name of
``dir(numpy)``, which imports numpy's lazily loaded subpackages, ``numpy.f2py`` (its Fortran
wrapper generator, which imports ``charset_normalizer``) and ``numpy.testing`` (which
imports ``unittest`` and ``importlib.metadata``), ``numpy.ma`` and ``numpy.polynomial``
among them.  Nothing of multieye uses them; they cost 0.05-0.08 CPU-s of every ``multieye
calibrate`` (``python -X importtime``, scipy 1.17.1, numpy 2.4; docs/results/peers.md).
matplotlib uses ``numpy.ma``: where the command draws figures it loads then.

:func:`defer_numpy_extras` puts them in ``sys.modules`` as lazy modules
(:class:`importlib.util.LazyLoader`): the same module objects, executed when one of their
attributes is first read, so whoever uses them gets them whole, only later.  It is for a
process multieye owns (the command line), not for a library user's, whose numpy it would
change.

Synopsis
--------
>>> from multieye.core.numpy_extras import defer_numpy_extras
>>> defer_numpy_extras()          # after numpy's import, before SciPy's      # doctest: +SKIP
"""

from __future__ import annotations

import importlib.util
import sys

__all__ = ["defer_numpy_extras", "DEFERRED"]

#: numpy's subpackages loaded on first use (what no stage of multieye reads; numpy.random,
#: which SciPy reads at its import, is not among them).
DEFERRED = ("numpy.f2py", "numpy.testing", "numpy.ma", "numpy.polynomial")


def defer_numpy_extras(modules: tuple[str, ...] = DEFERRED) -> tuple[str, ...]:
    """Make each of ``modules`` (numpy subpackages) a lazy module, unless it is imported already.

    Imports numpy (a command calls this once numpy is imported).  Returns the names made lazy
    (those already imported, or that numpy lacks, are left alone)."""
    import numpy  # noqa: PLC0415 (the caller has imported it already; no import at start-up)

    deferred = []
    for name in modules:
        if name in sys.modules:
            continue
        spec = importlib.util.find_spec(name)
        if spec is None or spec.loader is None or not hasattr(spec.loader, "exec_module"):
            continue
        spec.loader = importlib.util.LazyLoader(spec.loader)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
        # numpy's own attribute, so that ``numpy.f2py`` and ``import numpy.f2py as f2py``
        # find the module instead of numpy's __getattr__, which would import it
        setattr(numpy, name.rpartition(".")[2], module)
        deferred.append(name)
    return tuple(deferred)
