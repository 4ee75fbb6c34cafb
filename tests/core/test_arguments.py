"""Argument checks of the public functions: every wrong argument is an InputError saying what
was expected, never a TypeError or a numpy error from further in."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from multieye.core.arguments import (
    as_path,
    camera_names,
    one_of,
    positive_int,
    real_array,
    real_number,
)
from multieye.core.errors import InputError


def test_real_array_converts_and_checks_the_shape():
    assert real_array([1, 2], "x").dtype == np.float64
    assert real_array(np.eye(4)[None], "T", shape=(None, 4, 4)).shape == (1, 4, 4)
    assert real_array(np.array([True, False]), "x").tolist() == [1.0, 0.0]


@pytest.mark.parametrize("value, message", [
    (None, "T is None; expected a real array of shape (N, 4, 4)"),
    (np.eye(4)[None] + 1j, "T must be real, got complex numbers"),
    ("abc", "T must be a real array of shape (N, 4, 4), got str"),
    ({"a": 1}, "got dict"),
    ([[1, 2], [3]], "T must be a real array of shape (N, 4, 4)"),
    (np.array([["a"]]), "T must be a real array of shape (N, 4, 4), got an array of dtype <U1"),
    (np.eye(4), "T must be a real array of shape (N, 4, 4), got shape (4, 4)"),
    (np.zeros((2, 3, 4)), "got shape (2, 3, 4)"),
])
def test_real_array_refusals(value, message):
    with pytest.raises(InputError) as info:
        real_array(value, "T", shape=(None, 4, 4))
    assert message in str(info.value)


@pytest.mark.parametrize("value, kw, message", [
    (None, {}, "x must be a number, got None"),
    ("1", {}, "x must be a number, got '1'"),
    (True, {}, "x must be a number, got True"),
    (1j, {}, "x must be a number"),
    (float("nan"), {}, "x must be a finite number, got nan"),
    (0.0, {"positive": True}, "x must be a positive number, got 0.0"),
    (float("inf"), {"positive": True}, "x must be a positive number, got inf"),
])
def test_real_number_refusals(value, kw, message):
    with pytest.raises(InputError) as info:
        real_number(value, "x", **kw)
    assert message in str(info.value)
    assert real_number(None, "x", allow_none=True) is None
    assert real_number(np.float32(2.5), "x", positive=True) == 2.5


@pytest.mark.parametrize("value", [0, -1, 1.5, None, True, "3"])
def test_positive_int_refusals(value):
    with pytest.raises(InputError, match="n must be a positive integer"):
        positive_int(value, "n")
    assert positive_int(np.int64(3), "n") == 3


@pytest.mark.parametrize("names, message", [
    ("ab", "names must be a list of 2 strings (one per camera), got 'ab'"),
    (["a"], "names has 1 entries but there are 2 cameras"),
    (["a", 1], "names must be non-empty strings"),
    (["a", ""], "names must be non-empty strings"),
    (["a", "a"], "names must be distinct"),
    (5, "names must be a list of 2 strings"),
])
def test_camera_names_refusals(names, message):
    with pytest.raises(InputError) as info:
        camera_names(names, 2)
    assert message in str(info.value)
    assert camera_names(None, 2) is None
    assert camera_names(("a", "b"), 2) == ("a", "b")


def test_one_of_and_as_path():
    assert one_of("joint", "method", ("joint",)) == "joint"
    with pytest.raises(InputError, match="method must be one of joint, shah, got None"):
        one_of(None, "method", ("joint", "shah"))
    assert as_path("a/b") == Path("a/b")
    for bad in (None, 5, ["a"], b"a", "", "a\0b"):
        with pytest.raises(InputError, match="dataset must be a path"):
            as_path(bad, "dataset")
