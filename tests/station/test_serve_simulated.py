"""`station serve --simulate` as a real process, driven by the console commands.

The console commands run in this process through `station.cli.main` (the same code as the
`station` executable, without paying an interpreter start per command); the daemon is a
subprocess with the GRBL emulator inside it, as `--simulate` configures it.
"""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from station.cli import main
from station.commands.demo import FILES, summarise
from station.config import EMULATOR_PORT
from station.control import ControlError, request
from station.daemon import wait_until

ROOT = Path(__file__).resolve().parents[2]
GARMENT = ROOT / "tests" / "data" / "garments" / "berkeley" / "tshirt-coarse.obj"
FABRIC = {"group": "p4m", "w1": [60, 0], "w2": [0, 60], "origin": [0, 0], "units": "mm"}


@pytest.fixture
def served(tmp_path):
    # Twice the default emulator speed: the cut still lasts seconds, ample for the pause,
    # the Hold and the abort below, and the retried cut watched to the end halves.
    port = EMULATOR_PORT.replace("speed=50", "speed=100")
    config = tmp_path / "station.toml"
    config.write_text(
        f'[serial]\nport = "{port}"\n'
        f'[store]\npath = "{tmp_path / "jobs.db"}"\nwork_dir = "{tmp_path / "work"}"\n'
        f'[control]\nsocket = "{tmp_path / "station.sock"}"\n'
        "[align]\nrestarts = 1\n[nest]\nseconds = 1.0\n")
    log = open(tmp_path / "daemon.log", "wb")  # noqa: SIM115
    proc = subprocess.Popen([sys.executable, "-m", "station.cli", "serve", "--simulate",
                             "--config", str(config)], stdout=log, stderr=log, cwd=tmp_path)
    log.close()
    sock = tmp_path / "station.sock"

    def up() -> bool:
        try:
            return request(sock, "ping", timeout=1.0)["pid"] == proc.pid
        except (ControlError, OSError):
            return False

    assert wait_until(up, 60), (tmp_path / "daemon.log").read_text()
    fabric = tmp_path / "fabric.json"
    fabric.write_text(json.dumps(FABRIC))
    yield proc, sock, fabric, tmp_path
    if proc.poll() is None:
        proc.terminate()
        proc.wait(30)


def console(capsys, *argv: str) -> tuple[int, dict | str]:
    """Run a console command as `station ...` would; JSON answer (or stderr on error)."""
    capsys.readouterr()
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, (json.loads(out) if code == 0 and out.strip().startswith("{") else err)


