"""`station confirm` for seams: a job whose CAD pattern has unsure inferred seams waits at
"confirm seams" with the seams drawn and listed, as a job waits at "confirm fabric" (issue
34). The pattern is a CAD-like export of the bundled GPG tee (no seam data in it, its
sleeves unnotched, :mod:`tests.station.unsure_seams`); the
daemon's planning step reads it with the station's own `dxf_job_garment`."""

from __future__ import annotations

import contextlib
import importlib.util
import json
import shutil
import threading
import warnings
from pathlib import Path

import cv2
import pytest

from solver.garment import load_garment
from solver.seams.export import export_cad_dxf
from station.cli import main
from station.config import load_config
from station.control import ControlError, request
from station.daemon import CONFIRM_SEAMS, Daemon, JobControl, wait_until
from station.jobstore import Job
from station.order import read_order
from station.seams_confirm import checked_seams
from station.steps.dxfseams import dxf_job_garment, order_dxf_garments
from station.steps.submission import check_job
from station.web.feed import Feed
from station.web.jobview import JobFiles
from tests.station.unsure_seams import without_notches

_spec = importlib.util.spec_from_file_location(
    "daemon_tests", Path(__file__).with_name("test_daemon.py"))
_daemon_tests = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_daemon_tests)

GPG_TEE = Path(__file__).resolve().parents[1] / "data" / "garments" / \
    "garment_pattern_generator" / "tee.json"  # MIT, bundled
BELOW = 0.9  # seams.confirm_below here: the tee's unnotched sleeve seams score 0.68, the
# body's 0.93-1


class SeamsPipeline(_daemon_tests.TickingPipeline):
    """Plans with the station's DXF step (seams inferred, drawn, confirmed), then cuts as
    the ticking pipeline does."""

    def __init__(self, config) -> None:
        super().__init__(tick=0.02)
        self.config = config
        self.planned = []

    def check(self, garment: str, fabric: str | None, options: dict) -> None:
        pass

    def plan(self, job: Job, captured, workdir: Path, control: JobControl):
        self.planned.append(dxf_job_garment(job, workdir, self.config))
        return super().plan(job, captured, workdir, control)


