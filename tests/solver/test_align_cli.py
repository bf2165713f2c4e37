"""`station align` end to end: the written placement is what `station fit` measures."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from station.cli import main

PANTS = Path(__file__).resolve().parents[1] / "data" / "garments" / "berkeley" / "pants-coarse.obj"


@pytest.fixture
def fabric(tmp_path):
    path = tmp_path / "fabric.json"
    path.write_text(json.dumps({"group": "p4m", "w1": [4, 0], "w2": [0, 4],
                                "origin": [0.5, 0.2], "units": "cm"}))
    return path


def run_json(capsys, argv):
    assert main(argv) == 0
    out, err = capsys.readouterr()
    return json.loads(out), err


@pytest.mark.parametrize("method", ["paper", "global"])
def test_station_fit_recomputes_every_number_of_the_report(tmp_path, fabric, capsys, method):
    placement = tmp_path / "placement.json"
    png = tmp_path / "aligned.png"
    rep, err = run_json(capsys, ["align", str(PANTS), "--units", "m", "--fabric", str(fabric),
                                 "--method", method, "--restarts", "4", "--seed", "3",
                                 "-o", str(placement), "--json", "--png", str(png)])
    assert "start 4/4" in err  # progress per start on stderr
    for key in ("e_fit_random_mm2", "e_fit_aligned_mm2", "seconds", "method", "restarts"):
        assert key in rep
    assert rep["method"] == method and rep["restarts"] == 4
    assert rep["e_fit_aligned_mm2"] < rep["e_fit_random_mm2"]
    assert png.stat().st_size > 1000
    fit, _ = run_json(capsys, ["fit", str(PANTS), "--units", "m", "--fabric", str(fabric),
                               "--placement", str(placement), "--json"])
    assert fit["e_fit_mm2"] == pytest.approx(rep["e_fit_aligned_mm2"], rel=1e-9)
    for key in ("e_fit_mm2", "e_fit_cm2", "mismatch_mean_mm", "mismatch_max_mm"):
        assert fit[key] == pytest.approx(rep[key], rel=1e-9, abs=1e-9)
    stored = json.loads(placement.read_text())
    assert stored["report"]["e_fit_aligned_mm2"] == rep["e_fit_aligned_mm2"]


def test_grain_option_in_degrees_in_the_file(tmp_path, fabric, capsys):
    placement = tmp_path / "p.json"
    run_json(capsys, ["align", str(PANTS), "--units", "m", "--fabric", str(fabric),
                      "--restarts", "3", "--grain", "2", "-o", str(placement), "--json"])
    pieces = json.loads(placement.read_text())["pieces"]
    assert {p["grain_source"] for p in pieces} == {"drape"}
    rel = np.array([p["angle_deg"] - p["grain_deg"] for p in pieces]) % 180.0
    assert np.all(np.minimum(rel, 180.0 - rel) <= 2.0 + 1e-9)


def test_fixed_piece_keeps_the_initial_placement(tmp_path, fabric, capsys):
    first = tmp_path / "first.json"
    run_json(capsys, ["align", str(PANTS), "--units", "m", "--fabric", str(fabric),
                      "--restarts", "2", "--seed", "9", "-o", str(first), "--json"])
    init = json.loads(first.read_text())
    name = init["pieces"][1]["name"]
    second = tmp_path / "second.json"
    rep, _ = run_json(capsys, ["align", str(PANTS), "--units", "m", "--fabric", str(fabric),
                               "--restarts", "3", "--init", str(first), "--fix", name,
                               "-o", str(second), "--json"])
    again = json.loads(second.read_text())["pieces"][1]
    assert abs(again["angle_deg"] - init["pieces"][1]["angle_deg"]) < 1e-9
    assert np.allclose(again["translation_mm"], init["pieces"][1]["translation_mm"],
                       rtol=0, atol=1e-9)
    assert rep["fixed"] == {name: "both"}


def test_weights_file_and_bad_input(tmp_path, fabric, capsys):
    weights = tmp_path / "w.json"
    weights.write_text(json.dumps({"0": 0.0, "1": 2.0}))
    rep, _ = run_json(capsys, ["align", str(PANTS), "--units", "m", "--fabric", str(fabric),
                               "--restarts", "2", "--weights", str(weights),
                               "-o", str(tmp_path / "p.json"), "--json"])
    assert rep["weights"] == {"0": 0.0, "1": 2.0} and "objective_mm2" in rep
    assert main(["align", str(PANTS), "--units", "m", "--fabric", str(fabric),
                 "--fix", "sleeve", "-o", str(tmp_path / "x.json")]) == 2
    assert "no piece 'sleeve'" in capsys.readouterr().err
    weights.write_text("{not json")
    assert main(["align", str(PANTS), "--units", "m", "--fabric", str(fabric),
                 "--weights", str(weights), "-o", str(tmp_path / "x.json")]) == 2
    assert "w.json: not valid JSON" in capsys.readouterr().err
