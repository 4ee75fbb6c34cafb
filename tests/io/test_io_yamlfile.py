"""The YAML loader's limits: alias bombs, deep nesting, huge files and stray bytes end in one
DatasetError naming the file (and line), never in a hang, a MemoryError or a RecursionError."""

from __future__ import annotations

import time

import pytest

from multieye.core.errors import DatasetError
from multieye.io.intrinsics_files import read_intrinsics
from multieye.io.kalibr import read_camchain
from multieye.io.rig import load_rig
from multieye.io.yamlfile import (
    MAX_YAML_ALIASES,
    MAX_YAML_BYTES,
    MAX_YAML_DEPTH,
    load_yaml,
    parse_yaml,
)


def _bomb(levels: int = 9) -> str:
    """The classic 'billion laughs': each level a list of nine aliases of the one before."""
    lines = ["a0: &a0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    for k in range(1, levels):
        refs = ", ".join([f"*a{k - 1}"] * 9)
        lines.append(f"a{k}: &a{k} [{refs}]")
    return "\n".join(lines) + "\n"


def test_alias_bomb_is_refused_at_once():
    text = _bomb()
    assert len(text) < 800
    start = time.perf_counter()
    with pytest.raises(DatasetError, match=r"x\.yaml:\d+: YAML refused: the aliases \(\*name\) "
                                           r"expand it to more than 100000 values"):
        parse_yaml(text, "x.yaml")
    assert time.perf_counter() - start < 1.0


def test_alias_bomb_in_a_mapping_key_is_refused():
    text = _bomb(4) + "? *a3\n: 1\n"
    with pytest.raises(DatasetError, match=r"x.yaml:\d+: invalid YAML: mapping keys must be plain"):
        parse_yaml(text, "x.yaml")


@pytest.mark.parametrize("text", ["a: &a [*a]\n", "a: &a {b: *a}\n", "a: &a [1, [2, *a]]\n"])
def test_recursive_alias_is_refused(text):
    with pytest.raises(DatasetError, match="x.yaml:1: YAML refused: recursive alias"):
        parse_yaml(text, "x.yaml")


@pytest.mark.parametrize("text", [
    "a: " + "[" * 100_000 + "]" * 100_000 + "\n",
    "a: " + "{b: " * 5000 + "1" + "}" * 5000 + "\n",
    "".join("  " * i + f"k{i}:\n" for i in range(200)) + "  " * 200 + "v: 1\n",
], ids=["flow-sequences", "flow-mappings", "block-mappings"])
def test_deep_nesting_is_refused(text):
    with pytest.raises(DatasetError, match=f"YAML refused: nested deeper than {MAX_YAML_DEPTH}"):
        parse_yaml(text, "x.yaml")


def test_nesting_through_aliases_counts_too():
    nest = "[" * 20 + "x" + "]" * 20
    text = f"a: &a {nest}\nb: &b {'[' * 20}*a{']' * 20}\n"
    with pytest.raises(DatasetError, match="nested deeper than 32 levels once its aliases"):
        parse_yaml(text, "x.yaml")


def test_too_many_aliases():
    text = "a: &a 1\nb: [" + ", ".join(["*a"] * (MAX_YAML_ALIASES + 1)) + "]\n"
    with pytest.raises(DatasetError, match="x.yaml:2: YAML refused: more than 100 aliases"):
        parse_yaml(text, "x.yaml")


def test_a_few_aliases_and_merge_keys_still_work():
    doc = parse_yaml("base: &m {file: mocap.txt, unit: mm}\n"
                     "cam0: {<<: *m, unit: m}\ncam1: *m\n", "x.yaml")
    assert doc.data["cam0"] == {"file": "mocap.txt", "unit": "m"}
    assert doc.data["cam1"] == {"file": "mocap.txt", "unit": "mm"}
    assert doc.line("cam1", "unit") == 1


def test_size_limit(tmp_path):
    path = tmp_path / "big.yaml"
    path.write_text("# " + "x" * MAX_YAML_BYTES + "\na: 1\n")
    with pytest.raises(DatasetError, match=r"big\.yaml: YAML file is \d+ bytes, more than the "
                                           r"1000000 accepted"):
        load_yaml(path, what="YAML file")
    with pytest.raises(DatasetError, match="larger than 1000000 bytes"):
        parse_yaml(path.read_text(), path)


@pytest.mark.parametrize("text, expected", [
    ("a: 1\nb: \x07\n", "x.yaml:2: invalid YAML: character #x0007 is not allowed"),
    ("\x00\x01\x02", "x.yaml:1: invalid YAML: character #x0000"),
    ("a: " + "9" * 5000 + "\n", "x.yaml: invalid YAML value: Exceeds the limit"),
    ("a: !!python/object:os.system x\n", "x.yaml:1: invalid YAML: could not determine a "
                                         "constructor"),
    ("a: [1, 2\n", "x.yaml:2: invalid YAML"),
])
def test_garbage_is_one_dataset_error(text, expected):
    with pytest.raises(DatasetError) as info:
        parse_yaml(text, "x.yaml")
    assert str(info.value).startswith(expected)
    assert "\n" not in str(info.value)


def test_key_with_a_line_break_stays_on_one_line(tmp_path):
    (tmp_path / "rig.yaml").write_text('setup: eye-to-base\ncameras: {"a\\nb": 1}\n')
    with pytest.raises(DatasetError) as info:
        load_rig(tmp_path)
    assert "\n" not in str(info.value) and "'a\\nb'" in str(info.value)


def test_every_yaml_reader_applies_the_limits(tmp_path):
    (tmp_path / "rig.yaml").write_text(_bomb())
    with pytest.raises(DatasetError, match=r"rig\.yaml:\d+: YAML refused"):
        load_rig(tmp_path)
    (tmp_path / "info.yaml").write_text(_bomb() + "camera_matrix: *a8\n")
    with pytest.raises(DatasetError, match=r"info\.yaml:\d+: YAML refused"):
        read_intrinsics(tmp_path / "info.yaml")
    (tmp_path / "chain.yaml").write_text("cam0: &c {camera_model: pinhole, x: "
                                         + "[" * 50 + "]" * 50 + "}\n")
    with pytest.raises(DatasetError, match=r"chain\.yaml:1: YAML refused: nested deeper"):
        read_camchain(tmp_path / "chain.yaml")
    (tmp_path / "huge.yaml").write_text("camera_matrix: [" + "1, " * 400_000 + "1]\n")
    with pytest.raises(DatasetError, match=r"huge\.yaml: intrinsics file is \d+ bytes"):
        read_intrinsics(tmp_path / "huge.yaml")


@pytest.mark.parametrize("body", [
    "a: " + "[" * 100_000 + "]" * 100_000 + "\n",
], ids=["yaml"])
def test_opencv_filestorage_nesting_is_refused_before_opencv_parses_it(tmp_path, body):
    # OpenCV's own parser recurses without a limit and crashes the process on such a file.
    (tmp_path / "cv.yaml").write_text("%YAML:1.0\n---\n" + body)
    with pytest.raises(DatasetError, match="cv.yaml: FileStorage refused: nested deeper"):
        read_intrinsics(tmp_path / "cv.yaml")
    (tmp_path / "cv.xml").write_text("<?xml version=\"1.0\"?>\n<opencv_storage>"
                                     + "<a>" * 100_000 + "</a>" * 100_000 + "</opencv_storage>")
    with pytest.raises(DatasetError, match="cv.xml: FileStorage refused: nested deeper"):
        read_intrinsics(tmp_path / "cv.xml")


def test_empty_documents_pass_and_a_second_document_is_one_line(tmp_path):
    """A saved ``ros2 topic echo --once`` ends with ``---`` (an empty second document), and a
    file may start with one: read as the one document. Two documents with content: one line
    naming the second's line and what to do (before: 'invalid YAML: but found another
    document' for both)."""
    assert parse_yaml("---\na: 1\n---\n", "f.yaml").data == {"a": 1}
    assert parse_yaml("a: 1\n...\n---\n", "f.yaml").data == {"a": 1}
    with pytest.raises(DatasetError, match=r"f.yaml:2: a second YAML document starts here"
                                           r".*expected one document") as info:
        parse_yaml("a: 1\n---\nb: 2\n", "f.yaml")
    assert "\n" not in str(info.value)
