"""The type and presence checks of ``rig.yaml`` (:mod:`multieye.io.rig`): each raises a
:class:`DatasetError` at the line of the key concerned, naming the dotted key path and what
was expected."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping

from multieye.io.yamlfile import YamlDocument, shown

__all__ = ["Checker"]

_FLOAT_TEXT = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+$")


class Checker:
    """Type and presence checks that raise at the line of the key concerned."""

    def __init__(self, doc: YamlDocument):
        self.doc = doc
        self.folder = doc.path.parent

    def error(self, message, keys):
        return self.doc.error(message, *keys)

    def mapping(self, value, keys, allowed, required=()):
        if not isinstance(value, Mapping):
            raise self.error(f"expected a mapping, got {type(value).__name__}", keys)
        for key in value:
            if key not in allowed:
                raise self.error(f"unknown key; expected one of {', '.join(allowed)}",
                                 keys + (key,))
        for key in required:
            if key not in value:
                raise self.error(f"missing key {key!r}", keys)
        return value

    def string(self, value, keys):
        if not isinstance(value, str) or not value.strip():
            raise self.error(f"expected a non-empty string, got {shown(value)}", keys)
        return value.strip()

    def boolean(self, value, keys) -> bool:
        if not isinstance(value, bool):
            raise self.error(f"expected true or false, got {shown(value)}", keys)
        return value

    def choice(self, value, keys, options):
        if isinstance(value, (list, dict)) or value not in options:
            raise self.error(f"expected one of {', '.join(options)}, got {shown(value)}", keys)
        return value

    def number(self, value, keys, *, positive=False, integer=False, maximum=None, unit=""):
        """A finite number (``integer``: an int), > 0 if ``positive``, and at most ``maximum``
        (in magnitude when it may be negative); ``unit`` names it in the message."""
        ok = isinstance(value, int) if integer else isinstance(value, (int, float))
        ok = ok and not isinstance(value, bool) and math.isfinite(value)
        ok = ok and (not positive or value > 0)
        ok = ok and (maximum is None or (value if positive else abs(value)) <= maximum)
        if not ok:
            kind = "integer" if integer else "number"
            unit = f" {unit}" if unit else ""
            if maximum is None:
                what = f"a {'positive ' if positive else ''}{kind}{unit}"
            elif positive:
                what = f"a positive {kind} of at most {maximum:g}{unit}"
            else:
                what = f"a {kind} between {-maximum:g} and {maximum:g}{unit}"
            hint = ""
            if isinstance(value, str) and _FLOAT_TEXT.match(value.strip()):
                hint = (" (YAML 1.1 reads an exponent without a dot and a sign as text: write "
                        "1.0e-3, not 1e-3)")
            raise self.error(f"expected {what}, got {shown(value)}{hint}", keys)
        return value if integer else float(value)

    def path(self, value, keys, kind):
        named = self.folder / self.string(value, keys)
        try:
            p = named.resolve()
        except (RuntimeError, OSError) as exc:     # a link loop (RuntimeError before 3.13)
            raise self.error(f"{kind} is a symbolic link loop (or cannot be resolved: "
                             f"{getattr(exc, 'strerror', None) or 'loop'}): {named}",
                             keys) from None
        except ValueError as exc:                  # a NUL byte
            raise self.error(f"invalid path {shown(str(named))}: {exc}", keys) from None
        if not p.exists():
            raise self.error(f"{kind} not found: {p}", keys)
        if kind == "folder" and not p.is_dir():
            raise self.error(f"expected a folder, found a file: {p}", keys)
        if kind == "file" and p.is_dir():
            raise self.error(f"expected a file, found a folder: {p}", keys)
        return p
