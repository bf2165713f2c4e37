"""`station gcode` from the console: JSON summary, refusal without writing, profile file."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from gcode.machine import default_machine
from gcode.program import load_program
from station.cli import main

sys.path.insert(0, str(Path(__file__).parent))  # gcode_helpers (importlib mode)
from gcode_helpers import make_layout  # noqa: E402


def test_gcode_command_json(tmp_path, capsys):
    lay = tmp_path / "LAYOUT.json"
    lay.write_text(json.dumps(make_layout()))
    out = tmp_path / "JOB.nc"
    assert main(["gcode", str(lay), "-o", str(out), "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    for key in ("lines", "pieces", "cut_length_mm", "travel_length_mm", "estimated_seconds"):
        assert key in rep
    assert rep["pieces"] == 3 and rep["arcs"] > 0
    prog = load_program(out, default_machine())
    assert len(prog.lines) == rep["lines"] and len(prog.pieces) == 3
    # without arcs the same job needs many more lines
    assert main(["gcode", str(lay), "-o", str(tmp_path / "b.nc"), "--json", "--no-arcs"]) == 0
    rep2 = json.loads(capsys.readouterr().out)
    assert rep2["arcs"] == 0 and rep2["lines"] > 3 * rep["lines"]
    assert abs(rep2["cut_length_mm"] - rep["cut_length_mm"]) < 0.01 * rep["cut_length_mm"]


def test_gcode_command_refuses_and_writes_nothing(tmp_path, capsys):
    lay = tmp_path / "LAYOUT.json"
    lay.write_text(json.dumps(make_layout(origin=(1400.0, 0.0))))
    out = tmp_path / "JOB.nc"
    assert main(["gcode", str(lay), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("station gcode: error: ") and "outside the work area" in err
    assert not out.exists()


def test_gcode_command_with_a_knife_profile(tmp_path, capsys):
    lay = tmp_path / "LAYOUT.json"
    lay.write_text(json.dumps(make_layout()))
    m = tmp_path / "knife.toml"
    m.write_text("[machine]\nname = \"drag knife\"\ntool = \"knife\"\nlaser_mode = false\n"
                 "[cut]\nkerf = 0.0\n")
    out = tmp_path / "JOB.nc"
    assert main(["gcode", str(lay), "--machine", str(m), "-o", str(out), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["machine"] == "drag knife"
    text = out.read_text()
    assert "M4" not in text and "G1 Z-1 F600" in text
