"""`station gcode` and `station inspect` on a job's marker cut in bites (issue 35): one
bite's program on request, and one line saying how many bites there are otherwise."""

from __future__ import annotations

import json
import re

import numpy as np

from station.cli import main
from station.steps.bites import ROLL_MARGIN_MM, save_bites

from .test_cut_bites import WINDOW, _plan


def _job_folder(tmp_path):
    plan = _plan()  # 0.8 m of marker on a 600 mm window: two bites
    plan.layout.save(tmp_path / "layout.json")
    save_bites(plan, tmp_path / "bites.json")
    return plan, tmp_path / "layout.json"


def _cut_x(program: str) -> np.ndarray:
    """x of every cutting move's end (mm)."""
    return np.array([float(x) for x in re.findall(r"^G[123] X(-?[0-9.]+)", program, re.M)])


def test_station_gcode_cuts_one_bite_where_the_planned_advance_leaves_it(tmp_path, capsys):
    plan, layout = _job_folder(tmp_path)
    out = tmp_path / "bite.nc"
    assert main(["gcode", str(layout), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "the marker is cut in 2 bites" in err and "--bite 1 to 2" in err
    assert len(err.splitlines()) == 1 and not out.exists()
    assert main(["gcode", str(layout), "-o", str(out), "--bite", "3"]) == 2
    assert "not 3" in capsys.readouterr().err
    for k, bite in enumerate(plan.bites, start=1):
        assert main(["gcode", str(layout), "-o", str(out), "--bite", str(k), "--json"]) == 0
        summary = json.loads(capsys.readouterr().out)
        assert summary["bite"] == f"{k} of 2" and summary["pieces"] == len(bite.pieces)
        xs = _cut_x(out.read_text())
        assert xs.max() < WINDOW.length - ROLL_MARGIN_MM  # every bite within the window
        pieces = [p for p in plan.layout.pieces if p.id in bite.pieces]
        first = min(p.outline[:, 0].min() for p in pieces)
        begins = first if k == 1 else first - bite.start_mm + ROLL_MARGIN_MM
        assert abs(xs.min() - begins) < 1.0  # the kerf's offset only


def test_station_inspect_says_a_marker_is_not_a_garment_and_how_to_cut_its_bites(tmp_path,
                                                                                 capsys):
    _, layout = _job_folder(tmp_path)
    assert main(["inspect", str(layout)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "a marker (LAYOUT.json), not a garment" in err and "cut in 2 bites" in err
    assert f"station gcode {layout} --bite K" in err
