"""Machine profiles (TOML) and LAYOUT.json reading: defaults and one-line errors."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from gcode.layout import layout_from_dict, load_layout
from gcode.machine import default_machine, load_machine
from untrusted import InputError
from untrusted.limits import MAX_FEATURES_PER_PIECE, MAX_LAYOUT_FEATURES

sys.path.insert(0, str(Path(__file__).parent))  # gcode_helpers (importlib mode)
from gcode_helpers import make_layout  # noqa: E402


def test_default_profile_is_the_laser_table():
    m = default_machine()
    assert m.tool == "laser" and m.laser_mode and m.max_s == 1000
    assert m.work_area == (0.0, 0.0, 1600.0, 1000.0)
    assert m.cut.feed <= m.max_feed and m.cut.power <= m.max_s


@pytest.mark.parametrize("text,match", [
    ("[machine]\nspeed = 3\n", "unknown key 'speed' in \\[machine\\]"),
    ("[machine]\nmax_s = \"lots\"\n", "max_s = 'lots': expected a number"),
    ("[machine]\nwork_area = [0, 0, 10]\n", "expected a list of 4 numbers"),
    ("[machine]\nwork_area = [0, 0, -10, 10]\n", "x_max > x_min"),
    ("[cut]\nfeed = 20000\n", "feed 20000 exceeds max_feed"),
    ("[cut]\npower = 2000\n", "power 2000 exceeds max_s"),
    ("[cut]\nnotch = \"round\"\n", "notch must be"),
    ("[cut]\npasses = 0\n", "\\[cut\\] passes = 0: must be in \\[1, 20\\]"),
    ("[laser]\n", "unknown section"),
    ("[machine\n", "not valid TOML"),
    ("[knife]\nz_up = -5\n", "z_up must be above z_down"),
])
def test_bad_profiles_name_file_and_key(tmp_path, text, match):
    p = tmp_path / "m.toml"
    p.write_text(text)
    with pytest.raises(ValueError, match=match) as exc:
        load_machine(p)
    assert str(exc.value).startswith(str(p))


@pytest.mark.parametrize("section,key,value", [
    ("machine", "work_area", "[0, 0, inf, inf]"),
    ("machine", "work_area", "[0, 0, 12000, 1000]"),
    ("machine", "work_area", "[0, nan, 100, 100]"),
    ("machine", "max_s", "inf"),
    ("machine", "max_s", "1e30"),
    ("machine", "max_feed", "nan"),
    ("machine", "rapid_feed", "-1"),
    ("machine", "acceleration", "0"),
    ("machine", "rx_buffer", "100000"),
    ("machine", "rx_buffer", "8"),
    ("machine", "min_cut_feed", "0"),
    ("machine", "min_cut_feed", "5000"),  # above the cutting feed
    ("machine", "park", "[inf, 0]"),
    ("cut", "feed", "inf"),
    ("cut", "power", "-inf"),
    ("cut", "passes", "1000"),
    ("cut", "kerf", "50"),
    ("cut", "lead_in", "1e9"),
    ("cut", "tolerance", "0"),
    ("cut", "tabs", "-1"),
    ("cut", "notch_depth", "nan"),
    ("knife", "z_down", "-inf"),
    ("knife", "plunge_feed", "1e12"),
])
def test_every_bad_number_is_refused_by_file_and_key(tmp_path, section, key, value):
    """Finite numbers in stated ranges only (issue 16): inf passed "> 0" and wrote moves
    off the table, S words of 32 digits and a buffer bigger than GRBL's."""
    p = tmp_path / "m.toml"
    p.write_text(f"[{section}]\n{key} = {value}\n")
    with pytest.raises(ValueError) as exc:
        load_machine(p)
    msg = str(exc.value)
    assert msg.startswith(f"{p}: ") and "\n" not in msg
    assert key in msg, msg


def test_profile_file_overrides(tmp_path):
    p = tmp_path / "m.toml"
    p.write_text("[machine]\ntool = \"knife\"\nlaser_mode = false\nwork_area = [0, 0, 900, 600]\n"
                 "[cut]\nkerf = 0.0\ntabs = 3\n[knife]\nz_down = -2.0\n")
    m = load_machine(p)
    assert m.tool == "knife" and m.work_area == (0, 0, 900, 600) and m.cut.tabs == 3
    assert m.knife.z_down == -2.0 and m.knife.z_up == 5.0
    with pytest.raises(FileNotFoundError, match="machine profile not found"):
        load_machine(tmp_path / "none.toml")


def test_layout_origin_moves_pieces_onto_the_table(tmp_path):
    data = make_layout(origin=(100.0, 50.0))
    p = tmp_path / "LAYOUT.json"
    p.write_text(json.dumps(data))
    lay = load_layout(p)
    assert lay.origin == (100.0, 50.0) and lay.gap == 10
    raw = np.asarray(data["pieces"][0]["outline"])
    assert np.allclose(lay.pieces[0].outline, raw + [100, 50])
    assert np.allclose(lay.pieces[0].marks, [[250, 150]])
    assert np.allclose(lay.pieces[0].notches[0].at, [330, 200])
    assert lay.pieces[2].grainline.shape == (2, 2)


@pytest.mark.parametrize("mutate,match", [
    (lambda d: d.update(units="in"), "units must be"),
    (lambda d: d.pop("pieces"), "missing \"pieces\""),
    (lambda d: d["pieces"][0].update(outline=[[0, 0], [1, 1]]), "at least 3"),
    (lambda d: d["pieces"][0].update(outline=[[0, 0], [1, "a"], [2, 2]]), "list of"),
    (lambda d: d["pieces"][1].update(id="disc#1"), "duplicate id"),
    (lambda d: d["pieces"][0].update(notches=[{"dir": 1}]), "notches\\[0\\]"),
    (lambda d: d.update(version=2), "unsupported layout version"),
])
def test_bad_layouts(mutate, match):
    d = make_layout()
    mutate(d)
    with pytest.raises(ValueError, match=match) as exc:
        layout_from_dict(d, "L.json")
    assert str(exc.value).startswith("L.json")


def test_layout_file_errors(tmp_path):
    p = tmp_path / "L.json"
    p.write_text("{nope")
    with pytest.raises(ValueError, match="not valid JSON"):
        load_layout(p)
    with pytest.raises(FileNotFoundError, match="layout not found"):
        load_layout(tmp_path / "missing.json")


def test_marks_and_notches_are_bounded_before_any_quadratic_work():
    """5,000 marks took 24 s to plan (ordering is quadratic): refused at reading."""
    square = [[100, 100], [900, 100], [900, 700], [100, 700]]
    many = [[500.0, 400.0]] * (MAX_FEATURES_PER_PIECE + 1)
    with pytest.raises(InputError, match=r"pieces\[0\]\.marks has 1,001 elements"):
        layout_from_dict({"pieces": [{"outline": square, "marks": many}]}, "l.json")
    per_piece = [[500.0, 400.0]] * MAX_FEATURES_PER_PIECE
    pieces = [{"id": f"p{i}", "outline": square, "marks": per_piece}
              for i in range(MAX_LAYOUT_FEATURES // MAX_FEATURES_PER_PIECE + 1)]
    with pytest.raises(InputError, match="more than 20,000 marks, notches and holes"):
        layout_from_dict({"pieces": pieces}, "l.json")
