"""Cut-ready pieces through the console: align -> nest -> gcode with default options."""

from __future__ import annotations

import json

import numpy as np
import pytest
import shapely

from gcode.machine import default_machine
from gcode.program import load_program
from station.cli import main


@pytest.fixture
def clean_cwd(tmp_path, monkeypatch):
    """No station.toml around: the built-in defaults (10 mm seams, 1000 mm roll)."""
    monkeypatch.delenv("STATION_CONFIG", raising=False)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_default_nest_then_gcode_cuts_garment_pieces_with_allowances(clean_cwd, data_dir,
                                                                     capsys):
    tmp = clean_cwd
    fabric = tmp / "fabric.json"
    fabric.write_text(json.dumps({"group": "p4m", "w1": [50, 0], "w2": [0, 50]}))
    garment = data_dir / "garments" / "berkeley" / "tshirt-coarse.obj"
    assert main(["align", str(garment), "--units", "m", "--fabric", str(fabric),
                 "--restarts", "2", "-o", str(tmp / "P.json")]) == 0
    assert main(["nest", str(tmp / "P.json"), "-o", str(tmp / "L.json"), "--time", "2"]) == 0
    assert main(["gcode", str(tmp / "L.json"), "-o", str(tmp / "J.nc"), "--json"]) == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    layout = json.loads((tmp / "L.json").read_text())
    assert report["pieces"] == len(layout["pieces"]) == 6
    assert layout["allowance"]["seam_mm"] == 10.0 and layout["width"] == 1000.0
    for p in layout["pieces"]:
        cut, sew = shapely.Polygon(p["outline"]), shapely.Polygon(p["sew_line"])
        allowance = np.asarray(p["allowance"])
        assert len(allowance) == len(p["sew_line"]) and set(allowance) <= {10.0, 20.0}
        assert cut.contains(sew.buffer(allowance.min() - 0.5))
        assert sew.buffer(2 * allowance.max() + 0.5).contains(cut)
        assert p["notches"]
        for n in p["notches"]:
            assert 0 < n["depth"] <= allowance.max() / 2
            assert cut.exterior.distance(shapely.Point(n["at"])) < 1e-6
    load_program(tmp / "J.nc", default_machine())  # re-read and re-checked


def test_seam_allowance_option_sets_the_seams(clean_cwd, data_dir, tmp_path, capsys):
    fabric = tmp_path / "fabric.json"
    fabric.write_text(json.dumps({"group": "p4m", "w1": [50, 0], "w2": [0, 50]}))
    garment = data_dir / "garments" / "garment_pattern_generator" / "tee.json"
    assert main(["align", str(garment), "--fabric", str(fabric), "--restarts", "1",
                 "-o", str(tmp_path / "P.json")]) == 0
    (tmp_path / "A.json").write_text(json.dumps({"hem": 30, "opening": 6}))
    assert main(["nest", str(tmp_path / "P.json"), "-o", str(tmp_path / "L.json"),
                 "--time", "1", "--seam-allowance", "15", "--allowance",
                 str(tmp_path / "A.json")]) == 0
    layout = json.loads((tmp_path / "L.json").read_text())
    used = set(np.concatenate([p["allowance"] for p in layout["pieces"]]).tolist())
    assert used == {15.0, 30.0, 6.0}
    (tmp_path / "bad.json").write_text(json.dumps({"no-such-seam": 5}))
    capsys.readouterr()
    assert main(["nest", str(tmp_path / "P.json"), "-o", str(tmp_path / "L2.json"),
                 "--time", "1", "--allowance", str(tmp_path / "bad.json")]) == 2
    (error,) = capsys.readouterr().err.splitlines()  # one line, naming the file
    assert f"{tmp_path / 'bad.json'}: no seam line, opening or piece 'no-such-seam'" in error


def test_pieces_touching_the_selvedge_still_make_a_program(clean_cwd, data_dir, capsys):
    """Gap 0 puts pieces on the fabric's edge: the kerf must not leave the table."""
    tmp = clean_cwd
    assert main(["nest", str(data_dir / "nesting" / "jakobs1.json"), "-o", str(tmp / "L.json"),
                 "--time", "1"]) == 0
    layout = json.loads((tmp / "L.json").read_text())
    ys = np.concatenate([np.asarray(p["outline"])[:, 1] for p in layout["pieces"]])
    # something lies within half a kerf of a selvedge: its kerf would leave the fabric
    assert ys.min() < 0.1 or ys.max() > layout["width"] - 0.1
    assert main(["gcode", str(tmp / "L.json"), "-o", str(tmp / "J.nc")]) == 0
    program = load_program(tmp / "J.nc", default_machine())
    assert len(program.pieces) == len(layout["pieces"])


def _aligned_pants(tmp, data_dir, print_: dict) -> None:
    """The Berkeley trousers aligned on grain under ``print_``, as tmp/P.json."""
    fabric = tmp / "fabric.json"
    fabric.write_text(json.dumps(print_))
    garment = data_dir / "garments" / "berkeley" / "pants-coarse.obj"
    assert main(["align", str(garment), "--units", "m", "--fabric", str(fabric),
                 "--restarts", "2", "-o", str(tmp / "P.json")]) == 0


def test_a_piece_wider_than_the_roll_is_refused_by_name(clean_cwd, data_dir, capsys):
    """Berkeley trousers on grain (legs along the roll) on a 200 mm wide roll: no leg fits
    across it; the operator hears which piece and why."""
    tmp = clean_cwd
    _aligned_pants(tmp, data_dir, {"group": "p4m", "w1": [50, 0], "w2": [0, 50]})
    capsys.readouterr()
    assert main(["nest", str(tmp / "P.json"), "-o", str(tmp / "L.json"), "--time", "1",
                 "--width", "200"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "mm across the roll" in err and "piece" in err


def test_inspect_names_the_openings_an_allowance_file_takes(data_dir, capsys):
    garment = data_dir / "garments" / "berkeley" / "tshirt-coarse.obj"
    assert main(["inspect", str(garment), "--units", "m", "--json"]) == 0
    openings = json.loads(capsys.readouterr().out)["opening_list"]
    assert [o["name"] for o in openings] == ["open#0", "open#1", "open#2", "open#3"]
    assert sorted(o["kind"] for o in openings) == ["hem", "hem", "hem", "opening"]
    neck = next(o for o in openings if o["kind"] == "opening")
    bottom = max(openings, key=lambda o: o["length_mm"])
    assert bottom["kind"] == "hem" and neck["length_mm"] < bottom["length_mm"]


def test_a_marker_longer_than_the_table_is_refused_with_its_cause(clean_cwd, data_dir, capsys):
    """Berkeley trousers on grain need a ~2 m marker; the default table is 1600 mm long.
    nest warns at once, and gcode refuses naming the marker and the table, not a move
    and the kerf (what it said before)."""
    tmp = clean_cwd
    _aligned_pants(tmp, data_dir, {"group": "pmm", "w1": [60, 0], "w2": [0, 80]})
    capsys.readouterr()
    assert main(["nest", str(tmp / "P.json"), "-o", str(tmp / "L.json"), "--time", "2"]) == 0
    layout = json.loads((tmp / "L.json").read_text())
    assert layout["length"] > 1600.0
    assert "table window is 1600 mm" in capsys.readouterr().err
    assert main(["gcode", str(tmp / "L.json"), "-o", str(tmp / "J.nc")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "cuts x=0 to 1600 mm" in err and "--length 1600" in err
    assert not (tmp / "J.nc").exists()