@pytest.fixture(scope="module")
def tee_dxf(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("cad") / "tee.dxf"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        export_cad_dxf(load_garment(GPG_TEE), out, allowance_mm=10.0, seed=3)
    return without_notches(out, "sleeve")


@contextlib.contextmanager
def served(tmp_path: Path, pipeline_class: type[SeamsPipeline]):
    """A daemon planning with ``pipeline_class`` (seams.confirm_below = BELOW) on its own
    thread: (daemon, pipeline, control socket)."""
    config = load_config(None, {
        "store": {"path": str(tmp_path / "jobs.db"), "work_dir": str(tmp_path / "work")},
        "control": {"socket": str(tmp_path / "station.sock")},
        "seams": {"confirm_below": BELOW},
    })
    pipeline = pipeline_class(config)
    daemon = Daemon(config, pipeline)
    daemon.control.start()
    thread = threading.Thread(target=daemon.run_loop, daemon=True)
    thread.start()
    try:
        yield daemon, pipeline, tmp_path / "station.sock"
    finally:
        daemon.shutdown()
        thread.join(5)
        daemon.control.stop()


@pytest.fixture
def station(tmp_path, tee_dxf):
    with served(tmp_path, SeamsPipeline) as (daemon, pipeline, sock):
        job = request(sock, "submit", garment=str(tee_dxf), fabric=None)["job"]["id"]
        assert wait_until(lambda: _state(sock, job)["state"] == "paused", 10)
        yield daemon, pipeline, sock, job, tmp_path / "work" / f"job-{job}"


def _state(sock, job):
    return request(sock, "status", job=job)["job"]


def _pairs(garment) -> set[frozenset[str]]:
    names = garment.piece_names
    return {frozenset((names[s.piece_a], names[s.piece_b])) for s in garment.seam_lines}


def test_unsure_seams_wait_with_their_picture_and_are_confirmed(station, capsys):
    daemon, pipeline, sock, job, folder = station
    reason = _state(sock, job)["reason"]
    found = json.loads((folder / "seams.json").read_text())
    assert len(found["pieces"]) == 6 and len(found["seams"]) >= 6
    unsure = [s["number"] for s in found["seams"] if s["confidence"] < BELOW]
    assert 0 < len(unsure) < len(found["seams"])
    assert reason.startswith(f"{CONFIRM_SEAMS}: seam(s) {', '.join(map(str, unsure))} of "
                             f"{len(found['seams'])} under confidence {BELOW:g}")
    picture = cv2.imread(str(folder / "seams.png"))
    assert picture is not None and picture.shape[1] == 1800
    # the web console asks the same question, with the picture among the job's files
    questions = Feed(daemon, daemon.console.questions)._questions([_state(sock, job)])
    assert questions == [{"job": job, "question": CONFIRM_SEAMS, "answer": "confirm",
                          "reason": reason}]
    assert "seams.png" in JobFiles(folder.parent).detail(job)["pictures"]
    # accepted as found: planning goes on with exactly those seams, and asks no more
    assert main(["confirm", str(job), "--socket", str(sock), "--json"]) == 0
    answer = json.loads(capsys.readouterr().out)
    assert answer["message"] == f"seams confirmed as found ({len(found['seams'])}); planning"
    assert wait_until(lambda: _state(sock, job)["state"] == "done", 10)
    planned = pipeline.planned[-1]
    assert _pairs(planned) == {frozenset((s["a"], s["b"])) for s in found["seams"]}
    again = json.loads((folder / "seams.json").read_text())["seams"]
    assert all(s["source"] == "declared" and s["confidence"] == 1.0 for s in again)
    with pytest.raises(ControlError, match="not waiting"):
        request(sock, "confirm", job=job)


def test_a_correction_is_checked_then_planned_with(station, tmp_path, capsys):
    _, pipeline, sock, job, folder = station
    found = json.loads((folder / "seams.json").read_text())
    sleeves = next(s for s in found["seams"] if s["confidence"] < BELOW)
    # a piece the pattern lacks: refused at once, the job keeps waiting
    with pytest.raises(ControlError, match="no piece 'collar'"):
        request(sock, "confirm", job=job, seams={"not_seams": [[sleeves["a"], "collar"]]})
    assert _state(sock, job)["state"] == "paused"
    # ends that are no points pass the quick check, but planning refuses them and asks again
    bad = {"seams": [{"a": "front", "a_ends": "here", "b": "back", "b_ends": [[0, 0]]}]}
    request(sock, "confirm", job=job, seams=bad)
    assert wait_until(lambda: "were refused" in (_state(sock, job)["reason"] or ""), 10)
    assert _state(sock, job)["state"] == "paused"
    # the operator's veto of one unsure pair: planned without that seam, the rest inferred
    veto = tmp_path / "veto.json"
    veto.write_text(json.dumps({"not_seams": [[sleeves["a"], sleeves["b"]]]}))
    assert main(["confirm", str(job), "--seams", str(veto), "--socket", str(sock)]) == 0
    assert "seams corrected by the operator (0 declared, 1 vetoed)" in capsys.readouterr().out
    assert wait_until(lambda: _state(sock, job)["state"] == "done", 10)
    pairs = _pairs(pipeline.planned[-1])
    assert frozenset((sleeves["a"], sleeves["b"])) not in pairs
    assert frozenset(("front", "back")) in pairs


def test_seams_sent_with_the_job_are_not_asked_again(station, tee_dxf, data_dir) -> None:
    _, pipeline, sock, first, folder = station
    found = json.loads((folder / "seams.json").read_text())
    sleeves = next(s for s in found["seams"] if s["confidence"] < BELOW)
    veto = {"not_seams": [[sleeves["a"], sleeves["b"]]]}
    config = load_config(None)
    with pytest.raises(ValueError, match="no piece 'collar'"):
        check_job(str(tee_dxf), None, {"seams": {"not_seams": [["front", "collar"]]}}, config)
    obj = str(data_dir / "garments" / "berkeley" / "pants-coarse.obj")
    with pytest.raises(ValueError, match="job option seams is for a DXF pattern"):
        check_job(obj, None, {"seams": veto, "units": "m"}, config)
    # while the first job waits, one sent with its seams is planned and cut without asking
    job = request(sock, "submit", garment=str(tee_dxf), fabric=None,
                  options={"seams": veto})["job"]["id"]
    assert wait_until(lambda: _state(sock, job)["state"] == "done", 10)
    assert frozenset((sleeves["a"], sleeves["b"])) not in _pairs(pipeline.planned[-1])
    assert _state(sock, first)["state"] == "paused"


class OrderSeamsPipeline(SeamsPipeline):
    """Plans an order's DXF styles with the station's own step, then cuts as the ticking
    pipeline does."""

    def plan(self, job: Job, captured, workdir: Path, control: JobControl):
        self.planned.append(order_dxf_garments(job, read_order(job.garment), workdir,
                                               self.config))
        return _daemon_tests.TickingPipeline.plan(self, job, captured, workdir, control)


def test_an_order_asks_for_each_unsure_style_in_turn_and_never_twice(tmp_path, tee_dxf):
    shutil.copyfile(tee_dxf, tmp_path / "tee.dxf")  # an order's patterns lie beside it
    other = tmp_path / "tee-b.dxf"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        export_cad_dxf(load_garment(GPG_TEE), other, allowance_mm=10.0, seed=5)
    without_notches(other, "sleeve")
    order = tmp_path / "order.toml"
    order.write_text(f'name = "PO-7"\n[[garment]]\npattern = "tee.dxf"\ncopies = 2\n'
                     f'[[garment]]\npattern = "{other.name}"\ncopies = 1\n')
    with served(tmp_path, OrderSeamsPipeline) as (_, pipeline, sock):
        job = request(sock, "submit", garment=str(order), fabric=None)["job"]["id"]
        folder = tmp_path / "work" / f"job-{job}"
        asked = []
        for _ in range(3):  # two styles, each unsure: two questions, then done
            assert wait_until(lambda: _state(sock, job)["state"] in ("paused", "done"), 20)
            if _state(sock, job)["state"] == "done":
                break
            asked.append(_state(sock, job)["reason"])
            listed = json.loads((folder / "seams.json").read_text())
            assert main(["confirm", str(job), "--socket", str(sock)]) == 0
            assert wait_until(lambda: _state(sock, job)["state"] != "paused", 10)
        assert _state(sock, job)["state"] == "done"
    assert [r.split(":")[1].strip() for r in asked] == ["tee.dxf", "tee-b.dxf"]
    assert all(r.startswith(CONFIRM_SEAMS) for r in asked)
    styles = pipeline.planned[-1]
    assert [key[0].name for key in styles] == ["tee.dxf", "tee-b.dxf"]
    for key, garment in styles.items():  # each planned with the seams its question listed
        tag = key[0].stem
        own = json.loads((folder / f"seams-confirmed-{tag}.json").read_text())
        assert _pairs(garment) == {frozenset((s["a"], s["b"])) for s in own["seams"]}
        assert cv2.imread(str(folder / f"seams-{tag}.png")) is not None
    assert own == listed  # the last question's list is what the last style was sewn by
    assert not (folder / "seams-confirmed.json").exists()  # every answer went to its style


def test_infer_must_say_true_or_false():
    with pytest.raises(ValueError, match="infer: true or false"):
        checked_seams({"seams": [], "infer": "no"}, {"front"}, "the seams sent")
    assert checked_seams({"seams": [], "infer": False}, {"front"}, "s")["infer"] is False
