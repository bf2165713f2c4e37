"""An order that asks for reshaping (issue 35): each style and size of the order reshaped
on its placement by the single garment's step, its copies sharing it, and the marker cut
from the reshaped pattern, which placement.json names in the units it was written in."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from scipy.spatial import cKDTree

from gcode.machine import default_machine
from solver.garment import load_garment
from solver.nest.instance import affine, invert
from station.config import load_config
from station.daemon import JobControl
from station.jobstore import JobStore
from station.order import read_order
from station.steps.capture import Captured
from station.steps.order import load_order_garment
from station.steps.plan_order import plan_order
from station.steps.submission import check_job
from tests.station.test_order import P4M_60, TEE_JSON, graded_export


def test_an_order_asking_for_reshaping_cuts_each_garment_reshaped(tmp_path):
    (tmp_path / "patterns").mkdir()
    graded_export(TEE_JSON, tmp_path / "patterns" / "tee.dxf", {"S": 1.0})
    order = tmp_path / "order.toml"
    order.write_text('name = "PO-8"\n[[garment]]\npattern = "patterns/tee.dxf"\n'
                     'sizes = { "S" = 2 }\n')
    config = load_config(None, {"nest": {"seconds": 0.5, "length_mm": 3000.0},
                                "seams": {"confirm_below": 0.0}})  # its seams taken as found
    check_job(str(order), None, {"reshape": True}, config)  # an order may ask for it
    with pytest.raises(ValueError, match="drop job option symmetrise"):
        check_job(str(order), None, {"symmetrise": True}, config)
    fabric = tmp_path / "fabric.json"
    fabric.write_text(json.dumps(P4M_60))
    store = JobStore(tmp_path / "jobs.db")
    job = store.submit(str(order), None, {"restarts": 1, "reshape": True})
    store.close()
    work = tmp_path / "job"
    work.mkdir()
    table = dataclasses.replace(default_machine(), work_area=(0.0, 0.0, 3000.0, 1000.0))
    plan = plan_order(job, Captured(str(fabric), P4M_60), work, config, table,
                      JobControl(job.id))
    report = json.loads((work / "report.json").read_text())
    (style,) = report["reshape"]["styles"]  # two copies of one size: reshaped once
    assert style["garments"] == ["tee-S-1", "tee-S-2"] and "rejected" not in report["reshape"]
    assert style["e_fit_after_mm2"] < style["e_fit_before_mm2"]
    assert style["e_fit_before_mm2"] == pytest.approx(report["garments"][0]["e_fit_aligned_mm2"])
    # every piece of the marker is cut on the reshaped pattern's sew line, not the drawn one
    reshaped = cKDTree(plan.garment.uv)
    drawn = cKDTree(load_order_garment(read_order(order).garments[0]).uv)
    moved = 0.0
    for piece in plan.layout.pieces:
        pattern_points = affine(invert(piece.transform), piece.sew_line)
        assert reshaped.query(pattern_points)[0].max() < 1e-6
        moved = max(moved, drawn.query(pattern_points)[0].max())
    assert 0.05 < moved <= style["max_displacement_mm"] + 1e-9
    assert len(plan.layout.pieces) == 12
    # placement.json names the reshaped pattern in mm: read back, it is the one cut
    for g in json.loads((work / "placement.json").read_text())["garments"]:
        named = g["placement"]
        assert named["garment"] == str(work / style["reshaped"])
        again = load_garment(named["garment"], units=named["garment_units"])
        assert np.abs(again.uv - plan.garment.uv).max() < 1e-6