def test_console_drives_the_simulated_station(served, capsys):
    proc, sock, fabric, tmp = served
    s = ["--socket", str(sock), "--json"]

    def status(job: int) -> dict:
        code, answer = console(capsys, "status", str(job), *s)
        assert code == 0, answer
        return answer["job"]

    # a bad job file: a clear one-line error, and nothing queued
    bad = tmp / "broken.obj"
    bad.write_text("v 0 0 0\nf 1 2 3\n")
    code, err = console(capsys, "submit", str(bad), "--fabric", str(fabric), *s)
    assert code == 2 and "station submit: error:" in err and str(bad) in err, err
    bad_fabric = tmp / "bad.json"
    bad_fabric.write_text("{not json")
    code, err = console(capsys, "submit", str(GARMENT), "--fabric", str(bad_fabric), *s)
    assert code == 2 and "bad.json" in err, err
    assert console(capsys, "jobs", *s)[1]["jobs"] == []

    code, answer = console(capsys, "submit", str(GARMENT), "--fabric", str(fabric),
                           "--units", "m", *s)
    assert code == 0, answer
    job = answer["job"]["id"]
    assert wait_until(lambda: status(job)["pieces"]["cutting"] >= 1, 120), \
        (status(job), (tmp / "daemon.log").read_text()[-3000:])

    # a second (and third...) client while cutting: every answer within a second
    times: list[float] = []

    def client() -> None:
        t0 = time.monotonic()
        request(sock, "status", job=job)
        times.append(time.monotonic() - t0)

    clients = [threading.Thread(target=client) for _ in range(4)]
    for c in clients:
        c.start()
    for c in clients:
        c.join()
    assert len(times) == 4 and max(times) < 1.0, times
    running = status(job)
    assert running["progress"]["step"] == "cutting" and "seconds_left" in running["progress"]

    # pause = feed hold in place; the machine says Hold
    code, answer = console(capsys, "pause", str(job), *s)
    assert code == 0 and "feed hold" in answer["message"], answer
    assert status(job)["state"] == "paused"
    assert wait_until(lambda: status(job)["progress"].get("machine") == "Hold", 5), status(job)
    held = status(job)["progress"]["lines_sent"]
    time.sleep(0.5)
    assert status(job)["pieces"]["cut"] <= running["pieces"]["cut"] + 1
    code, answer = console(capsys, "resume", str(job), *s)
    assert code == 0 and status(job)["state"] == "cutting", answer
    assert wait_until(lambda: status(job)["progress"]["lines_sent"] > held, 10)

    # abort: safe stop, then retry cuts only what was not cut
    code, answer = console(capsys, "abort", str(job), *s)
    assert code == 0, answer
    assert wait_until(lambda: status(job)["state"] == "aborted", 30), status(job)
    cut_before = status(job)["pieces"]["cut"]
    code, err = console(capsys, "retry", "999", *s)
    assert code == 2 and "no job 999" in err
    code, answer = console(capsys, "retry", str(job), *s)
    assert code == 0, answer
    # station watch: a bar per step until the job ends (one line per step off a terminal)
    capsys.readouterr()
    assert main(["watch", str(job), "--socket", str(sock)]) == 0
    watched = capsys.readouterr().err
    assert "cutting ..." in watched and watched.rstrip().endswith("done"), watched
    assert status(job)["state"] == "done"
    final = status(job)
    assert final["pieces"]["cut"] == sum(final["pieces"].values()) >= 4
    code, answer = console(capsys, "log", str(job), "--limit", "1000", *s)
    messages = [e["message"] for e in answer["events"]]
    for n in range(sum(final["pieces"].values())):
        assert sum(m.startswith(f"piece {n} ") and m.endswith(" cut") for m in messages) == 1
    assert sum(m.endswith(" cut") for m in messages) == sum(final["pieces"].values())
    assert cut_before < sum(final["pieces"].values())
    assert "aborted -> submitted: retried by the operator" in messages

    # the preview: the marker over the print of the job's FABRIC.json
    out = tmp / "preview.png"
    code, err = console(capsys, "preview", str(job), "-o", str(out), "--socket", str(sock))
    assert code == 0, err
    image = cv2.imread(str(out))
    assert image is not None and image.shape[1] == 1600
    code, err = console(capsys, "preview", "999", "-o", str(out), "--socket", str(sock))
    assert code == 2 and "no job 999" in err

    # SIGTERM: a clean stop with nothing running
    proc.terminate()
    assert proc.wait(30) == 0
    assert "stopped" in (tmp / "daemon.log").read_text()


def test_progress_bar_redraws_in_place_with_the_time_left():
    import io

    from station.progress import ProgressBar

    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    out = Terminal()
    bar = ProgressBar(out)
    bar.show("nesting", 0.25, None)
    bar.show("cutting", 0.5, 42.0, "3/6 pieces")
    bar.finish("done")
    text = out.getvalue()
    assert "\r  nesting        [#######" in text and " 25%" in text
    assert "[###############...............]  50% ETA   42 s 3/6 pieces" in text
    assert text.rstrip().endswith("done")


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    """`station demo` with small settings, its printout and what its job read and loaded
    (one run shared by the tests below: it takes most of a minute)."""
    import contextlib
    import io

    sys.path.insert(0, str(Path(__file__).parent))  # job_io (importlib mode)
    from job_io import JobIO

    out = tmp_path_factory.mktemp("demo") / "demo-out"
    printed = io.StringIO()
    with pytest.MonkeyPatch.context() as mp, contextlib.redirect_stdout(printed):
        job_io = JobIO(mp, threads=("daemon", "stream"))
        code = main(["demo", "--out", str(out), "--restarts", "1", "--nest-seconds", "1",
                     "--speed", "400"])
    return code, out, printed.getvalue(), job_io


