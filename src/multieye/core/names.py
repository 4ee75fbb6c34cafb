"""Camera names as file names: the rule rig.yaml's names follow, and a safe form for others.

A camera's name becomes a file name in the outputs (``OUT/intrinsics/<camera>.yaml``,
``OUT/export/camera_info/<camera>.yaml``; docs/outputs.md, section 1), so a name that is not
a plain file name on every common system (a ``/`` or ``..`` leading out of the folder, a
control character, 5000 characters) is refused where rig.yaml gives it
(:func:`camera_name_problem`), and a name read from another file (``calibration.json`` given
to ``multieye report`` or ``multieye export``) is reduced to a safe form (:func:`file_stem`);
two cameras whose files would be one file are refused (:func:`file_stems`).

>>> camera_name_problem("front left") is None, camera_name_problem("../x")
(True, "holds '/'")
>>> file_stem("front left"), file_stem("../../etc/passwd")
('front left', '_.__._etc_passwd')
"""

from __future__ import annotations

import re
import unicodedata
from collections.abc import Iterable
from typing import Protocol

from multieye.core.errors import InputError

__all__ = ["MAX_NAME_CHARS", "MAX_NAME_BYTES", "NAME_RULE", "Named", "camera_name_problem",
           "file_stem", "file_stems", "same_file_key"]

#: Longest camera name, in characters and in bytes of UTF-8 (file names hold 255 bytes).
MAX_NAME_CHARS = 100
MAX_NAME_BYTES = 200
#: Characters no camera name may hold: path separators and what Windows refuses in names.
_FORBIDDEN = frozenset('/\\:*?"<>|')
#: What a camera name may be, for messages and docs/rig-yaml.md.
NAME_RULE = (f"1 to {MAX_NAME_CHARS} printable characters ({MAX_NAME_BYTES} bytes of UTF-8), "
             "none of / \\ : * ? \" < > |, no '..', not starting with '.' and not starting or "
             "ending with white space")


def _bad_char(ch: str) -> bool:
    return ch in _FORBIDDEN or not ch.isprintable()


def camera_name_problem(name, taken: dict | None = None) -> str | None:
    """Why ``name`` cannot be a camera name, or None when it can (:data:`NAME_RULE`).

    Parameters
    ----------
    name : object
        The name as a file gave it.
    taken : dict, optional
        The names seen so far (:func:`same_file_key` -> name), updated: a name that would be
        one file with one of them on macOS or Windows (equal but for case or Unicode
        normalisation) is refused.

    Returns
    -------
    str or None
        A phrase to follow the name in a message (``"holds '/'"``), or None.
    """
    if not isinstance(name, str):
        return f"is a {type(name).__name__}, not text"
    if not name:
        return "is empty"
    if len(name) > MAX_NAME_CHARS:
        return f"is {len(name)} characters long"
    bad = next((ch for ch in name if _bad_char(ch)), None)
    if bad is not None:
        return f"holds {bad!r}"
    if len(name.encode("utf-8")) > MAX_NAME_BYTES:
        return f"is {len(name.encode('utf-8'))} bytes long in UTF-8"
    if name.startswith("."):
        return "starts with '.'"
    if ".." in name:
        return "holds '..'"
    if name != name.strip():
        return "starts or ends with white space"
    if taken is not None:
        other = taken.setdefault(same_file_key(name), name)
        if other != name:
            return (f"would be one file with camera {other!r} on macOS and Windows (names "
                    "must differ in more than case)")
    return None


def file_stem(name: str) -> str:
    """``name`` as a file name without extension: unchanged when it is a valid camera name
    (:func:`camera_name_problem`), else reduced: each character that a name may not hold (and
    white space at either end) becomes ``_``, each ``.`` followed by another ``.`` or at the
    start becomes ``_``, and the name is cut to :data:`MAX_NAME_CHARS` characters and
    :data:`MAX_NAME_BYTES` bytes; an empty name becomes ``_``.

    The result always passes :func:`camera_name_problem`.
    """
    name = str(name)
    if camera_name_problem(name) is None:
        return name
    chars = ["_" if _bad_char(ch) else ch for ch in name[:MAX_NAME_CHARS]]
    while len("".join(chars).encode("utf-8")) > MAX_NAME_BYTES:
        chars.pop()
    stem = re.sub(r"\.(?=\.)", "_", "".join(chars))
    stem = "_" + stem[1:] if stem.startswith(".") else stem
    left = len(stem) - len(stem.lstrip())
    right = len(stem) - len(stem.rstrip())
    stem = "_" * left + stem.strip() + "_" * right if stem.strip() else "_" * len(stem)
    return stem or "_"


def same_file_key(name: str) -> str:
    """The key under which two names are one file on some system: Unicode NFC, case folded
    (macOS and Windows compare names that way)."""
    return unicodedata.normalize("NFC", name).casefold()


class Named(Protocol):
    """Anything with a ``name`` (a camera's record, its data, its rig.yaml entry)."""

    name: str


def file_stems(cameras: Iterable[Named], *, what: str = "file") -> dict[str, str]:
    """:func:`file_stem` of every camera's name, refusing two names that would be one file.

    Parameters
    ----------
    cameras : iterable of objects with a ``name`` (str)
    what : str
        What the files are, for the message (``"export/camera_info/<camera>.yaml"``).

    Returns
    -------
    dict
        name -> stem, in the order given.

    Raises
    ------
    InputError
        Two names whose stems are equal, or equal but for case or Unicode normalisation.
    """
    stems: dict[str, str] = {}
    seen: dict[str, str] = {}
    for name in (c.name for c in cameras):
        stem = file_stem(name)
        key = same_file_key(stem)
        if key in seen:
            raise InputError(f"cameras {seen[key]!r} and {name!r} would be one {what} "
                             f"({stem!r}): give them names that differ in more than case and "
                             "in more than characters a file name cannot hold")
        seen[key] = name
        stems[name] = stem
    return stems
