"""Reading text files at the file boundary, with errors that name the file and the line.

Every reader of a text format (TUM, CSV exports, YAML, JSON) goes through these helpers, so
that a missing file, a file that is not UTF-8, or a cell that is not a number produces the same
kind of message: ``path:line: what was expected, what was found``.
"""

from __future__ import annotations

import itertools
import math
import os
import re
import warnings
from array import array
from collections.abc import Iterator, Mapping, Sequence

import numpy as np

from multieye.core.arguments import as_path
from multieye.core.errors import DatasetError
from multieye.core.limits import MAX_JSON_BYTES, MAX_TABLE_BYTES
from multieye.core.regular_files import open_bounded_text, read_bounded
import json

__all__ = [
    "read_text",
    "data_lines",
    "split_fields",
    "parse_float",
    "read_number_rows",
    "read_json",
    "text_lines",
    "count_lines",
    "line_blocks",
    "NumberTable",
    "LENGTH_UNITS",
    "length_scale",
]

#: Length units accepted at the file boundary, and their size in metres.
LENGTH_UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}

_FIELD_SEP = re.compile(r"[,;\s]+")
_DECIMAL_COMMA = re.compile(r"\d,\d")


def read_text(path: str | os.PathLike, *, what: str = "file",
              max_bytes: int = MAX_TABLE_BYTES) -> str:
    """Whole content of a UTF-8 text file (a BOM is dropped).

    Parameters
    ----------
    path : path-like
    what : str
        How the message names the file when it is missing (``"trajectory file"``).
    max_bytes : int
        Refuse a larger file, counted while reading (default
        :data:`~multieye.core.limits.MAX_TABLE_BYTES`; small formats such as YAML pass less).

    Raises
    ------
    DatasetError
        Missing file, not a regular file (a folder, a device, a FIFO, a socket), unreadable,
        larger than ``max_bytes``, or not UTF-8 (with the 1-based line of the first bad byte).
    """
    p = as_path(path, what)
    data = read_bounded(p, what=what, max_bytes=max_bytes)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise DatasetError(f"not a UTF-8 text file (byte 0x{data[exc.start]:02x})",
                           path=p, line=line) from None


def read_json(path: str | os.PathLike, *, what: str = "JSON file",
              max_bytes: int = MAX_JSON_BYTES):
    """Parse a JSON file; a syntax error becomes a DatasetError with its line."""

    text = read_text(path, what=what, max_bytes=max_bytes)
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise DatasetError(f"invalid JSON: {exc.msg}", path=path, line=exc.lineno) from None
    except RecursionError:      # arrays or objects nested deeper than Python's stack
        raise DatasetError("invalid JSON: nested too deeply", path=path) from None


def read_json_as(path: str | os.PathLike, parse, *, what: str = "JSON file"):
    """``parse(data, path)`` of a JSON file (:func:`read_json`), where a value of a type the
    parser's own checks did not foresee becomes one line naming the file, never a traceback.

    Raises
    ------
    DatasetError
        As :func:`read_json` and ``parse``, or ``unexpected content (...)``.
    """
    data = read_json(path, what=what)
    try:
        return parse(data, path)
    except (TypeError, ValueError, OverflowError, AttributeError, KeyError, IndexError,
            RecursionError) as exc:     # a value of a type no check of ``parse`` foresaw
        raise DatasetError(f"unexpected content ({type(exc).__name__}: {exc})",
                           path=path) from None


def data_lines(text: str) -> Iterator[tuple[int, str]]:
    """Non-empty lines with ``#`` comments removed, as ``(1-based line number, content)``."""
    for number, raw in enumerate(text.splitlines(), start=1):
        content = raw.split("#", 1)[0].strip()
        if content:
            yield number, content


def split_fields(content: str) -> list[str]:
    """Fields of a row separated by commas, semicolons, spaces or tabs (any mix, runs count
    once)."""
    return [f for f in _FIELD_SEP.split(content.strip()) if f]


def is_nanoseconds(token: str) -> bool:
    """Whether a time-stamp cell is integer nanoseconds: 16 to 19 digits, the rule of image
    names (:func:`multieye.io.image_folder.stamp_from_name`; seconds have at most 10 digits
    before the point, and 11 to 15 digits are ambiguous)."""
    text = token.strip()
    return text.isascii() and text.isdigit() and 16 <= len(text) <= 19