@pytest.mark.slow
def test_demo_runs_a_detected_job_end_to_end_and_writes_every_file(demo):
    """The print is detected (not the truth), every file the README lists is written, and
    the summary agrees with the report."""
    code, out, printed, _ = demo
    assert code == 0, printed
    report = json.loads((out / "report.json").read_text())
    summary = report["summary"]
    assert report["missing"] == [] and all((out / name).is_file() for name in FILES)
    assert summary["fabric_source"] == "detected"
    assert summary["group_detected"] == summary["group_truth"] == "pmm"
    assert summary["lattice_error_mm"] < 1.0
    assert summary["pieces_cut"] == summary["pieces_total"] == 6
    assert summary["e_fit_aligned_cm2"] < summary["e_fit_random_cm2"]
    assert "pieces cut    6/6" in printed and "VISION UNAVAILABLE" not in printed
    # cut-ready by default: every piece on grain (1 deg, fabric x), reshaping bounded
    placed = json.loads((out / "placement.json").read_text())
    assert placed["grain"]["tolerance_deg"] == 1.0
    turn = np.array([p["angle_deg"] - p["grain_deg"] for p in placed["pieces"]]) % 180.0
    assert np.all(np.minimum(turn, 180.0 - turn) <= 1.0)
    assert summary["off_grain_max_deg"] <= 1.0 and "grain: largest off-grain" in printed
    if summary["e_fit_reshaped_cm2"] is not None:
        assert summary["reshape_max_move_mm"] <= 10.0
        assert summary["reshape_area_change_max_pct"] <= 1.0
    frame = cv2.imread(str(out / "frame.png"))
    assert frame is not None and frame.shape[:2] == (960, 1280)
    nc = (out / "job.nc").read_text()
    assert nc.count("G4 P0.01") == 6


@pytest.mark.slow
def test_one_job_loads_its_garment_once_and_reads_back_none_of_its_files(demo):
    """Inside the daemon's process each step hands the next its objects (issue 16): the
    garment is loaded once per plan, however many steps use it (align, reshape, seam
    allowance, nesting, pictures), and no file the job wrote for the operator (FABRIC.json,
    the photo, PLACEMENT.json, LAYOUT.json, the reshaped pattern) is read back."""
    code, out, printed, job_io = demo
    assert code == 0, printed
    report = json.loads((out / "report.json").read_text())
    assert report["plan"]["reshape"].get("rejected") is None  # the reshaped pattern was cut
    assert job_io.written, "the counters saw no file written: they are not installed"
    assert (len(job_io.garment_loads), dict(job_io.read_back)) == (1, {}), (
        job_io.garment_loads, dict(job_io.read_back))


def test_capture_uses_the_simulators_truth_only_when_vision_is_missing(tmp_path, monkeypatch):
    """Without `vision` the dry run still runs, on the known print, and says so."""
    from station.config import load_config
    from station.daemon import JobControl
    from station.jobstore import JobStore
    from station.simstation import simulated_pipeline

    monkeypatch.setitem(sys.modules, "vision.pipeline", None)  # import fails
    store = JobStore(tmp_path / "jobs.db")
    job = store.submit(str(GARMENT), None, {"units": "m"})
    pipeline = simulated_pipeline(load_config(None))
    fabric = json.loads(Path(pipeline.capture(job, tmp_path, JobControl(job.id)).path
                             ).read_text())
    store.close()
    assert fabric["source"] == "simulator truth: vision unavailable"
    camera = json.loads((tmp_path / "camera.json").read_text())
    assert fabric["group"] == camera["truth"]["group"] == "pmm"
    assert fabric["w1"] == camera["truth"]["w1"]
    assert cv2.imread(str(tmp_path / "frame.png")) is not None
    assert not (tmp_path / "detection.png").exists()


def test_an_orders_e_fit_is_summed_over_its_garments_and_each_copy_counts():
    plan = {"order": "PO-1",
            "garments": [{"e_fit_random_mm2": 400.0, "e_fit_aligned_mm2": 100.0},
                         {"e_fit_random_mm2": 600.0, "e_fit_aligned_mm2": 300.0}],
            "reshape": {"styles": [{"garments": ["a-1", "a-2"], "e_fit_after_mm2": 50.0,
                                    "max_displacement_mm": 4.0, "area_change_max_pct": 0.5},
                                   {"garments": ["b-1"], "rejected": "no fit"}]}}
    s = summarise({"pieces": {"cut": 3}}, plan, {}, {}, 1.0)
    assert (s["e_fit_random_cm2"], s["e_fit_aligned_cm2"]) == (10.0, 4.0)
    assert s["e_fit_reshaped_cm2"] == 1.0 and s["reshape_max_move_mm"] == 4.0
