"""YAML documents that remember the line of every key, for messages that point at it.

:func:`load_yaml` parses once with PyYAML's safe loader and keeps the start mark of each
mapping key and sequence item, so a reader can say ``rig.yaml:12: cameras.cam1.poses: file
not found`` instead of only naming the file.  Duplicate keys, which PyYAML silently resolves
to the last value, are rejected.

Every YAML file multieye reads (rig.yaml, intrinsics, Kalibr camchains, ROS camera_info) is
held to limits far above any real file of these kinds and low enough that a hostile or broken
one cannot exhaust memory, time or the stack: at most :data:`MAX_YAML_BYTES` bytes,
:data:`MAX_YAML_DEPTH` levels of nesting, :data:`MAX_YAML_ALIASES` aliases (``*name``) and
:data:`MAX_YAML_NODES` values once the aliases are expanded; a recursive alias (a collection
that contains itself) is refused.  A file beyond a limit is a DatasetError naming the file
(and the line where there is one), like any other malformed file.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from multieye.core.errors import DatasetError
from multieye.core.limits import MAX_YAML_BYTES  # largest YAML file read: a rig.yaml is a few kB
from multieye.io.textfile import read_text

__all__ = ["YamlDocument", "load_yaml", "parse_yaml", "shown", "yaml_float", "yaml_list",
           "MAX_YAML_BYTES", "MAX_YAML_DEPTH", "MAX_YAML_ALIASES", "MAX_YAML_NODES"]

KeyPath = tuple[Any, ...]

#: Deepest nesting of mappings and sequences, aliases expanded (rig.yaml needs 5).
MAX_YAML_DEPTH = 32
#: Most aliases (``*name``) in one file.
MAX_YAML_ALIASES = 100
#: Most values (mappings, sequences and scalars) once the aliases are expanded: an alias
#: expansion bomb (aliases of aliases of lists) stops here instead of growing past the memory.
MAX_YAML_NODES = 100_000


class _LimitError(yaml.MarkedYAMLError):
    """A YAML file beyond one of the limits above (the message says which)."""


@dataclass(frozen=True)
class YamlDocument:
    """A parsed YAML file with the 1-based line of every key.

    Attributes
    ----------
    path : Path
        The file.
    data : object
        The document as plain Python (dicts, lists, str, int, float, bool, None).
    lines : mapping of key path to int
        ``lines[("cameras", "cam0", "images")]`` is the line of that key; sequence items use
        their index.  The empty path is the document start.
    """

    path: Path
    data: Any
    lines: Mapping[KeyPath, int] = field(repr=False)

    def line(self, *keys) -> int | None:
        """Line of the key path, or of its closest ancestor that has one."""
        keys = tuple(keys)
        while keys:
            if keys in self.lines:
                return self.lines[keys]
            keys = keys[:-1]
        return self.lines.get(())

    def error(self, message: str, *keys, camera: str | None = None) -> DatasetError:
        """A DatasetError at the line of ``keys``, prefixed with the dotted key path."""
        where = ".".join(str(k) if str(k).isprintable() else repr(k) for k in keys)
        text = f"{where}: {message}" if where else message
        return DatasetError(text, path=self.path, line=self.line(*keys), camera=camera)


class _Loader(yaml.SafeLoader):
    """Safe loader that keeps mapping keys as their text (``yes:`` stays ``"yes"``, ``0:``
    stays ``"0"``), so that keys in the data and in :attr:`YamlDocument.lines` agree; and
    that counts nesting and aliases while it composes, so that a deep or alias-heavy file
    stops at a limit instead of at the end of the stack or the memory."""

    def __init__(self, stream):
        super().__init__(stream)
        self._depth = 0
        self._aliases = 0

    def compose_node(self, parent, index):
        if self.check_event(yaml.AliasEvent):
            self._aliases += 1
            if self._aliases > MAX_YAML_ALIASES:
                raise _LimitError(None, None, f"more than {MAX_YAML_ALIASES} aliases (*name); "
                                  "write the values out", self.peek_event().start_mark)
            return super().compose_node(parent, index)
        self._depth += 1
        try:
            if self._depth > MAX_YAML_DEPTH:
                raise _LimitError(None, None, f"nested deeper than {MAX_YAML_DEPTH} levels",
                                  self.peek_event().start_mark)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def construct_mapping(self, node, deep=False):
        if not isinstance(node, yaml.MappingNode):
            return super().construct_mapping(node, deep=deep)
        self.flatten_mapping(node)
        mapping = {}
        for key_node, value_node in node.value:
            if isinstance(key_node, yaml.ScalarNode):
                key = key_node.value
            else:
                raise yaml.constructor.ConstructorError(
                    None, None, "mapping keys must be plain values", key_node.start_mark)
            mapping[key] = self.construct_object(value_node, deep=deep)
        return mapping


# OpenCV's matrix tag, read as the mapping it tags ({rows, cols, dt, data}), for FileStorage
# YAML that lost its ``%YAML:1.0`` line (which routes a file to OpenCV's own parser).
_Loader.add_constructor("tag:yaml.org,2002:opencv-matrix", _Loader.construct_mapping)


def _empty_document(node: yaml.Node | None) -> bool:
    """Whether a composed document holds nothing (a ``---`` or ``...`` with nothing after)."""
    return node is None or (isinstance(node, yaml.ScalarNode) and node.value == ""
                            and node.tag == "tag:yaml.org,2002:null")


def _single_node(loader: _Loader, path: Path) -> yaml.Node | None:
    """The stream's one document, as PyYAML's ``get_single_node``, except that empty
    documents are let pass: ``ros2 topic echo --once`` ends its message with ``---``, and a
    file may start with one.  Several documents with content are refused, naming the line of
    the second."""
    loader.get_event()                          # STREAM-START
    node = None
    while not loader.check_event(yaml.StreamEndEvent):
        line = loader.peek_event().start_mark.line + 1
        document = loader.compose_document()
        if _empty_document(document):
            continue
        if node is not None:
            raise DatasetError("a second YAML document starts here (---): expected one "
                               "document; keep one (a saved 'ros2 topic echo' holds one "
                               "message per document)", path=path, line=line)
        node = document
    loader.get_event()                          # STREAM-END
    return node


def _check_expansion(root: yaml.Node) -> None:
    """Refuse a composed document whose aliases expand it beyond :data:`MAX_YAML_NODES`
    values or :data:`MAX_YAML_DEPTH` levels, or that contains itself through an alias.

    The composed document is a graph in which an alias is the anchored node itself, so sizes
    are summed once per node: linear in the file, however large the expansion.
    """
    done: dict[int, tuple[int, int]] = {}
    active: set[int] = set()

    def visit(node: yaml.Node) -> tuple[int, int]:
        key = id(node)
        if key in done:
            return done[key]
        if key in active:
            raise _LimitError(None, None, "recursive alias: a collection contains itself",
                              node.start_mark)
        active.add(key)
        children: list = []
        if isinstance(node, yaml.MappingNode):
            children = [n for pair in node.value for n in pair]
        elif isinstance(node, yaml.SequenceNode):
            children = node.value
        count, depth = 1, 1
        for child in children:
            c, d = visit(child)
            count, depth = count + c, max(depth, d + 1)
            if count > MAX_YAML_NODES:
                raise _LimitError(None, None, f"the aliases (*name) expand it to more than "
                                  f"{MAX_YAML_NODES} values; write the values out",
                                  child.start_mark)
            if depth > MAX_YAML_DEPTH:
                raise _LimitError(None, None, f"nested deeper than {MAX_YAML_DEPTH} levels "
                                  "once its aliases are expanded", child.start_mark)
        active.discard(key)
        done[key] = (count, depth)
        return count, depth

    visit(root)


def _walk(node: yaml.Node, prefix: KeyPath, lines: dict, path: Path) -> None:
    if isinstance(node, yaml.MappingNode):
        seen: dict[Any, int] = {}
        for key_node, value_node in node.value:
            line = key_node.start_mark.line + 1
            if not isinstance(key_node, yaml.ScalarNode):
                raise DatasetError("invalid YAML: mapping keys must be plain values",
                                   path=path, line=line)
            key = key_node.value
            if key in seen:
                raise DatasetError(f"duplicate key {key!r} (first on line {seen[key]})",
                                   path=path, line=line)
            seen[key] = line
            lines[prefix + (key,)] = line
            _walk(value_node, prefix + (key,), lines, path)
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            lines[prefix + (i,)] = item.start_mark.line + 1
            _walk(item, prefix + (i,), lines, path)


def parse_yaml(text: str, path: str | os.PathLike) -> YamlDocument:
    """Parse YAML text (``path`` only names it in messages); see :func:`load_yaml`."""
    path = Path(path)
    if len(text) > MAX_YAML_BYTES:
        raise DatasetError(f"YAML file larger than {MAX_YAML_BYTES} bytes; not a file "
                           "multieye reads", path=path)
    loader = None
    try:
        loader = _Loader(text)
        node = _single_node(loader, path)
        lines: dict[KeyPath, int] = {}
        data = None
        if node is not None:
            _check_expansion(node)
            lines[()] = node.start_mark.line + 1
            _walk(node, (), lines, path)
            data = loader.construct_document(node)
    except _LimitError as exc:
        mark = exc.problem_mark
        raise DatasetError(f"YAML refused: {exc.problem}", path=path,
                           line=None if mark is None else mark.line + 1) from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = mark.line + 1 if mark is not None else None
        problem = exc.problem or exc.context or "invalid YAML"
        if "'\\t'" in problem:
            problem += " (YAML indents with spaces, not tabs)"
        if "could not determine a constructor for the tag" in problem:
            problem += " (a tag multieye does not read: remove it)"
        raise DatasetError(f"invalid YAML: {problem}", path=path, line=line) from None
    except yaml.reader.ReaderError as exc:
        raise DatasetError(f"invalid YAML: character #x{exc.character:04x} is not allowed in "
                           "YAML", path=path, line=text[:exc.position].count("\n") + 1) from None
    except yaml.YAMLError as exc:
        raise DatasetError(f"invalid YAML: {_one_line(exc)}", path=path) from None
    except (ValueError, OverflowError) as exc:   # e.g. an integer of more than 4300 digits
        raise DatasetError(f"invalid YAML value: {_one_line(exc)}", path=path) from None
    except RecursionError:                       # not reached within the limits; never a trace
        raise DatasetError("YAML refused: nested too deeply", path=path) from None
    finally:
        if loader is not None:
            loader.dispose()
    return YamlDocument(path, data, lines)


def load_yaml(path: str | os.PathLike, *, what: str = "YAML file") -> YamlDocument:
    """Read and parse a YAML file.

    Raises
    ------
    DatasetError
        Missing or unreadable file, invalid YAML (with the line PyYAML reports), duplicate keys,
        a file beyond the limits of the module docstring.
    """
    return parse_yaml(read_text(path, what=what, max_bytes=MAX_YAML_BYTES), path)


def _one_line(exc: Exception) -> str:
    text = " ".join(str(exc).split())
    return text[:200] or type(exc).__name__


def shown(value: Any, limit: int = 60) -> str:
    """``repr(value)`` for a message, cut to ``limit`` characters (a value from a file can be
    a whole document)."""
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def yaml_float(value: float) -> str:
    """Shortest exact text of a float that YAML 1.1 readers (PyYAML) read back as a float.

    ``repr`` gives ``1e-05``, which YAML 1.1 reads as a string: a ``.0`` is added to the
    mantissa.
    """
    text = repr(float(value))
    if "e" in text and "." not in text.split("e")[0]:
        mantissa, exponent = text.split("e")
        text = f"{mantissa}.0e{exponent}"
    return text


def yaml_list(values) -> str:
    """A flow sequence ``[a, b, ...]`` of floats written with :func:`yaml_float`."""
    return "[" + ", ".join(yaml_float(v) for v in values) + "]"
