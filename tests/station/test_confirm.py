"""`station confirm`: a job whose detected print is uncertain waits for the operator."""

from __future__ import annotations

import importlib.util
import json
import threading
from pathlib import Path

import pytest

from station.cli import main
from station.config import load_config
from station.control import ControlError, request
from station.daemon import CONFIRM_FABRIC, Daemon, JobControl, JobInterrupted, wait_until
from station.jobstore import Job

_spec = importlib.util.spec_from_file_location(
    "daemon_tests", Path(__file__).with_name("test_daemon.py"))
_daemon_tests = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_daemon_tests)

# A pmm check 5 % off square, as the camera measured it: p4m stretched, or pmm.
DETECTED = {"group": "pmm", "w1": [20.0, 0.0], "w2": [0.0, 21.0], "origin": [1.0, 2.0],
            "units": "mm", "kind": "lattice", "confidence": 0.55, "source": "detected"}


class UnsurePipeline(_daemon_tests.TickingPipeline):
    """Detects a print with low confidence, as the station's pipeline then does: the
    FABRIC.json is written and the job waits at 'confirm fabric'."""

    def capture(self, job: Job, workdir: Path, control: JobControl):
        (workdir / "fabric.json").write_text(json.dumps(DETECTED))
        raise JobInterrupted("paused", f"{CONFIRM_FABRIC}: pmm at confidence 0.55")

    def plan(self, job: Job, captured, workdir: Path, control: JobControl):
        self.planned_with = json.loads(Path(job.plan["fabric"]).read_text())
        return super().plan(job, captured, workdir, control)


@pytest.fixture
def station(tmp_path):
    config = load_config(None, {
        "store": {"path": str(tmp_path / "jobs.db"), "work_dir": str(tmp_path / "work")},
        "control": {"socket": str(tmp_path / "station.sock")},
    })
    pipeline = UnsurePipeline(tick=0.02)
    daemon = Daemon(config, pipeline)
    daemon.control.start()
    thread = threading.Thread(target=daemon.run_loop, daemon=True)
    thread.start()
    garment = tmp_path / "shirt.obj"
    garment.write_text("# stand-in\n")
    yield pipeline, tmp_path / "station.sock", garment
    daemon.shutdown()
    thread.join(5)
    daemon.control.stop()


def _state(sock, job):
    return request(sock, "status", job=job)["job"]


def test_uncertain_print_waits_then_the_operator_corrects_it(station, capsys):
    pipeline, sock, garment = station
    job = request(sock, "submit", garment=str(garment), fabric=None)["job"]["id"]
    assert wait_until(lambda: _state(sock, job)["state"] == "paused", 5)
    assert _state(sock, job)["reason"].startswith(CONFIRM_FABRIC)
    # A group the measured lattice cannot carry is refused, and the job keeps waiting.
    assert main(["confirm", str(job), "--group", "p6", "--socket", str(sock)]) == 2
    err = capsys.readouterr().err
    assert "hexagonal" in err
    # ... saying which groups it can carry, and the stretch each needs (nearest first).
    carried = err.split("each needs: ")[1].split(")")[0].split(", ")
    stretch = {g: float(v.rstrip(" %")) for g, v in (c.split(" ", 1) for c in carried)}
    assert {"pmm", "p4m"} <= set(stretch) and "p6" not in stretch and "p3" not in stretch
    assert stretch["pmm"] == 0 and stretch["p4m"] == pytest.approx(2, abs=1)
    assert list(stretch.values()) == sorted(stretch.values())
    assert _state(sock, job)["state"] == "paused"
    assert main(["confirm", str(job), "--group", "p4m", "--socket", str(sock),
                 "--json"]) == 0
    answer = json.loads(capsys.readouterr().out)
    assert answer["group"] == "p4m"
    # The snap to a square lattice stretches the measured one 2.4 %: within tolerance.
    assert "warning" not in answer["message"]
    assert wait_until(lambda: _state(sock, job)["state"] == "done", 10)
    used = pipeline.planned_with
    assert used["group"] == "p4m" and used["detected_group"] == "pmm" and used["confirmed"]
    # Snapped to a square lattice on the measured one (mean length), origin kept, and
    # the stretch that took recorded.
    assert used["w1"][0] == pytest.approx(used["w2"][1]) and used["origin"] == [1.0, 2.0]
    assert used["distortion"]["lattice_strain"] == pytest.approx(0.024, abs=0.002)
    with pytest.raises(ControlError, match="not waiting"):
        request(sock, "confirm", job=job)


def test_accepting_keeps_the_detected_group(station):
    pipeline, sock, garment = station
    job = request(sock, "submit", garment=str(garment), fabric=None)["job"]["id"]
    assert wait_until(lambda: _state(sock, job)["state"] == "paused", 5)
    assert request(sock, "confirm", job=job)["group"] == "pmm"
    assert wait_until(lambda: _state(sock, job)["state"] == "done", 10)
    assert pipeline.planned_with["group"] == "pmm" and pipeline.planned_with["w2"] == [0, 21]


def test_a_correction_that_stretches_the_lattice_is_confirmed_with_a_warning():
    """An operator's group whose lattice is 6 % off the measured one: accepted (the
    operator knows the cloth), and the stretch named as detection names its own."""
    from vision.pipeline import confirm_fabric

    doc = dict(DETECTED, w2=[0.0, 22.4], distortion={"warning": None})
    out = confirm_fabric(doc, "p4m")
    assert out["group"] == "p4m" and out["distortion"]["lattice_strain"] > 0.03
    assert "stretches the measured lattice" in out["distortion"]["warning"]
    assert "lattice_strain" not in confirm_fabric(doc).get("distortion", {})
