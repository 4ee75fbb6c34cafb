"""YAML documents that remember the line of every key, for messages that point at it.

:func:`load_yaml` parses once with PyYAML's safe loader and keeps the start mark of each
mapping key and sequence item, so a reader can say ``rig.yaml:12: cameras.cam1.poses: file
not found`` instead of only naming the file.  Duplicate keys, which PyYAML silently resolves
to the last value, are rejected.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from multieye.core.errors import DatasetError
from multieye.io.textfile import read_text

__all__ = ["YamlDocument", "load_yaml", "parse_yaml", "yaml_float", "yaml_list"]

KeyPath = tuple[Any, ...]


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
        where = ".".join(str(k) for k in keys)
        text = f"{where}: {message}" if where else message
        return DatasetError(text, path=self.path, line=self.line(*keys), camera=camera)


class _Loader(yaml.SafeLoader):
    """Safe loader that keeps mapping keys as their text (``yes:`` stays ``"yes"``, ``0:``
    stays ``"0"``), so that keys in the data and in :attr:`YamlDocument.lines` agree."""

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


def _walk(node: yaml.Node, prefix: KeyPath, lines: dict, path: Path) -> None:
    if isinstance(node, yaml.MappingNode):
        seen: dict[Any, int] = {}
        for key_node, value_node in node.value:
            key = key_node.value if isinstance(key_node, yaml.ScalarNode) else repr(key_node.value)
            line = key_node.start_mark.line + 1
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
    loader = _Loader(text)
    try:
        node = loader.get_single_node()
        lines: dict[KeyPath, int] = {}
        data = None
        if node is not None:
            lines[()] = node.start_mark.line + 1
            _walk(node, (), lines, path)
            data = loader.construct_document(node)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = mark.line + 1 if mark is not None else None
        problem = exc.problem or exc.context or "invalid YAML"
        raise DatasetError(f"invalid YAML: {problem}", path=path, line=line) from None
    except yaml.YAMLError as exc:
        raise DatasetError(f"invalid YAML: {exc}", path=path) from None
    finally:
        loader.dispose()
    return YamlDocument(path, data, lines)


def load_yaml(path: str | os.PathLike, *, what: str = "YAML file") -> YamlDocument:
    """Read and parse a YAML file.

    Raises
    ------
    DatasetError
        Missing or unreadable file, invalid YAML (with the line PyYAML reports), duplicate keys.
    """
    return parse_yaml(read_text(path, what=what), path)


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
