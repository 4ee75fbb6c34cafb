"""Camera names as file names (issue 19): the rule, and the safe form of any other name."""

from __future__ import annotations

import os
from types import SimpleNamespace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from multieye.core.errors import InputError
from multieye.core.names import camera_name_problem, file_stem, file_stems


@pytest.mark.parametrize("name", ["cam0", "front left", "caméra", "cam.1", "a-b_c", "x" * 100,
                                  "\u20ac" * 66, "0", "cam."])
def test_file_names_are_kept(name):
    assert camera_name_problem(name) is None
    assert file_stem(name) == name


@pytest.mark.parametrize("name, problem", [
    ("", "is empty"), ("../x", "holds '/'"), ("a\\b", "holds '\\\\'"), (".", "starts with '.'"),
    ("..", "starts with '.'"), ("x..y", "holds '..'"), ("c" * 101, "101 characters"),
    ("\u20ac" * 67, "201 bytes"), ("a\x00b", "holds '\\x00'"), ("a\tb", "holds '\\t'"),
    (" a", "white space"), ("a ", "white space"), ("a:b", "holds ':'"), ("a\udcffb", "holds"),
    (3, "not text")])
def test_names_that_cannot_be_file_names(name, problem):
    assert problem in camera_name_problem(name)


def test_names_one_file_on_macos_are_refused():
    taken = {}
    assert camera_name_problem("cam0", taken) is None
    assert "one file with camera 'cam0'" in camera_name_problem("CAM0", taken)
    assert camera_name_problem("caf\u00e9", taken) is None
    assert "one file with camera" in camera_name_problem("cafe\u0301", taken)


@settings(max_examples=300, deadline=None, derandomize=True, database=None)
@given(st.text(max_size=300))
def test_the_safe_form_is_always_a_file_name(name):
    stem = file_stem(name)
    assert camera_name_problem(stem) is None, (name, stem)
    assert os.sep not in stem and not stem.startswith(".")


def test_the_safe_form_of_paths():
    assert file_stem("../../etc/passwd") == "_.__._etc_passwd"
    assert file_stem("/abs/x") == "_abs_x"
    assert file_stem("") == "_"
    assert len(file_stem("c" * 5000)) == 100


def test_two_names_reducing_to_one_file_are_refused():
    def cams(*names):
        return [SimpleNamespace(name=n) for n in names]

    assert file_stems(cams("a/b", "c")) == {"a/b": "a_b", "c": "c"}
    with pytest.raises(InputError, match="cameras 'a/b' and 'a_b' would be one"):
        file_stems(cams("a/b", "a_b"))
    with pytest.raises(InputError, match="'Cam' and 'cam'"):
        file_stems(cams("Cam", "cam"))
