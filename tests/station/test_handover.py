"""A job paused and resumed in the same daemon process is cut from the objects its plan
made, not from the files it wrote (issue 16); the demo's test covers one job straight
through (test_serve_simulated). Without the held plan this test sees LAYOUT.json read."""

from __future__ import annotations

import sys
import threading
from pathlib import Path

from simulators.cloth import plain_cloth
from station.config import SCHEMA, load_config
from station.daemon import JobControl
from station.jobstore import JobStore
from station.simstation import simulated_pipeline

sys.path.insert(0, str(Path(__file__).parent))  # job_io (importlib mode)
from job_io import JobIO  # noqa: E402

GARMENT = (Path(__file__).resolve().parents[2] / "tests" / "data" / "garments" / "berkeley"
           / "tshirt-coarse.obj")


def in_daemon_thread(work):
    """Run ``work()`` in a thread named as the daemon's job thread; return its result."""
    out: dict = {}

    def run() -> None:
        try:
            out["result"] = work()
        except BaseException as exc:  # noqa: BLE001  (re-raised in the test)
            out["error"] = exc

    thread = threading.Thread(target=run, name="daemon")
    thread.start()
    thread.join(120)
    if "error" in out:
        raise out["error"]
    return out["result"]


def test_a_job_resumed_in_the_same_process_cuts_from_its_planned_layout(tmp_path,
                                                                        monkeypatch):
    port = SCHEMA["serial"]["port"].default.replace("speed=50", "speed=400").replace(
        "name=station", f"name=handover-{id(tmp_path)}")
    config = load_config(None, {"nest": {"seconds": 1.0}, "serial": {"port": port},
                                "machine": {"check_mode": False}})
    pipeline = simulated_pipeline(config)
    image = plain_cloth((640, 480), 0.4 / 0.08, weave="twill", seed=4)
    monkeypatch.setattr(pipeline, "_photograph", lambda: (image, image, 0.08, None))
    job_io = JobIO(monkeypatch, threads=("daemon", "stream"))
    store = JobStore(tmp_path / "jobs.db")
    try:
        job = store.submit(str(GARMENT), None, {"units": "m"})
        control = JobControl(job.id)

        def plan():
            captured = pipeline.capture(job, tmp_path, control)
            return pipeline.plan(job, captured, tmp_path, control)

        planned = in_daemon_thread(plan)
        store.set_plan(job.id, planned.record())
        store.set_pieces(job.id, planned.pieces)
        for piece in store.pieces(job.id)[:-1]:  # paused with one piece left to cut
            store.set_piece_state(job.id, piece["piece"], "cut")
        # resumed: run_job starts afresh with the store's copy of the plan
        resumed = store.job(job.id)
        stored = resumed.plan
        assert type(stored) is dict and stored == planned.record()
        in_daemon_thread(lambda: pipeline.cut(resumed, None, store, control, False))
        pieces = store.pieces(job.id)
    finally:
        store.close()
    assert pieces and all(p["state"] == "cut" for p in pieces)
    assert (tmp_path / "layout.json").is_file() and "layout.json" in {
        Path(p).name for p in job_io.written}
    assert (len(job_io.garment_loads), dict(job_io.read_back)) == (1, {}), (
        job_io.garment_loads, dict(job_io.read_back))
