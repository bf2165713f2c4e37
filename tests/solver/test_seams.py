"""Seams inferred from a CAD-like DXF export of a garment whose seams are known (issue 34,
item 2): the exporter writes no seam data, the inference reads only the file."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import pytest

from solver.garment import load_garment
from solver.garment.dxf import read_dxf_pattern
from solver.garment.dxf_garment import sew_pieces
from solver.seams import infer_seams
from solver.seams.export import export_cad_dxf
from solver.seams.names import name_affinity, name_parts
from solver.seams.score import sample_seams, score_seams
from station.cli import main

GPG_TEE = "garments/garment_pattern_generator/tee.json"


def test_names_in_codes_and_languages():
    assert name_parts("REGULAR TEEFR") == ({"front"}, None)
    assert name_parts("right_sleeve_b")[0] == {"sleeve"}
    assert name_parts("Rücken links") == ({"back"}, "left")
    assert name_affinity("left_ftorso", "left_btorso") > name_affinity("left_ftorso",
                                                                       "right_btorso")
    # a right sleeve's back half never meets a left sleeve's front half
    assert name_affinity("right_sleeve_b", "left_sleeve_f") < 0
    assert name_affinity("right_sleeve_b", "right_sleeve_f") > 0
    # a back waistband belongs to the back, and is no back piece for a sleeve
    assert name_affinity("wb_back", "right_btorso") > name_affinity("wb_back", "right_ftorso")
    assert name_affinity("wb_back", "right_sleeve_b") < 0


@pytest.fixture(scope="module")
def tee_export(tmp_path_factory):
    path = Path(__file__).resolve().parents[1] / "data" / GPG_TEE  # MIT: tests/data/garments
    out = tmp_path_factory.mktemp("seams") / "tee.dxf"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        truth = export_cad_dxf(load_garment(path), out, allowance_mm=10.0, seed=3)
    return out, truth


def test_seams_of_a_generated_export_score_against_the_truth(tee_export):
    path, truth = tee_export
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pieces = sew_pieces(read_dxf_pattern(path, allowance_mm=10.0).cut_list())
        seams = infer_seams(pieces)
    score = score_seams(truth, sample_seams(seams, pieces))
    # measured 1.00 / 1.00 for seeds 0-4 (python -m bench seams; 0.911 / 1.00 before the
    # sleeve caps met at the shoulder); the issue asks 0.90
    assert score.recall >= 0.97 and score.precision >= 0.95
    assert all(0 <= s.confidence <= 1 and s.source == "inferred" for s in seams)
    for s in seams:  # every edge is sewn at most once: no two seams overlap on a piece
        for t in seams:
            if t is s:
                continue
            for (p, a0, a1) in ((s.piece_a, s.a_start, s.a_end), (s.piece_b, s.b_start, s.b_end)):
                for (q, b0, b1) in ((t.piece_a, t.a_start, t.a_end),
                                    (t.piece_b, t.b_start, t.b_end)):
                    if p == q:
                        assert min(a1, b1) - max(a0, b0) < 1.0 or a1 <= b0 or b1 <= a0


@pytest.mark.parametrize(("garment", "options", "min_found"), [
    ("garmentcode/tshirt_specification.json", {}, 0.9),  # named left and right halves
    ("berkeley/tshirt-coarse.obj", {"units": "m"}, 0.95),  # unnamed: caps meet at shoulders
    ("garmentcode/pants_specification.json", {}, 0.9),  # back darts, a waistband over them
    ("garmentcode/shirt_mean_specification.json", {}, 0.9),  # its neckline and sleeve hems
    # are as long as each other and unnotched
])
def test_what_is_inferred_is_true(garment, options, min_found, tmp_path):
    """Seams are inferred whole, named halves are told apart, darts marked by notches and
    drill holes are sewn and the waist across them: measured 99.6 / 100 %, 99.4 / 99.4 %
    and 92-98 / 100 % (found / inferred true) for every seed 0-4; the pants were 66 / 100 %
    before darts were marked, the Berkeley tshirt 70 / 100 % before its sleeve caps' halves
    had to meet at a shoulder and its underarm close, 85 / 99.6 % before notches matching
    inside both sides counted double in a notched file (the tshirt 95 / 100 % before a
    front and a back sewn at the side paid less for their shoulder).
    The shirt's neckline was sewn to a sleeve's hem (97 / 89 %) before a notched file's
    long unnotched edges were left open: 94.5-96.7 / 100 % since, seeds 0-4."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        g = load_garment(Path(__file__).resolve().parents[1] / "data" / "garments" / garment,
                         **options)
        truth = export_cad_dxf(g, tmp_path / "g.dxf", allowance_mm=10.0, seed=1)
        pieces = sew_pieces(read_dxf_pattern(tmp_path / "g.dxf", allowance_mm=10.0).cut_list())
        score = score_seams(truth, sample_seams(infer_seams(pieces), pieces))
    assert score.precision >= 0.95 and score.recall >= min_found


def test_inspect_lists_a_dxf_garments_seams(tee_export, capsys):
    path, _ = tee_export
    assert main(["inspect", str(path), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["kind"] == "dxf" and summary["seam_lines"] > 0
    assert all(ln["piece_a"] != ln["piece_b"] for ln in summary["seam_line_list"])


def test_an_operator_vetoes_and_declares_seams_and_sees_them_drawn(tee_export, tmp_path,
                                                                   capsys):
    path, _ = tee_export
    assert main(["inspect", str(path), "--json"]) == 0
    first = json.loads(capsys.readouterr().out)["dxf"]["seams"]
    vetoed = first[-1]  # the longest-listed one, whatever it is
    pair = [vetoed["piece_a"], vetoed["piece_b"]]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pattern = read_dxf_pattern(path, allowance_mm=10.0)
    front = next(p for p in pattern.cut_list() if p.name == pair[0])
    a_ends = front.sew[[0, 3]].tolist()
    other = next(p for p in pattern.cut_list() if p.name == pair[1])
    b_ends = other.sew[[0, 3]].tolist()
    seams_file = tmp_path / "S.json"
    seams_file.write_text(json.dumps({
        "not_seams": [pair],
        "seams": [{"a": pair[0], "a_ends": a_ends, "b": pair[1], "b_ends": b_ends}]}))
    png = tmp_path / "seams.png"
    assert main(["inspect", str(path), "--json", "--seams", str(seams_file),
                 "--png", str(png)]) == 0
    after = json.loads(capsys.readouterr().out)["dxf"]["seams"]
    between = [s for s in after if {s["piece_a"], s["piece_b"]} == set(pair)]
    assert [s["source"] for s in between] == ["declared"]  # vetoed: only the declared one
    assert between[0]["confidence"] == 1.0
    assert png.stat().st_size > 5000
    seams_file.write_text(json.dumps({"not_seams": [[pair[0], "no such piece"]]}))
    assert main(["inspect", str(path), "--seams", str(seams_file)]) == 2
    assert "no piece 'no such piece'" in capsys.readouterr().err