def first_cell_is_nanoseconds(path: str | os.PathLike, column: int, *,
                              what: str = "file") -> bool:
    """Whether the first row of a table of numbers (commas and/or spaces, ``#`` comments)
    holds integer nanoseconds in ``column`` (:func:`is_nanoseconds`); the file's first row
    decides for every row, as in TUM files.  False for a file without such a row."""
    for _, content in text_lines(path, what=what):
        cells = split_fields(content)
        if any(map(_is_float, cells)):         # a header row of names does not decide
            return column < len(cells) and is_nanoseconds(cells[column])
    return False


def _is_float(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def parse_float(token: str, *, path: str | os.PathLike | None, line: int | None,
                name: str, finite: bool = True) -> float:
    """A finite float from a text cell, or a DatasetError naming the cell.

    Parameters
    ----------
    token : str
        The cell's text.
    path, line : file and 1-based line, for the message.
    name : str
        What the cell holds (``"qw"``, ``"Time (Seconds)"``).
    finite : bool
        False: ``nan`` and ``inf`` (and numbers beyond the float range) are returned as they
        are, for readers that leave such rows out one by one.
    """
    try:
        value = float(token)
    except ValueError:
        comma = ("; a decimal comma: write numbers with a decimal point (0.5, not 0,5)"
                 if re.fullmatch(r"\s*[-+]?\d*,\d+\s*", token) else "")
        raise DatasetError(f"expected a number for {name}, got {token.strip()[:40]!r}{comma}",
                           path=path, line=line) from None
    if finite and not math.isfinite(value):
        raise DatasetError(f"expected a finite number for {name}, got {token.strip()!r}",
                           path=path, line=line)
    return value


def read_number_rows(path: str | os.PathLike, columns: Sequence[str], *, files: str,
                     what: str = "file", finite: bool = True, skip_line: int | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Rows of numbers separated by commas and/or spaces, with ``#`` comments and blank lines,
    read line by line into arrays (a table of millions of rows never exists as Python objects).

    Parameters
    ----------
    path : path-like
    columns : sequence of str
        Name of each column, for messages; every row must have exactly this many entries.
    files : str
        How messages name the format: ``"TUM trajectory files"`` gives "TUM trajectory files
        must have 8 entries per row, got 7 (expected t tx ty tz qx qy qz qw)".
    what : str
        How a missing-file message names the file.
    finite : bool
        False: cells ``nan`` and ``inf`` are read as such (see :func:`parse_float`).
    skip_line : int, optional
        A line left out (a header row, :func:`header_row`).

    Returns
    -------
    data : ndarray, shape (N, len(columns)), float64
    lines : ndarray, shape (N,), int64
        1-based line of each row.

    Raises
    ------
    DatasetError
        Missing or unreadable file, a row with another number of entries, a cell that is not a
        finite number (each with the line), or no rows at all.
    """
    table = NumberTable(len(columns))
    for contents, numbers in line_blocks(path, what=what):
        if skip_line is not None and skip_line in numbers:
            k = numbers.index(skip_line)
            contents, numbers = contents[:k] + contents[k + 1:], numbers[:k] + numbers[k + 1:]
        table.add_block(contents, numbers, columns, files=files, path=path, finite=finite)
    if not len(table):
        raise DatasetError(f"no rows: expected lines '{' '.join(columns)}'", path=path)
    return table.arrays()


def header_row(path: str | os.PathLike, *, what: str = "file") -> tuple[int, list[str]] | None:
    """The first row of a table of numbers when it holds names and no number (a header):
    ``(1-based line, its cells)`` (separated by commas, else semicolons, else white space, so
    that a name may hold a space: ``t [ns]``); None when it holds a number or the file has no
    row."""
    for number, content in text_lines(path, what=what):
        if any(map(_is_float, split_fields(content))):
            return None
        sep = "," if "," in content else ";" if ";" in content else None
        return number, [c.strip() for c in content.split(sep)]
    return None


def physical_lines(path: str | os.PathLike, *, what: str = "file",
                   max_bytes: int = MAX_TABLE_BYTES) -> Iterator[tuple[int, str]]:
    """Every physical line of a UTF-8 text file as ``(1-based number, text without its line
    break)``, read one at a time (never the whole text in memory; a leading BOM dropped).

    Raises
    ------
    DatasetError
        As :func:`read_text`, the bound counted as the lines are read; a line that is not
        UTF-8, with its number.
    """
    p = as_path(path, what)
    with open_bounded_text(p, what=what, max_bytes=max_bytes) as lines:
        for number, raw in enumerate(lines, start=1):
            if number == 1 and raw.startswith(b"\xef\xbb\xbf"):
                raw = raw[3:]
            try:
                text = raw.decode("utf-8")
            except UnicodeDecodeError as exc:
                raise DatasetError(f"not a UTF-8 text file (byte 0x{raw[exc.start]:02x})",
                                   path=p, line=number) from None
            yield number, text.rstrip("\r\n")


def text_lines(path: str | os.PathLike, *, what: str = "file",
               max_bytes: int = MAX_TABLE_BYTES) -> Iterator[tuple[int, str]]:
    """:func:`data_lines` of a file read line by line (never the whole text in memory):
    :func:`physical_lines` without ``#`` comments, white space and empty lines.

    Raises
    ------
    DatasetError
        As :func:`physical_lines`.
    """
    for number, text in physical_lines(path, what=what, max_bytes=max_bytes):
        content = text.split("#", 1)[0].strip()
        if content:
            yield number, content


def _decoded_lines(path: str | os.PathLike, *, what: str, max_bytes: int
                   ) -> Iterator[tuple[int, list[str]]]:
    """:func:`physical_lines` a block of bytes (1 MiB) at a time, as ``(number of the first
    line, lines)``, each line without its ``\\n``.  A line that is not UTF-8 raises as
    :func:`physical_lines` does, once the lines before it are given."""
    p = as_path(path, what)
    first, rest = 1, b""
    with open_bounded_text(p, what=what, max_bytes=max_bytes) as f:
        for block in itertools.chain(f.blocks(), [None]):
            if block is None:           # the end: a last line without its line break
                data, rest = rest, b""
            else:
                data = rest + block
                cut = data.rfind(b"\n") + 1
                data, rest = data[:cut], data[cut:]
            if not data:
                continue
            if first == 1 and data.startswith(b"\xef\xbb\xbf"):
                data = data[3:]
            try:
                text = data.decode("utf-8")
            except UnicodeDecodeError as exc:
                good = data[:exc.start].count(b"\n")     # the lines before the bad one
                yield first, data[:data.rfind(b"\n", 0, exc.start) + 1].decode("utf-8").split(
                    "\n")[:good]
                raise DatasetError(f"not a UTF-8 text file (byte 0x{data[exc.start]:02x})",
                                   path=p, line=first + good) from None
            lines = text.split("\n")
            if lines[-1] == "":
                lines.pop()
            yield first, lines
            first += len(lines)


def line_blocks(path: str | os.PathLike, *, what: str = "file", size: int = 1 << 14,
                max_bytes: int = MAX_TABLE_BYTES) -> Iterator[tuple[list[str], list[int]]]:
    """:func:`text_lines` gathered ``size`` at a time: ``(contents, line numbers)``; read a
    block of bytes at a time (line by line, 8 of the 52 ms that read_tum took for 12,193
    rows went to reading the lines)."""
    contents: list[str] = []
    numbers: list[int] = []
    for first, lines in _decoded_lines(path, what=what, max_bytes=max_bytes):
        stripped = [line.split("#", 1)[0].strip() if "#" in line else line.strip()
                    for line in lines]
        if all(stripped):
            contents += stripped
            numbers += range(first, first + len(stripped))
        else:
            kept = [k for k, c in enumerate(stripped) if c]
            contents += [stripped[k] for k in kept]
            numbers += [first + k for k in kept]
        while len(contents) >= size:
            yield contents[:size], numbers[:size]
            contents, numbers = contents[size:], numbers[size:]
    if contents:
        yield contents, numbers


def count_lines(path: str | os.PathLike, *, what: str = "file",
                max_bytes: int = MAX_TABLE_BYTES) -> int:
    """Lines of a file (line breaks, plus one for a last line without), counted in blocks of
    bytes: a bound on its rows before they are parsed."""
    p = as_path(path, what)
    n, last = 0, b"\n"
    with open_bounded_text(p, what=what, max_bytes=max_bytes) as f:
        for block in f.blocks():
            n += block.count(b"\n")
            last = block[-1:]
    return n + (last != b"\n")


class NumberTable:
    """Rows of numbers gathered into flat arrays (8 bytes a number, no Python object per
    row), for tables of millions of rows."""

    def __init__(self, n_columns: int):
        self.n = int(n_columns)
        self._values = array("d")
        self._lines = array("q")

    def __len__(self) -> int:
        return len(self._lines)

    def add(self, content: str, number: int, columns: Sequence[str], *, files: str,
            path, finite: bool, hints: Mapping[int, str] | None = None) -> None:
        """Parse one data line (comments removed) and append it; DatasetError naming the line
        when it does not hold ``len(columns)`` numbers (with ``hints[count]``, what a row of
        that count may be, or that its numbers have decimal commas)."""
        fields = split_fields(content)
        if len(fields) != self.n:
            raise DatasetError(f"{files} must have {len(columns)} entries per row, got "
                               f"{len(fields)} (expected {' '.join(columns)})"
                               + _count_hint(content, len(fields), self.n, hints),
                               path=path, line=number)
        try:
            values = [float(f) for f in fields]
        except ValueError:
            if not len(self) and not any(_is_float(f) for f in fields):
                raise DatasetError(f"this first row is not numbers but names, a header ("
                                   f"{' '.join(fields)[:80]}): {files} hold numbers only; start "
                                   "the line with # to make it a comment", path=path,
                                   line=number) from None
            values = [parse_float(f, path=path, line=number, name=name, finite=finite)
                      for f, name in zip(fields, columns)]
        if finite and not all(map(math.isfinite, values)):
            for f, name in zip(fields, columns):
                parse_float(f, path=path, line=number, name=name, finite=True)
        self._values.extend(values)
        self._lines.append(number)

    def add_block(self, contents: Sequence[str], numbers: Sequence[int],
                  columns: Sequence[str], *, files: str, path, finite: bool,
                  hints: Mapping[int, str] | None = None) -> None:
        """:meth:`add` for many lines at once: parsed by numpy's C reader when every line
        holds ``len(columns)`` plain numbers, else line by line with Python's ``float``
        (which names the bad line and reads what it reads)."""
        joined = "\n".join(contents)
        if "," in joined or ";" in joined:
            joined = joined.replace(",", " ").replace(";", " ")
            ok = all(len(split_fields(c)) == self.n for c in contents)
        else:
            ok = all(len(c.split()) == self.n for c in contents)
        if ok:
            try:
                with warnings.catch_warnings():         # older numpy: a warning, not an error
                    warnings.simplefilter("error")
                    block = np.fromstring(joined, dtype=np.float64, sep=" ")
                ok = block.size == len(contents) * self.n and (
                    not finite or bool(np.isfinite(block).all()))
            except (ValueError, DeprecationWarning):
                ok = False
        if not ok:
            for content, number in zip(contents, numbers):
                self.add(content, number, columns, files=files, path=path, finite=finite,
                         hints=hints)
            return
        self._values.frombytes(block.tobytes())
        self._lines.extend(numbers)

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """``(data (N, n_columns) float64, lines (N,) int64)``; the table gives its memory to
        them."""
        data = np.frombuffer(self._values, dtype=np.float64).reshape(-1, self.n)
        lines = np.frombuffer(self._lines, dtype=np.int64)
        return data, lines


def _count_hint(content: str, count: int, wanted: int, hints: Mapping[int, str] | None) -> str:
    """What a row of ``count`` entries where ``wanted`` are expected may be: numbers written
    with decimal commas (``0,5``: the row has ``wanted`` entries when only spaces, tabs and
    semicolons separate them), else ``hints[count]``; empty when neither."""
    if _DECIMAL_COMMA.search(content) and len(
            [f for f in re.split(r"[;\s]+", content.strip()) if f]) == wanted:
        return ("; the numbers look written with decimal commas (0,5): write them with a "
                "decimal point (0.5)")
    hint = (hints or {}).get(count)
    return f"; {hint}" if hint else ""


def length_scale(unit: str, *, path: str | os.PathLike | None = None,
                 line: int | None = None) -> float:
    """Metres per ``unit`` (``"m"``, ``"cm"`` or ``"mm"``)."""
    try:
        return LENGTH_UNITS[unit]
    except (KeyError, TypeError):
        raise DatasetError(f"length unit must be one of {', '.join(LENGTH_UNITS)}, got {unit!r}",
                           path=path, line=line) from None
