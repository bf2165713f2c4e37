"""An order as a station job (issue 34, item 3): submitted through the daemon's intake (the
order and its patterns copied together, checked garment by garment), planned by the same
steps per garment into one marker and program (each DXF size's unsure seams confirmed
by the operator first), and counted per garment in its status."""

from __future__ import annotations

import dataclasses
import json

import pytest

from gcode.machine import default_machine
from station.config import load_config
from station.control import ControlError, request
from station.daemon import CONFIRM_SEAMS, Daemon, JobControl, JobInterrupted
from station.jobstore import JobStore
from station.progress import garment_counts
from station.seams_confirm import confirm_seams
from station.steps.capture import Captured
from station.steps.plan_order import plan_order
from tests.station.test_daemon_defence import StationChecked, config_file
from tests.station.test_order import P4M_60, TEE_JSON, graded_export
from tests.station.unsure_seams import without_notches


@pytest.fixture(scope="module")
def tee_order(tmp_path_factory):
    folder = tmp_path_factory.mktemp("order-job")
    (folder / "patterns").mkdir()
    without_notches(graded_export(TEE_JSON, folder / "patterns" / "tee.dxf",
                                  {"S": 1.0, "M": 1.06}))  # unsure seams: asked to confirm
    order = folder / "order.toml"
    order.write_text('name = "PO-7"\n[[garment]]\npattern = "patterns/tee.dxf"\n'
                     'sizes = { "S" = 1, "M" = 1 }\n')
    return order


def test_the_daemon_takes_an_order_with_its_patterns_and_refuses_a_bad_one(tee_order,
                                                                            tmp_path):
    config = load_config(config_file(tmp_path))
    daemon = Daemon(config, StationChecked(config))
    daemon.control.start()
    sock = tmp_path / "station.sock"
    try:
        job = request(sock, "submit", garment=str(tee_order))["job"]
        copy = daemon.store.job(job["id"]).garment
        assert copy.endswith("order.toml") and copy != str(tee_order)
        assert (tmp_path / "work" / "inputs").exists()
        copied = [p.name for p in (tmp_path / "work" / "inputs").rglob("*.dxf")]
        assert copied == ["tee.dxf"]  # beside the copy, where the order names it
        bad = tee_order.parent / "bad.toml"
        bad.write_text('[[garment]]\npattern = "patterns/tee.dxf"\nsizes = { "XXL" = 1 }\n')
        with pytest.raises(ControlError, match=rf"^{bad}: garment\[0\]: tee.dxf has no size "
                                               "XXL; sizes are S, M$"):
            request(sock, "submit", garment=str(bad))
        with pytest.raises(ControlError, match="job option size is the order file's"):
            request(sock, "submit", garment=str(tee_order), options={"size": "M"})
        assert len(request(sock, "jobs")["jobs"]) == 1
    finally:
        daemon.control.stop()
        daemon.store.close()
        daemon.lock.release()


def test_an_order_is_planned_per_garment_into_one_marker_and_counted_per_garment(
        tee_order, tmp_path):
    config = load_config(None, {"nest": {"seconds": 1.0, "length_mm": 3000.0}})
    fabric = tmp_path / "fabric.json"
    fabric.write_text(json.dumps(P4M_60))
    store = JobStore(tmp_path / "jobs.db")
    job = store.submit(str(tee_order), None, {"restarts": 2})
    work = tmp_path / "job"
    work.mkdir()
    table = dataclasses.replace(default_machine(), work_area=(0.0, 0.0, 3000.0, 1000.0))
    asked = []
    while True:  # each size an unsure pattern of its own: the operator confirms each once
        try:
            plan = plan_order(job, Captured(str(fabric), P4M_60), work, config, table,
                              JobControl(job.id))
            break
        except JobInterrupted as wait:
            assert wait.reason.startswith(CONFIRM_SEAMS) and len(asked) < 2, wait.reason
            asked.append(wait.reason.split(":")[1].strip())
            confirm_seams(work)
    assert asked == ["tee.dxf size S", "tee.dxf size M"]
    report = json.loads((work / "report.json").read_text())
    assert [g["garment"] for g in report["garments"]] == ["tee-S-1", "tee-M-1"]
    assert all(g["e_fit_aligned_mm2"] < g["e_fit_random_mm2"] for g in report["garments"])
    assert {(p.garment, p.size) for p in plan.layout.pieces} == {("tee-S-1", "S"),
                                                                 ("tee-M-1", "M")}
    assert plan.program.summary()["pieces"] == len(plan.layout.pieces) == 12
    assert (work / "job.nc").is_file()
    placements = json.loads((work / "placement.json").read_text())["garments"]
    assert [g["garment"] for g in placements] == ["tee-S-1", "tee-M-1"]

    record = plan.record()
    store.set_plan(job.id, record)
    store.set_pieces(job.id, plan.pieces)
    first_s = next(k for k, p in enumerate(plan.layout.pieces) if p.garment == "tee-S-1")
    store.set_piece_state(job.id, first_s, "cut")
    status = store.summary(store.job(job.id))
    assert status["garments"] == {"tee-S-1": {"cut": 1, "total": 6},
                                  "tee-M-1": {"cut": 0, "total": 6}}
    assert garment_counts(status) == " (tee-S-1 1/6, tee-M-1 0/6)"
    store.close()
