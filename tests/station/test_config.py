"""station.toml is checked in full: wrong types, ranges and unknown keys fail at load."""

from __future__ import annotations

import pytest

from station.config import ConfigError, example_toml, load_config


def test_defaults_and_overrides():
    cfg = load_config(None, {"nest": {"gap_mm": 5}})
    assert cfg["nest"]["gap_mm"] == 5.0 and isinstance(cfg["nest"]["gap_mm"], float)
    assert cfg["serial"]["baud"] == 115200


def test_example_file_loads_to_the_defaults(tmp_path):
    path = tmp_path / "station.toml"
    path.write_text(example_toml())
    assert load_config(path).values == load_config(None).values


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[serial]\nbaud = 'fast'\n", "serial.baud must be int"),
        ("[serial]\nbuad = 9600\n", "unknown key serial.buad"),
        ("[lasers]\npower = 1\n", r"unknown section \[lasers\]"),
        ("[nest]\ngap_mm = -1\n", "nest.gap_mm must be at least 0"),
        ("[align]\nmethod = 'best'\n", "align.method must be one of paper, global"),
        ("[reshape]\nenabled = 1\n", "reshape.enabled must be bool"),
        ("[serial\n", "not valid TOML"),
    ],
)
def test_bad_configuration_names_file_and_key(tmp_path, text, message):
    path = tmp_path / "station.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=message) as info:
        load_config(path)
    assert str(path) in str(info.value)


def test_missing_file(tmp_path):
    with pytest.raises(ConfigError, match="no such configuration file"):
        load_config(tmp_path / "nope.toml")


def test_relative_paths_resolve_beside_the_file(tmp_path):
    path = tmp_path / "station.toml"
    path.write_text('[store]\npath = "db/jobs.db"\n')
    cfg = load_config(path)
    assert cfg.resolve(cfg["store"]["path"]) == tmp_path / "db" / "jobs.db"
