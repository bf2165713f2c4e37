"""station.toml is checked in full: wrong types, ranges and unknown keys fail at load."""

from __future__ import annotations

import argparse
import re

import pytest

from station.cli import main
from station.commands.serve import checked_config
from station.config import EMULATOR_PORT, ConfigError, example_toml, load_config


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


def _program_for(tmp_path, toml: str):
    """The program the station would cut for a one-square layout under ``toml``."""
    import json

    from station.pipeline import StationPipeline

    cfg = tmp_path / "station.toml"
    cfg.write_text(toml)
    layout = tmp_path / "layout.json"
    layout.write_text(json.dumps({"version": 1, "units": "mm", "pieces": [
        {"id": "sq", "outline": [[10, 10], [60, 10], [60, 60], [10, 60]]}]}))
    return StationPipeline(load_config(cfg)).program_for(layout, None)


def test_cut_section_reaches_the_program(tmp_path):
    """Issue 16: `power = 123` used to be checked and then cut at S700."""
    prog = _program_for(tmp_path, "[cut]\npower = 123\nfeed_mm_min = 1500\npasses = 2\n"
                                  "kerf_mm = 0.0\n")
    text = prog.text()
    assert "M4 S123" in text and "S700" not in text
    assert "F1500" in text and "F3000" not in text
    assert text.count("M4 S123") == 2  # two passes
    assert prog.check.cut_powers == (123.0,) and prog.check.cut_feeds == (1500.0,)
    xs = [float(w[1:]) for ln in prog.lines if ln.startswith("G1") for w in ln.split()
          if w.startswith("X")]
    assert min(xs) == 10 and max(xs) == 60  # no kerf offset


@pytest.mark.parametrize("toml,key", [
    ("[cut]\npower = 5000\n", "power"),  # above the profile's max_s
    ("[cut]\nfeed_mm_min = 20000\n", "feed"),  # above max_feed
    ("[cut]\nfeed_mm_min = 10\n", "min_cut_feed"),  # a slow beam burns through
    ("[cut]\npasses = 50\n", "passes"),
    ("[cut]\nkerf_mm = 9\n", "kerf"),
    ("[cut]\npower = inf\n", "power"),
])
def test_cut_section_is_refused_by_file_and_key(tmp_path, toml, key):
    with pytest.raises(ValueError) as exc:
        _program_for(tmp_path, toml)
    msg = str(exc.value)
    assert msg.startswith(str(tmp_path / "station.toml")) and key in msg, msg


@pytest.mark.parametrize(("text", "fault"), [
    ("[station]\nheartbeat_s = 1e300\n", "station.heartbeat_s must be at most 60"),
    ("[station]\nlost_after_s = 1e300\n", "station.lost_after_s must be at most 86400"),
    ("[station]\noutage_s = 1e300\n", "station.outage_s must be at most 86400"),
    ("[allowance]\nseam_mm = 1e300\n", "allowance.seam_mm must be at most 1000"),
    ("[store]\numask = 0\n", "store.umask must keep every permission from others"),
    ("[store]\numask = 0o022\n", "store.umask must keep every permission from others"),
    ('[store]\nurl = "mysql://root:pw@db/jobs"\n', "store.url must be a postgresql:// URL, "
     "not mysql://"),
    ('[station]\nname = "a\\u0000b"\n', "station.name must be at most 64 printable"),
    ('[store]\nurl = "postgresql://station:pw-1234@db/jobs"\n', "store.url holds a password; "
     "put it in PGPASSFILE (~/.pgpass) or PGPASSWORD instead"),
    ('[store]\nurl = "postgresql://station@db/jobs?password=pw-1234"\n',
     "store.url holds a password"),
    ('[store]\nurl = "postgresql://station@[db/jobs"\n', "store.url: not a valid postgresql"),
])
def test_every_limit_is_stated_and_no_password_is_echoed(tmp_path, text, fault):
    path = tmp_path / "station.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=re.escape(fault)) as refused:
        load_config(path)
    assert "pw" not in str(refused.value).replace(str(tmp_path), "")


def test_a_station_names_its_port_and_serve_refuses_without_one(tmp_path, capsys):
    """No emulator default: a daemon on a configuration naming no port refuses to start
    in one line; only `serve --simulate` supplies the emulator."""
    assert load_config(None)["serial"]["port"] == ""
    path = tmp_path / "station.toml"
    path.write_text(f'[store]\npath = "{tmp_path / "jobs.db"}"\n'
                    f'[control]\nsocket = "{tmp_path / "station.sock"}"\n')
    assert main(["serve", "--config", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"serial.port is not set in {path}" in err
    assert "--simulate" in err
    dry_run = argparse.Namespace(simulate=True, config=str(path))
    assert checked_config(dry_run)["serial"]["port"] == EMULATOR_PORT
    assert checked_config(dry_run)["camera"]["source"] == "simulated"
    path.write_text(f'[serial]\nport = "{EMULATOR_PORT}"\n')
    assert main(["serve", "--config", str(path)]) == 2
    assert "is the GRBL emulator: a dry run is `station serve --simulate`" in \
        capsys.readouterr().err
    assert not (tmp_path / "jobs.db").exists()  # refused before the store was opened
