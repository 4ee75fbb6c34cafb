"""A package's public names imported on first use (PEP 562), for the packages whose modules
are heavy to import (``multieye.imaging``: OpenCV; ``multieye.solvers`` and
``multieye.pipeline``: SciPy), so that a command can start its detection's workers before
it imports them (issue 21).

Synopsis
--------
>>> from multieye.core.lazy_names import lazy_names
>>> __getattr__, __dir__ = lazy_names(__name__, {"solve": ".registry"})  # doctest: +SKIP
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Mapping
from importlib import import_module

__all__ = ["lazy_names"]


def lazy_names(package: str, where: Mapping[str, str]
               ) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """The module-level ``__getattr__`` and ``__dir__`` of ``package``.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    where : mapping of str to str
        Public name -> the module that defines it: absolute (``multieye.core.lens``) or
        relative to ``package`` (``.registry``).  The name is imported from it when first
        read, then kept in the package's namespace.

    Returns
    -------
    getattr, dir : callable
        For ``__getattr__, __dir__ = lazy_names(__name__, ...)``.  Any other public name is
        looked up as a submodule of ``package``, as when the package imported them all;
        otherwise ``AttributeError``.
    """

    def __getattr__(name: str) -> object:
        if name in where:
            value = getattr(import_module(where[name], package), name)
            setattr(sys.modules[package], name, value)
            return value
        if not name.startswith("_"):   # a submodule, as when this package imported them all
            try:
                return import_module(f".{name}", package)
            except ModuleNotFoundError as exc:
                if exc.name != f"{package}.{name}":
                    raise
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(where))

    return __getattr__, __dir__
