"""Checks of the arguments of the public functions, so that a wrong argument (None, a complex
or ragged array, a string where a number belongs, names of the wrong length, a non-positive
iteration count) is an :class:`~multieye.core.errors.InputError` that says what was expected,
never a TypeError or a numpy traceback from deep inside.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import fields, is_dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

import difflib

from multieye.core.errors import InputError
from multieye.core.geometry import is_rigid

__all__ = ["real_array", "real_number", "positive_int", "camera_names", "one_of", "as_path",
           "did_you_mean", "with_fields", "transform"]


def _kind(value: Any) -> str:
    if isinstance(value, np.ndarray):
        return f"an array of dtype {value.dtype} and shape {value.shape}"
    return type(value).__name__


def real_array(value: Any, name: str, *, shape: tuple[int | None, ...] | None = None,
               expected: str | None = None) -> np.ndarray:
    """``value`` as a float64 array, or an InputError naming ``name`` and what was expected.

    Parameters
    ----------
    value : array_like
    name : str
        How the message names the argument.
    shape : tuple of int or None, optional
        Required shape; None entries take any length.
    expected : str, optional
        What the message says is expected (default: from ``shape``).
    """
    want = expected or ("an array of real numbers" if shape is None else
                        "a real array of shape (" + ", ".join("N" if n is None else str(n)
                                                              for n in shape)
                        + ("," if len(shape) == 1 else "") + ")")
    if value is None:
        raise InputError(f"{name} is None; expected {want}")
    if isinstance(value, (str, bytes, dict, set)):
        raise InputError(f"{name} must be {want}, got {_kind(value)}")
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be {want}: {exc}") from None
    if np.iscomplexobj(arr):
        raise InputError(f"{name} must be real, got complex numbers ({_kind(arr)})")
    if arr.dtype.kind not in "fiub":
        try:
            arr = arr.astype(np.float64)
        except (TypeError, ValueError):
            raise InputError(f"{name} must be {want}, got {_kind(arr)}") from None
    arr = arr.astype(np.float64, copy=False)
    if shape is not None and (arr.ndim != len(shape) or any(
            n is not None and n != k for n, k in zip(shape, arr.shape))):
        raise InputError(f"{name} must be {want}, got shape {arr.shape}")
    return arr


def real_number(value: Any, name: str, *, positive: bool = False, finite: bool = True,
                allow_none: bool = False) -> float | None:
    """A real number (``positive``: > 0; ``finite``: not NaN or inf), as a float."""
    if value is None and allow_none:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InputError(f"{name} must be a {'positive ' if positive else ''}number, got "
                         f"{value!r}")
    value = float(value)
    if (finite and not math.isfinite(value)) or (positive and not value > 0):
        raise InputError(f"{name} must be a {'positive' if positive else 'finite'} number, "
                         f"got {value!r}")
    return value


def positive_int(value: Any, name: str) -> int:
    """A positive integer (``max_iter``, ``processes``), or an InputError."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise InputError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def camera_names(names: Any, count: int, what: str = "cameras") -> tuple[str, ...] | None:
    """``names`` as a tuple of ``count`` distinct non-empty strings, or None when not given."""
    if names is None:
        return None
    if isinstance(names, (str, bytes)) or not isinstance(names, Sequence | np.ndarray):
        raise InputError(f"names must be a list of {count} strings (one per {what[:-1]}), got "
                         f"{names!r}")
    names = list(names)
    if len(names) != count:
        raise InputError(f"names has {len(names)} entries but there are {count} {what}; give "
                         f"one name per {what[:-1]}")
    if not all(isinstance(n, str) and n for n in names):
        raise InputError(f"names must be non-empty strings, got {names!r}")
    if len(set(names)) != len(names):
        raise InputError(f"names must be distinct, got {names!r}")
    return tuple(names)


def one_of(value: Any, name: str, options: Sequence[str]) -> str:
    """``value`` if it is one of ``options`` (strings), else an InputError listing them."""
    if not isinstance(value, str) or value not in options:
        raise InputError(f"{name} must be one of {', '.join(options)}, got {value!r}"
                         f"{did_you_mean(value, options)}")
    return value


def did_you_mean(word: Any, options: Sequence[str]) -> str:
    """``" (did you mean 'spacing'?)"`` when one of ``options`` is close to ``word`` (a typo,
    another case, ``_`` for ``-``), else ``""``; by :func:`difflib.get_close_matches`."""

    if not isinstance(word, str) or not word:
        return ""
    by_folded = {o.lower().replace("-", "_"): o for o in options}
    folded = word.lower().replace("-", "_")
    if folded in by_folded and by_folded[folded] != word:
        return f" (did you mean {by_folded[folded]!r}?)"
    close = difflib.get_close_matches(folded, list(by_folded), n=1, cutoff=0.75)
    return f" (did you mean {by_folded[close[0]]!r}?)" if close else ""


def as_path(value: Any, name: str = "path") -> Path:
    """``value`` as a Path, or an InputError when it is not a path (None, a number, a list)."""
    if isinstance(value, (str, os.PathLike)) and not isinstance(value, bytes):
        text = os.fspath(value)
        if isinstance(text, str) and text and "\0" not in text:
            return Path(text)
    raise InputError(f"{name} must be a path (str or os.PathLike), got {value!r}")


def with_fields(options: Any, kw: Mapping[str, Any], kind: type, what: str) -> Any:
    """``options`` (a frozen dataclass of type ``kind``) with the fields in ``kw`` replaced:
    the one way a public function takes its options as an object or as keyword arguments.
    InputError for anything else than a ``kind`` or for an unknown field (instead of
    dataclasses' TypeError), naming ``what``."""
    if not isinstance(options, kind) or not is_dataclass(options):
        raise InputError(f"{what} must be a multieye {kind.__name__}, got "
                         f"{type(options).__name__}")
    names = [f.name for f in fields(options)]
    unknown = sorted(set(kw) - set(names))
    if unknown:
        raise InputError(f"unknown option {', '.join(unknown)}; the options are "
                         f"{', '.join(names)}")
    return replace(options, **kw) if kw else options


def transform(value: Any, what: str, *, count: int | None = None, rigid: bool = False
              ) -> np.ndarray:
    """``value`` as a finite 4x4 transform (or ``count`` of them, one per camera), or an
    InputError naming ``what``: the one check of a transform a caller passes in.

    Parameters
    ----------
    value : array_like, shape (4, 4), or (count, 4, 4) with ``count``
    what : str
        How the message names the argument.
    count : int, optional
        The number of transforms expected (one per camera).
    rigid : bool
        Also require rigid transforms (:func:`multieye.core.geometry.is_rigid`).
    """
    want = ("a finite 4x4 transform" if count is None
            else f"{count} finite 4x4 transforms (one per camera)")
    T = real_array(value, what, expected=want)
    if T.shape != ((4, 4) if count is None else (count, 4, 4)) or not np.all(np.isfinite(T)):
        raise InputError(f"{what} must be {want}, got shape {T.shape}")
    if rigid and not np.all(is_rigid(T)):
        raise InputError(f"{what} is not a rigid transform")
    return T
