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
from station.pipeline import StationPipeline

GARMENT = (Path(__file__).resolve().parents[2] / "tests" / "data" / "garments" / "berkeley"
           / "tshirt-coarse.obj")


def _pipeline(monkeypatch, image, mm_per_px, **camera):
    config = load_config(None, {"camera": camera, "nest": {"seconds": 1.0}})
    pipeline = StationPipeline(config, simulate=True)
    monkeypatch.setattr(pipeline, "_photograph", lambda: (image, image, mm_per_px, None))
    return pipeline


def test_plain_cloth_is_nested_without_a_print(tmp_path, monkeypatch):
    image = plain_cloth((640, 480), 0.4 / 0.08, weave="twill", seed=4)
    pipeline = _pipeline(monkeypatch, image, 0.08)
    store = JobStore(tmp_path / "jobs.db")
    job = store.submit(str(GARMENT), None, {"units": "m"})
    control = JobControl(job.id)
    fabric = pipeline.capture(job, tmp_path, control)
    doc = json.loads(Path(fabric).read_text())
    assert doc["group"] is None and doc["kind"] == "plain"
    plan = pipeline.plan(job, fabric, tmp_path, control)
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


def test_stripes_go_on_nested_on_grain_along_the_stripes(tmp_path, monkeypatch):
    """A 1-D stripe print does not stop the job: it is nested as plain fabric with every
    piece's grain on the stripe axis nearest the roll's grain, and the report says so."""
    image = render_print(classic_print("stripes", 12.0, rotation=4.0), (320, 240), 0.5)
    pipeline = _pipeline(monkeypatch, image, 0.5)
    store = JobStore(tmp_path / "jobs.db")
    job = store.submit(str(GARMENT), None, {"units": "m"})
    control = JobControl(job.id)
    fabric = pipeline.capture(job, tmp_path, control)
    doc = json.loads(Path(fabric).read_text())
    assert doc["group"] is None and doc["kind"] == "stripes"
    plan = pipeline.plan(job, fabric, tmp_path, control)
    store.close()
    cloth = json.loads(Path(plan["report"]).read_text())["fabric"]
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
