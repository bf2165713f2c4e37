"""Issue 35, item 8: the roll, the table window and the machine profile are checked against
each other when the daemon starts and when a job is submitted, in one line."""

from __future__ import annotations

from pathlib import Path

import pytest

from gcode.machine import default_machine
from station.cli import main
from station.config import ConfigError, load_config
from station.pipeline import StationPipeline
from station.steps.table import table_window

TEE = Path(__file__).parents[1] / "data" / "garments" / "garment_pattern_generator" / "tee.json"


def _toml(tmp_path, nest: str, machine: str = "") -> str:
    path = tmp_path / "station.toml"
    path.write_text(f"[store]\npath = '{tmp_path}/jobs.db'\nwork_dir = '{tmp_path}/jobs'\n"
                    f"[control]\nsocket = '{tmp_path}/s.sock'\n[nest]\n{nest}\n"
                    f"[machine]\n{machine}\n")
    return str(path)


def test_a_roll_wider_than_the_table_is_refused_at_start_in_one_line(tmp_path, capsys):
    config = _toml(tmp_path, "width_mm = 1200.0")
    assert main(["serve", "--config", config, "--simulate", "--once"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "nest.width_mm 1200 is wider than the table" in err and "1000 mm across" in err
    assert not (tmp_path / "jobs.db").exists()  # refused before the store was opened


def test_a_submission_is_refused_by_the_same_check(tmp_path):
    """A fleet console checks a submission with a pipeline of its own configuration (the
    daemon's intake with the one it started with): a knife table 800 mm across."""
    profile = tmp_path / "knife.toml"
    profile.write_text('[machine]\ntool = "knife"\nlaser_mode = false\n'
                       "work_area = [0, 0, 1200, 800]\n")
    config = load_config(_toml(tmp_path, "length_mm = 1200.0", f"profile = '{profile}'"))
    with pytest.raises(ConfigError, match=r"nest.width_mm 1000 is wider than the table: the "
                       r"machine profile .*knife.toml cuts 800 mm across"):
        StationPipeline(config).check(str(TEE), None, {})
    fits = load_config(_toml(tmp_path, "length_mm = 1200.0\nwidth_mm = 800.0",
                             f"profile = '{profile}'"))
    assert StationPipeline(fits).window.width == 800.0


@pytest.mark.parametrize(("nest", "origin", "message"), [
    ({"length_mm": 1700.0}, [0, 0], "length_mm 1700 is longer than the table"),
    ({"width_mm": 950.0}, [0, 100], "width_mm 950 is wider than the table: .* cuts 900 mm"),
    ({}, [-5, 0], r"fabric_origin \[-5, 0\] lies outside the work area"),
])
def test_every_edge_of_the_window_is_checked(nest, origin, message):
    config = load_config(None, {"nest": nest, "machine": {"fabric_origin": origin}})
    with pytest.raises(ConfigError, match=message):
        table_window(config, default_machine())


def test_the_default_window_is_the_whole_default_table():
    window = table_window(load_config(None), default_machine())
    assert (window.x0, window.y0, window.x1, window.y1) == (0.0, 0.0, 1600.0, 1000.0)
    inset = table_window(load_config(None, {"nest": {"width_mm": 900.0, "length_mm": 1500.0},
                                            "machine": {"fabric_origin": [100, 100]}}),
                         default_machine())
    assert (inset.x1, inset.y1) == (1600.0, 1000.0)


def test_station_nest_warns_of_a_marker_wider_than_the_table_window(tmp_path, capsys):
    shirts = Path(__file__).parents[1] / "data" / "nesting" / "shirts.json"
    out = tmp_path / "layout.json"
    assert main(["nest", str(shirts), "--width", "1200", "--time", "1", "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert ("warning: the marker is 1200 mm wide but the table window is 1000 mm across "
            "(station.toml [nest] width_mm)") in err
    assert main(["nest", str(shirts), "--width", "60", "--time", "1", "-o", str(out)]) == 0
    assert "mm wide" not in capsys.readouterr().err
