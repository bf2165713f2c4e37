"""Grain on the command line: `station inspect` reports it, `station align` keeps it by
default, and the station's configuration turns it on."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from station.cli import main
from station.config import load_config

DATA = Path(__file__).resolve().parents[1] / "data" / "garments"
PANTS = DATA / "berkeley" / "pants-coarse.obj"
SPEC = DATA / "garment_pattern_generator" / "pants_straight_sides.json"


def run(capsys, argv: list[str]) -> tuple[int, dict | None, str]:
    code = main(argv)
    out, err = capsys.readouterr()
    return code, (json.loads(out) if code == 0 and "--json" in argv else None), err


def test_inspect_reports_each_pieces_grain_and_its_source(capsys, tmp_path):
    code, rep, err = run(capsys, ["inspect", str(PANTS), "--units", "m", "--json",
                                  "--grain-line", "piece1=10"])
    assert code == 0 and err == ""
    sources = [p["grain_source"] for p in rep["piece_list"]]
    pair = [j for i, j in rep["mirror_pairs"] if i == 1] + [i for i, j in
                                                            rep["mirror_pairs"] if j == 1]
    assert pair == [2]  # piece1's mirror image takes the operator's grain, mirrored
    assert sources == ["drape", "operator", "operator", "drape"]
    assert rep["piece_list"][1]["grain_deg"] == pytest.approx(10.0)
    assert abs(rep["piece_list"][0]["grain_deg"] - 90.0) < 5.0  # upright pants piece
    assert rep["grain_guessed"] == []
    # a specification places its panels around the body: that is its drape
    code, rep, err = run(capsys, ["inspect", str(SPEC), "--json"])
    assert code == 0 and rep["grain_guessed"] == [] and err == ""
    assert {p["grain_source"] for p in rep["piece_list"]} == {"drape"}
    # without the placement it is a flat pattern without grain lines: guessed, and said
    spec = json.loads(SPEC.read_text())
    for panel in spec["pattern"]["panels"].values():
        panel.pop("translation", None)
        panel.pop("rotation", None)
    flat = tmp_path / "flat.json"
    flat.write_text(json.dumps(spec))
    code, rep, err = run(capsys, ["inspect", str(flat), "--json"])
    assert code == 0 and rep["grain_guessed"]
    assert "warning" in err and "guessed" in err and err.count("\n") == 1
    assert {p["grain_source"] for p in rep["piece_list"]} == {"outline"}
    code, _, err = run(capsys, ["inspect", str(SPEC), "--grain-line", "sleeve=0"])
    assert code == 2 and "no piece 'sleeve'" in err and err.count("\n") == 1


def test_align_is_on_grain_by_default_and_free_on_request(tmp_path, capsys):
    fabric = tmp_path / "fabric.json"
    fabric.write_text(json.dumps({"group": "pmm", "w1": [60, 0], "w2": [0, 80],
                                  "grain_deg": 90}))
    out = tmp_path / "p.json"
    base = ["align", str(PANTS), "--units", "m", "--fabric", str(fabric), "--restarts", "2",
            "-o", str(out), "--json"]
    code, rep, _ = run(capsys, base)  # the defaults: 0 or 180 degrees, within 1
    doc = json.loads(out.read_text())
    turn = np.array([p["angle_deg"] + 90.0 - p["grain_deg"] for p in doc["pieces"]]) % 180.0
    assert np.all(np.minimum(turn, 180.0 - turn) <= 1.0)
    code, rep, _ = run(capsys, base + ["--nap"])
    assert code == 0
    doc = json.loads(out.read_text())
    assert doc["grain"] == {"tolerance_deg": 1.0, "nap": True, "fabric_grain_deg": 90.0}
    turn = np.array([p["angle_deg"] + 90.0 - p["grain_deg"] for p in doc["pieces"]])
    off = np.abs((turn + 180.0) % 360.0 - 180.0)  # the nap allows 0 only
    assert np.all(off <= 1.0 + 1e-9)
    assert rep["off_grain_max_deg"] == pytest.approx(off.max(), abs=1e-6)
    code, rep, _ = run(capsys, base + ["--grain", "off"])
    assert code == 0 and json.loads(out.read_text())["grain"]["tolerance_deg"] is None
    code, _, err = run(capsys, base + ["--grain", "-3"])
    assert code == 2 and "--grain" in err and err.count("\n") == 1


def test_station_defaults_cut_on_grain_and_bound_reshaping(tmp_path):
    cfg = load_config(None)
    assert cfg["align"]["grain_tolerance_deg"] == 1.0 and cfg["align"]["nap"] is False
    assert cfg["reshape"]["max_move_mm"] == 10.0
    bad = tmp_path / "station.toml"
    bad.write_text("[reshape]\nmax_move_mm = 0\n")
    with pytest.raises(ValueError, match="max_move_mm"):
        load_config(bad)
    bad.write_text('[align]\nup = "w"\n')
    with pytest.raises(ValueError, match="align.up"):
        load_config(bad)


def test_job_options_carry_grain_lines_and_bias_pieces():
    from station.simstation import simulated_pipeline
    from station.steps.garment import grained

    station = simulated_pipeline(load_config(None))
    station.check(str(PANTS), None, {"units": "m", "grain_lines": {"piece0": 45.0},
                                     "bias": ["piece1"]})
    for bad in ({"grain_lines": {"piece0": "up"}}, {"grain_lines": [1]}, {"bias": "piece1"}):
        with pytest.raises(ValueError, match="grain_lines|bias"):
            station.check(str(PANTS), None, {"units": "m", **bad})
    with pytest.raises(ValueError, match="no piece 'sleeve'"):  # refused at submission
        station.check(str(PANTS), None, {"units": "m", "grain_lines": {"sleeve": 0.0}})
    from solver.garment import load_garment

    g = grained(load_garment(PANTS, units="m"), station.config,
                {"grain_lines": {"piece0": 45.0}, "bias": ["piece1"]})
    assert (g.grains()[0].deg, g.grains()[0].source) == (45.0, "operator")
    assert g.grains()[1].bias and not g.grains()[0].bias


def test_nest_keeps_the_placements_grain_and_nap_forbids_the_half_turn(tmp_path, capsys):
    """LAYOUT.json's transform of a piece is its placement frame turned by the nest's move:
    its angle is -angle_deg (placement), plus 180 where the half turn is allowed."""
    fabric = tmp_path / "fabric.json"
    fabric.write_text(json.dumps({"group": "pmm", "w1": [60, 0], "w2": [0, 80]}))
    placement = tmp_path / "p.json"
    assert main(["align", str(PANTS), "--units", "m", "--fabric", str(fabric),
                 "--restarts", "2", "-o", str(placement)]) == 0
    angles = np.array([p["angle_deg"] for p in json.loads(placement.read_text())["pieces"]])
    for extra, allowed in (([], (0.0, 180.0)), (["--nap"], (0.0,))):
        layout = tmp_path / "layout.json"
        capsys.readouterr()
        assert main(["nest", str(placement), "-o", str(layout), "--width", "1000",
                     "--time", "1"] + extra) == 0
        placed = json.loads(layout.read_text())["pieces"]
        turn = np.array([np.degrees(np.arctan2(p["transform"][1][0], p["transform"][0][0]))
                         for p in placed]) + angles
        off = np.abs((turn[:, None] - np.array(allowed)[None] + 180.0) % 360.0 - 180.0)
        assert np.all(off.min(axis=1) < 1e-6), (extra, turn)


@pytest.mark.parametrize("garment", [DATA / "berkeley" / "tshirt-coarse.obj",
                                     DATA.parents[2] / "examples" / "tshirt-iso.obj"],
                         ids=lambda p: p.name)
def test_default_align_with_mirror_pairs_is_on_grain(tmp_path, capsys, garment):
    """Left and right pieces are aligned as mirror images by default; their grains are
    mirrored too, so both halves of every pair land on grain."""
    fabric = tmp_path / "fabric.json"
    fabric.write_text(json.dumps({"group": "pmm", "w1": [60, 0], "w2": [0, 80]}))
    out = tmp_path / "p.json"
    code, rep, _ = run(capsys, ["align", str(garment), "--units", "m", "--fabric",
                                str(fabric), "--restarts", "3", "-o", str(out), "--json"])
    assert code == 0 and rep["symmetry"]["pairs"]  # the mirror-pair path was taken
    doc = json.loads(out.read_text())
    turn = np.array([p["angle_deg"] - p["grain_deg"] for p in doc["pieces"]]) % 180.0
    assert np.all(np.minimum(turn, 180.0 - turn) <= 1.0)
