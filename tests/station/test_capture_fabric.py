"""The station's capture step on what the camera may see: plain cloth goes to plain
nesting; an uncertain print waits at "confirm fabric" with its files written."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from simulators.classics import classic_print
from simulators.cloth import plain_cloth
from simulators.fabric import render_print
from station.config import load_config
from station.daemon import CONFIRM_FABRIC, JobControl, JobInterrupted
from station.jobstore import JobStore
from station.simstation import simulated_pipeline

GARMENT = (Path(__file__).resolve().parents[2] / "tests" / "data" / "garments" / "berkeley"
           / "tshirt-coarse.obj")


def _pipeline(monkeypatch, image, mm_per_px, **camera):
    config = load_config(None, {"camera": camera, "nest": {"seconds": 1.0}})
    pipeline = simulated_pipeline(config)
    monkeypatch.setattr(pipeline, "_photograph", lambda: (image, image, mm_per_px, None))
    return pipeline


def test_plain_cloth_is_nested_without_a_print(tmp_path, monkeypatch):
    image = plain_cloth((640, 480), 0.4 / 0.08, weave="twill", seed=4)
    pipeline = _pipeline(monkeypatch, image, 0.08)
    store = JobStore(tmp_path / "jobs.db")
    job = store.submit(str(GARMENT), None, {"units": "m"})
    control = JobControl(job.id)
    fabric = pipeline.capture(job, tmp_path, control)
    doc = json.loads(Path(fabric.path).read_text())
    assert doc["group"] is None and doc["kind"] == "plain"
    plan = pipeline.plan(job, fabric, tmp_path, control).record()
    store.close()
    layout = json.loads(Path(plan["layout"]).read_text())
    assert len(plan["pieces"]) == len(layout["pieces"]) >= 2
    assert Path(plan["program"]).stat().st_size > 0
    assert json.loads(Path(plan["report"]).read_text())["fabric"]["kind"] == "plain"
    # woven cloth without a print is still cut on grain: every piece's grain along x
    placed = json.loads(Path(plan["placement"]).read_text())
    turn = np.array([p["angle_deg"] - p["grain_deg"] for p in placed["pieces"]]) % 180.0
    assert np.all(np.minimum(turn, 180.0 - turn) <= 1e-9)


def test_an_uncertain_print_pauses_at_confirm_fabric(tmp_path, monkeypatch):
    image = render_print(classic_print("gingham", 30.0, rotation=5.0), (240, 180), 0.5)
    pipeline = _pipeline(monkeypatch, image, 0.5, confirm_below=1.0)  # only a certain answer passes
    store = JobStore(tmp_path / "jobs.db")
    job = store.submit(str(GARMENT), None, {"units": "m"})
    with pytest.raises(JobInterrupted) as exc:
        pipeline.capture(job, tmp_path, JobControl(job.id))
    store.close()
    assert exc.value.state == "paused" and exc.value.reason.startswith(CONFIRM_FABRIC)
    assert f"station confirm {job.id}" in exc.value.reason
    assert json.loads((tmp_path / "fabric.json").read_text())["group"] == "p4m"
    assert cv2.imread(str(tmp_path / "detection.png")) is not None


def _stripes_job(tmp_path, monkeypatch, **options):
    """A t-shirt planned on a 12 mm stripe print turned by 4 degrees: (FABRIC.json
    content, plan, report)."""
    image = render_print(classic_print("stripes", 12.0, rotation=4.0), (320, 240), 0.5)
    pipeline = _pipeline(monkeypatch, image, 0.5)
    store = JobStore(tmp_path / "jobs.db")
    job = store.submit(str(GARMENT), None, {"units": "m", **options})
    control = JobControl(job.id)
    fabric = pipeline.capture(job, tmp_path, control)
    doc = json.loads(Path(fabric.path).read_text())
    assert doc["group"] is None and doc["kind"] == "stripes"
    plan = pipeline.plan(job, fabric, tmp_path, control).record()
    store.close()
    return doc, plan, json.loads(Path(plan["report"]).read_text())


def test_stripes_are_matched_across_the_seams(tmp_path, monkeypatch):
    """By default a stripe print is matched like a 1-D print (pm: a short step along the
    stripes, the period across them): the pieces' grain on the stripe axis, the stripes
    at one height on both sides of the long straight seams, pairs mirrored, and the
    marker keeps every piece on its stripes (verified when it is nested)."""
    from solver.fit import fit_report
    from solver.garment import load_garment
    from solver.placement import Placement

    doc, plan, report = _stripes_job(tmp_path, monkeypatch)
    cloth = report["fabric"]
    assert cloth["kind"] == "stripes" and cloth["group"] == "pm"
    assert "matched across the seams" in cloth["note"]
    assert abs(np.hypot(*cloth["w2"]) - doc["period"]) < 1e-9
    placed = json.loads(Path(plan["placement"]).read_text())
    turn = np.array([p["angle_deg"] - p["grain_deg"] + cloth["grain_deg"]
                     for p in placed["pieces"]]) % 180.0
    assert np.all(np.minimum(turn, 180.0 - turn) <= 1.0)  # grain on the stripe axis
    align = report["align"]
    assert align["e_fit_aligned_mm2"] < 0.9 * align["e_fit_random_mm2"]
    assert {mode for *_, mode in align["symmetry"]["pairs"]} == {"mirror"}
    # the longest seam line (the side seams, straight) carries its stripes across
    placement = Placement.load(plan["placement"])
    garment = load_garment(placement.garment)
    fit = fit_report(garment, placement)
    line = np.asarray(garment.seam_line_of_edge)
    longest = max(np.unique(line), key=lambda k: fit.length[line == k].sum())
    across = np.asarray(cloth["w2"]) / doc["period"]
    assert np.abs(fit.vector[line == longest] @ across).max() < doc["period"] / 20
    layout = json.loads(Path(plan["layout"]).read_text())
    assert len(layout["pieces"]) == len(plan["pieces"]) >= 2


def test_stripes_not_to_match_are_nested_on_grain_along_the_stripes(tmp_path, monkeypatch):
    """With ``match_stripes`` false a 1-D stripe print is nested as plain fabric with every
    piece's grain on the stripe axis nearest the roll's grain, and the report says so."""
    doc, plan, report = _stripes_job(tmp_path, monkeypatch, match_stripes=False)
    cloth = report["fabric"]
    assert cloth["kind"] == "stripes" and "not matched across the seams" in cloth["note"]
    # the grain is a stripe axis (along or across the stripes), the one nearest the roll
    off = (cloth["grain_deg"] - doc["direction_deg"]) % 90.0
    assert min(off, 90.0 - off) < 1e-6 and abs(cloth["grain_deg"]) <= 45.0
    assert 2.0 < abs(cloth["grain_deg"]) < 6.0  # the print was turned by 4 degrees
    placed = json.loads(Path(plan["placement"]).read_text())
    turn = np.array([p["angle_deg"] - p["grain_deg"] + cloth["grain_deg"]
                     for p in placed["pieces"]]) % 180.0
    assert np.all(np.minimum(turn, 180.0 - turn) <= 1e-6)
    layout = json.loads(Path(plan["layout"]).read_text())
    assert len(layout["pieces"]) == len(plan["pieces"]) >= 2
