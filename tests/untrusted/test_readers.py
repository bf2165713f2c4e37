"""The reading layer itself: what it refuses before any parsing or allocation."""

from __future__ import annotations

import os

import numpy as np
import pytest

import untrusted
from untrusted.limits import MAX_DEPTH


def test_a_fifo_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "pipe.json"
    os.mkfifo(fifo)
    with pytest.raises(untrusted.InputError, match="pipe.json: is not a regular file"):
        untrusted.read_json(fifo)


def test_size_is_checked_before_reading(tmp_path):
    big = tmp_path / "big.json"
    with open(big, "wb") as fh:
        fh.truncate(65 << 20)  # sparse: 65 MiB on paper, nothing on disk
    with pytest.raises(untrusted.InputError, match="big.json: JSON file of 68,157,440 bytes"):
        untrusted.read_json(big)


def test_a_missing_file_is_still_a_file_not_found_error(tmp_path):
    with pytest.raises(FileNotFoundError, match="gone.json: layout not found"):
        untrusted.read_json(tmp_path / "gone.json", what="layout")


@pytest.mark.parametrize("text,match", [
    ('{"a": [1, NaN]}', "a\\[1\\] = nan"),
    ('{"a": {"b": Infinity}}', "a.b = inf"),
    ('{"a": 1e999}', "a = inf"),
    ('{"a": [' + "9" * 30 + "]}", "more than 19 digits"),
    ('{"a": 9999999999999999999}', "a: integer out of the 64-bit range"),
    ("[" * (MAX_DEPTH + 1) + "]" * (MAX_DEPTH + 1), f"more than {MAX_DEPTH} levels"),
    ("", "empty file"),
    ('{"a": ', "truncated"),
])
def test_json_faults_name_the_key(text, match):
    with pytest.raises(untrusted.InputError, match=match):
        untrusted.parse_json(text, "F.json")


def test_nesting_up_to_the_limit_is_read():
    text = "[" * MAX_DEPTH + "]" * MAX_DEPTH
    assert untrusted.parse_json(text, "F.json") is not None


@pytest.mark.parametrize("text,match", [
    ("[a]\nb = nan\n", "a.b = nan"),
    ("[a]\nb = [1, -inf]\n", "a.b\\[1\\] = -inf"),
    ("a = 99999999999999999999\n", "integer out of the 64-bit range"),
    ("a = 1" + "0" * 5000 + "\n", "F.toml"),
])
def test_toml_faults_name_the_key(text, match):
    with pytest.raises(untrusted.InputError, match=match):
        untrusted.parse_toml(text, "F.toml")


def test_points_are_checked_and_converted_at_once():
    pts = untrusted.points([[0, 1], [2.5, 3]], "F", "outline")
    assert pts.dtype == float and pts.shape == (2, 2)
    np.testing.assert_array_equal(pts, [[0, 1], [2.5, 3]])
    for bad, match in ([[[0, 1], [2]], "needs 2 numbers"], [[["0", 1]], "not a number"],
                       [[[None, 1]], "not a number"],
                       [5, "must be a list"], [[[1e7, 0]], "beyond"]):
        with pytest.raises(untrusted.InputError, match=f"F: outline .*{match}"):
            untrusted.points(bad, "F", "outline")
    with pytest.raises(untrusted.InputError, match="100,001 points"):
        untrusted.points([[0, 0]] * 100_001, "F", "outline")


def test_numbers_and_integers_keep_their_ranges():
    assert untrusted.number(3, "F", "x", lo=0, hi=5) == 3.0
    assert untrusted.integer(2.0, "F", "n", lo=1, hi=3) == 2
    for value in (True, "1", None, float("nan"), 10**400):
        with pytest.raises(untrusted.InputError, match="F: x"):
            untrusted.number(value, "F", "x", lo=0, hi=5)
    with pytest.raises(untrusted.InputError, match="above 0"):
        untrusted.number(0, "F", "x", lo=0, hi=5, lo_open=True)
    with pytest.raises(untrusted.InputError, match=r"n = 1e\+20 is out of range \(1 to 3\)"):
        untrusted.integer(10**20, "F", "n", lo=1, hi=3)


def test_an_error_is_always_one_line():
    exc = untrusted.InputError("F.json", "first\nsecond\r\nthird")
    assert str(exc) == "F.json: first second third" and isinstance(exc, ValueError)
