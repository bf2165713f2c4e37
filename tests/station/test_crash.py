"""The station survives SIGKILL and SIGTERM in the middle of a cut without losing or
repeating anything.

The machine is the GRBL emulator on a pseudo-terminal served from this (the test's)
process, while the daemon is a separate `station serve` process that is killed and
restarted: like a real controller, the machine outlives the daemon and finishes the moves
already in its buffers after the kill. The emulator runs here rather than under
`station sim-grbl --pty` because its motion trace (every executed move with its laser
power) is the independent witness of what was really cut, and only this process can read it.
"""

from __future__ import annotations

import json
import os
import random
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from gcode.resume import OVERLAP_MM
from simulators.grbl import GrblEmulator
from simulators.grbl.pty import PtyBridge
from station.config import load_config
from station.control import ControlError, request
from station.daemon import wait_until
from station.jobstore import JobStore
from station.pipeline import StationPipeline

from .fleet_helpers import cutting

ROOT = Path(__file__).resolve().parents[2]
GARMENT = ROOT / "tests" / "data" / "garments" / "berkeley" / "tshirt-coarse.obj"
SETTINGS = {32: 1, 130: 1600, 131: 1000, 20: 1, 22: 1, 23: 3, 110: 12000, 111: 12000,
            120: 1500, 121: 1500}
FABRIC = {"group": "p4m", "w1": [60, 0], "w2": [0, 60], "origin": [0, 0], "units": "mm"}


class Station:
    """A pty machine in this process and `station serve` processes started on demand."""

    SERVE: tuple[str, ...] = ("serve",)  # the daemon's command line before --config

    def __init__(self, tmp: Path, speed: float) -> None:
        self.tmp = tmp
        self.emulator = GrblEmulator(speed=speed, force_origin=True, settings=SETTINGS,
                                     name=f"crash-{os.getpid()}")
        self.bridge = PtyBridge(self.emulator, link=str(tmp / "ttyGRBL"))
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self.bridge.serve, args=(self._stop,),
                                        daemon=True)
        self._thread.start()
        self.config_path = tmp / "station.toml"
        self.config_path.write_text(
            f'[serial]\nport = "{tmp / "ttyGRBL"}"\n'
            f'[store]\npath = "{tmp / "jobs.db"}"\nwork_dir = "{tmp / "work"}"\n'
            f'[control]\nsocket = "{tmp / "station.sock"}"\n'
            "[align]\nrestarts = 1\n[nest]\nseconds = 3.0\n")  # 1 s: no fit under load
        self.socket = tmp / "station.sock"
        self.fabric = tmp / "fabric.json"
        self.fabric.write_text(json.dumps(FABRIC))
        self.proc: subprocess.Popen | None = None
        self.starts = 0
        self.attempts: list[int] = []  # trace index where each resumed attempt begins

    def start(self) -> None:
        self.starts += 1
        log = open(self.tmp / f"daemon-{self.starts}.log", "wb")  # noqa: SIM115
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "station.cli", *self.SERVE, "--config", str(self.config_path)],
            stdout=log, stderr=log, cwd=self.tmp)
        log.close()

        def up() -> bool:
            try:
                return request(self.socket, "ping", timeout=1.0)["pid"] == self.proc.pid
            except (ControlError, OSError):
                return False

        assert wait_until(up, 60, 0.05), self.daemon_log()

    def daemon_log(self) -> str:
        return (self.tmp / f"daemon-{self.starts}.log").read_text(errors="replace")[-3000:]

    def status(self, job: int) -> dict:
        return request(self.socket, "status", job=job)["job"]

    def resume(self, job: int) -> None:
        """Resume once the machine rests: what the trace holds until then is the earlier
        attempts' (a dead daemon's buffered moves run on), everything after is this one's."""
        em = self.emulator
        assert wait_until(lambda: em.state == "Idle" and em.planner_blocks == 0, 60), em.state
        self.attempts.append(len(em.trace))
        request(self.socket, "resume", job=job)

    def status_pieces(self, job: int) -> list[dict]:
        store = JobStore(self.tmp / "jobs.db")
        try:
            return store.pieces(job)
        finally:
            store.close()

    def close(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        self._stop.set()
        self._thread.join(5)
        self.bridge.close()
        self.emulator.close()


@pytest.fixture
def station(tmp_path):
    s = Station(tmp_path, speed=60.0)
    yield s
    s.close()


def piece_cut_paths(program) -> list[np.ndarray]:
    """Points every 0.5 mm along each beam-on move of ``program`` (work mm)."""
    return [pts for contour in contours(program) for pts in contour]


def contours(program) -> list[list[np.ndarray]]:
    """The beam-on moves of ``program`` grouped into contours (a rapid or M5 ends one)."""
    import re

    from gcode.program import strip_comment

    pos = np.zeros(2)
    beam = False
    out: list[list[np.ndarray]] = [[]]
    for line in program.lines:
        code = strip_comment(line).upper().replace(" ", "")
        if not code:
            continue
        w = {k: float(v) for k, v in re.findall(r"([A-Z])([-+]?[0-9.]+)", code)}
        if code.startswith("M4"):
            beam = w.get("S", 0.0) > 0
        elif code.startswith("M5"):
            beam = False
            out.append([])
        g = code[:2] if code[:2] in ("G0", "G1", "G2", "G3") else None
        if g == "G0":
            out.append([])
        if g is None or ("X" not in w and "Y" not in w):
            continue
        target = np.array([w.get("X", pos[0]), w.get("Y", pos[1])])
        if beam and g == "G1":
            n = max(2, int(np.hypot(*(target - pos)) / 0.5) + 1)
            out[-1].append(pos + (target - pos) * np.linspace(0, 1, n)[:, None])
        elif beam and g in ("G2", "G3"):
            c = pos + [w.get("I", 0.0), w.get("J", 0.0)]
            a0 = np.arctan2(*(pos - c)[::-1])
            a1 = np.arctan2(*(target - c)[::-1])
            sweep = (a1 - a0) % (2 * np.pi) if g == "G3" else -((a0 - a1) % (2 * np.pi))
            if abs(sweep) < 1e-9:
                sweep = 2 * np.pi if g == "G3" else -2 * np.pi
            r = np.hypot(*(pos - c))
            n = max(2, int(abs(sweep) * r / 0.5) + 1)
            a = a0 + sweep * np.linspace(0, 1, n)
            out[-1].append(c + r * np.c_[np.cos(a), np.sin(a)])
        pos = target
    return [c for c in out if c]


def check_cut_exactly_once(station: Station, job: int, program_of=None) -> list[float]:
    """The store says every piece cut once; the machine's trace agrees (nothing cut twice
    beyond the resumed attempts' overlap); the mm of closed contours cut twice.
    ``program_of(name)``: the program that cut piece ``name`` alone (default: from the
    job's layout.json, a marker cut whole where it was planned)."""
    store = JobStore(station.tmp / "jobs.db")
    try:
        pieces = store.pieces(job)
        events = store.events(job)
        plan = store.job(job).plan
    finally:
        store.close()
    assert pieces and all(p["state"] == "cut" for p in pieces), pieces
    for p in pieces:
        cut_events = [e for e in events if e["kind"] == "piece"
                      and e["message"] == f"piece {p['piece']} ({p['name']}) cut"]
        assert len(cut_events) == 1, (p, cut_events)
    # The witness: what the machine executed, in order. Every point of every contour must
    # be cut, and a closed contour (it separates the piece) cut once, except where a
    # resumed attempt starts OVERLAP_MM back to join the kerf: the length cut twice is at
    # most that per attempt that reached the contour. Runs end where an attempt ends too:
    # the daemon's restart turned the beam off between them even where the re-cut starts
    # right where the interrupted attempt stopped (no rapid between).
    np.save(station.tmp / "trace.npy", np.array([list(s) for s in station.emulator.trace]))
    trace = station.emulator.trace
    seg = np.array([[s.x0, s.y0, s.x1, s.y1] for s in trace])
    beam_on = cutting(trace)  # a dark braking step does not break a run
    if program_of is None:
        pipeline = StationPipeline(load_config(station.config_path))
        program_of = lambda name: pipeline.program_for(plan["layout"], {name})  # noqa: E731
    retraced_mm = []
    for p in pieces:
        program = program_of(p["name"])
        for c, contour in enumerate(contours(program)):
            samples = densify(np.hstack([np.vstack(contour)[:-1], np.vstack(contour)[1:]]),
                              0.5)
            tree = cKDTree(samples)
            on = beam_on & (np.maximum(tree.query(seg[:, :2])[0], tree.query(seg[:, 2:])[0])
                            < 0.3)
            covered = np.zeros(len(samples), int)
            runs = 0
            for a, b in beam_runs(on, station.attempts):
                hit = cKDTree(densify(seg[a:b])).query(samples)[0] < 0.2
                covered += hit
                runs += bool(hit.any())
            assert covered.min() >= 1, (p["name"], c, "not cut everywhere",
                                        samples[covered == 0][[0, -1]])
            closed = np.hypot(*(samples[0] - samples[-1])) < 0.05
            if closed:
                twice = float(np.hypot(*np.diff(samples, axis=0).T)[
                    (covered[:-1] > 1) & (covered[1:] > 1)].sum())
                retraced_mm.append(twice)
                assert twice <= (runs - 1) * (OVERLAP_MM + 1.0), (p["name"], c, twice, runs)
    return retraced_mm


def beam_runs(on: np.ndarray, breaks: list[int]) -> list[tuple[int, int]]:
    """(first, end) of every run of True in ``on``, a run also ending at each index of
    ``breaks``."""
    runs = []
    for lo, hi in zip([0, *breaks], [*breaks, len(on)], strict=True):
        edges = np.diff(np.concatenate([[0], on[lo:hi].astype(int), [0]]))
        runs += [(lo + int(a), lo + int(b)) for a, b in
                 zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True)]
    return runs


def densify(seg: np.ndarray, step: float = 0.25) -> np.ndarray:
    """Points at most ``step`` mm apart along segments (N, 4)."""
    n = np.maximum(1, np.ceil(np.hypot(*(seg[:, 2:] - seg[:, :2]).T) / step)).astype(int)
    k = np.repeat(np.arange(len(seg)), n + 1)
    t = (np.arange(len(k)) - np.repeat(np.cumsum(n + 1) - (n + 1), n + 1)) / n[k]
    return seg[k, :2] * (1 - t[:, None]) + seg[k, 2:] * t[:, None]


class BeamLength:
    """Millimetres the machine has moved with the beam on so far (read incrementally)."""

    def __init__(self, emulator) -> None:
        self.emulator, self.seen, self.total = emulator, 0, 0.0

    def __call__(self) -> float:
        new = self.emulator.trace[self.seen:]
        self.seen += len(new)
        self.total += sum(float(np.hypot(s.x1 - s.x0, s.y1 - s.y0)) for s in new
                          if s.power > 0 and not s.rapid)
        return self.total


KILLS = 10


def test_sigterm_then_sigkill_at_random_moments_resumes_each_piece_where_it_stopped(
        station):
    rng = random.Random(20261122)
    station.start()
    job = request(station.socket, "submit", garment=str(GARMENT), fabric=str(station.fabric),
                  options={"units": "m"})["job"]["id"]
    assert wait_until(lambda: station.status(job)["pieces"]["cutting"] >= 1, 120), \
        (station.status(job), station.daemon_log())
    # First SIGTERM: a clean stop (feed hold, reset, beam off, state saved), exit 0.
    time.sleep(rng.uniform(0.0, 0.5))
    station.proc.send_signal(signal.SIGTERM)
    assert station.proc.wait(30) == 0, station.daemon_log()
    assert station.emulator.state == "Idle"  # held to a stop before the reset: no alarm
    assert station.emulator.planner_blocks == 0
    assert station.emulator.parser_state.spindle == "M5"
    assert "stopping safely" in station.daemon_log()
    station.start()
    st = station.status(job)
    assert st["state"] == "paused" and "the daemon stopped" in st["reason"], st
    assert st["pieces"]["cutting"] == 0
    station.resume(job)
    store = JobStore(station.tmp / "jobs.db")
    plan = store.job(job).plan
    store.close()
    pipeline = StationPipeline(load_config(station.config_path))
    programs = [pipeline.program_for(plan["layout"], {n}) for n in plan["pieces"]]
    assert len(programs) >= 4
    beam = BeamLength(station.emulator)
    total = sum(float(np.hypot(*np.diff(pts, axis=0).T).sum())
                for prog in programs for pts in piece_cut_paths(prog))
    longest = max(float(np.hypot(*np.diff(pts, axis=0).T).sum())
                  for prog in programs for pts in piece_cut_paths(prog))
    lengths = {name: sum(float(np.hypot(*np.diff(pts, axis=0).T).sum())
                         for pts in piece_cut_paths(prog))
               for name, prog in zip(plan["pieces"], programs, strict=True)}
    assert total > 0
    # Kill moments, drawn afresh after each restart: mostly after a random length of cut
    # (anywhere in the piece being cut or the next), the rest a random 0-60 ms after the
    # controller takes a piece's phase-1 marker (around its final move and sync point).
    # Kills come within the first 60 % of the cut left, so all of them fall during the cut.
    kills = windows = 0
    for _ in range(KILLS):
        # once this attempt streams, the store holds where it started (the journal carried
        # to the head's rest position), so what is left to cut is known
        assert wait_until(lambda: station.status(job)["state"] == "done" or any(
            p["state"] == "cutting" for p in station.status_pieces(job)), 60), \
            (kills, station.status(job), station.daemon_log()[-3000:])
        if station.status(job)["state"] == "done":
            break  # a last short stretch was cut before this loop saw it start (under load)
        pieces = station.status_pieces(job)
        left = sum(p["state"] != "cut" for p in pieces)
        remaining = sum(lengths[p["name"]] - (p["cut_mm"] or 0.0) for p in pieces
                        if p["state"] != "cut")
        base = beam()
        window = rng.random() < 0.4 and left > 1
        target = base + rng.uniform(0.0, min(1.3 * longest, 0.6 * remaining))
        marker0 = station.emulator.params.coord[5].copy()

        def due(target=target, window=window, marker0=marker0) -> bool:
            if window:
                m = station.emulator.params.coord[5]
                return m[2] == 1 and not np.array_equal(m, marker0)
            return beam() >= target

        def ended() -> bool:
            return f"job {job} done" in station.daemon_log()

        assert wait_until(lambda: due() or ended(), 120, 0.002), (
            kills, left, remaining, target - base, beam() - base, station.daemon_log())
        if window:
            time.sleep(rng.uniform(0.0, 0.06))
            windows += 1
        if ended() or station.status(job)["state"] == "done":
            break  # the last stretch (shorter than the store's cut_mm said) ended first
        station.proc.send_signal(signal.SIGKILL)
        station.proc.wait()
        kills += 1
        station.start()
        st = station.status(job)
        assert st["state"] == "paused" and "interrupted" in st["reason"], st
        station.resume(job)
    assert wait_until(lambda: station.status(job)["state"] == "done", 90), \
        (station.status(job), station.daemon_log())
    assert kills >= KILLS // 2, kills
    retraced = check_cut_exactly_once(station, job)
    print(f"closed contours cut twice: {sum(retraced):.1f} mm in all, at most "
          f"{max(retraced):.1f} mm on one")
    print(f"{kills} kills, {windows} around a final move")
    store = JobStore(station.tmp / "jobs.db")
    try:
        assert [j.id for j in store.jobs()] == [job]
        events = store.events(job)
    finally:
        store.close()
    messages = [e["message"] for e in events]
    print("\n".join(m for m in messages if "the machine reports" in m))
    assert sum("paused: interrupted: the daemon was not running" in m for m in messages) == kills
    assert sum(m == "paused -> cutting: resumed by the operator" for m in messages) == kills + 1
    assert any("resume continues from there" in m for m in messages)
    assert messages[-1] == "cutting -> done"
    # event ids are strictly increasing, none lost between the kills
    ids = [e["id"] for e in events]
    assert ids == sorted(ids) and len(set(ids)) == len(ids)


@pytest.fixture
def recovery(tmp_path):
    """A store with one planned job of three pieces and the final moves of its stream."""
    from gcode.recovery import FINAL_MOVES, save_final_moves

    store = JobStore(tmp_path / "jobs.db")
    job = store.submit("shirt.obj", "fabric.json", {})
    store.set_pieces(job.id, ["a", "b", "c"])
    (tmp_path / "layout.json").write_text("{}")
    # piece 1's final move in the program last streamed: a straight line (10,0) -> (10,40)
    save_final_moves(tmp_path / FINAL_MOVES, job.id,
                     {1: np.array([[10.0, 0.0], [10.0, 40.0]])})
    import station.cutting

    # the cut step's reconcile, with the job's folder that holds its final moves
    yield store, job, station.cutting, tmp_path
    store.close()


def _rest(state: str, x: float, y: float):
    from gcode.grbl import Status

    return Status(state=state, mpos=(x, y, 0.0))


@pytest.mark.parametrize("phase,rest,alarm,cut", [
    (2, ("Idle", 300.0, 300.0), False, True),   # marker after the final move: finished
    (2, ("Idle", 10.0, 40.0), True, True),      # ... whatever the position
    (2, ("Idle", 10.0, 20.0), False, False),    # ... unless the head stopped on that move
    (1, ("Idle", 10.0, 40.0), False, True),     # before the final move, head at its end
    (1, ("Idle", 10.0, 0.0), False, False),     # ... head at its start: not run
    (1, ("Idle", 10.0, 25.0), False, False),    # ... stopped half way (held and reset)
    (1, ("Alarm", 10.0, 40.0), True, False),    # ... position lost: cannot prove it
])
def test_recovery_believes_the_machine_only_when_it_proves_the_cut(recovery, phase, rest,
                                                                   alarm, cut):
    store, job, pipeline, plan = recovery
    params = {"G54": (0.0, 0.0, 0.0), "G59": (float(job.id), 2.0, float(phase))}
    pipeline.reconcile(job, plan, store, _rest(*rest), alarm, params)
    states = [p["state"] for p in store.pieces(job.id)]
    assert states == ["pending", "cut" if cut else "pending", "pending"]
    recovery_events = [e for e in store.events(job.id) if e["kind"] == "recovery"]
    assert len(recovery_events) == 1 and "piece 1 (b)" in recovery_events[0]["message"]


def test_recovery_ignores_markers_of_other_jobs_cleared_markers_and_cut_pieces(recovery):
    store, job, pipeline, plan = recovery
    at_end = _rest("Idle", 10.0, 40.0)
    for marker in ((job.id + 1.0, 2.0, 2.0), (0.0, 0.0, 0.0)):
        pipeline.reconcile(job, plan, store, at_end, False, {"G59": marker})
    assert [p["state"] for p in store.pieces(job.id)] == ["pending"] * 3
    store.set_piece_state(job.id, 1, "cut")
    pipeline.reconcile(job, plan, store, at_end, False, {"G59": (float(job.id), 2.0, 2.0)})
    assert sum(e["message"].endswith(" cut") for e in store.events(job.id)) == 1
    assert not [e for e in store.events(job.id) if e["kind"] == "recovery"]


def test_markers_bracket_each_pieces_final_move(tmp_path):
    """Every piece: G59 phase 1 just before its last beam-on move and phase 2 just after,
    both lines the streamer sends alone; nothing else in the program changes."""
    from gcode.program import PieceMarkers, build_program
    from gcode.recovery import final_moves
    from gcode.stream import is_sync_command
    from gcode.toolpath import build_toolpaths

    sys.path.insert(0, str(ROOT / "tests" / "gcode"))  # gcode_helpers (importlib mode)
    from gcode_helpers import make_layout  # a disc with a hole, notch and mark, ...

    (tmp_path / "layout.json").write_text(json.dumps(make_layout()))
    pipeline = StationPipeline(load_config(None))
    program = pipeline.program_for(tmp_path / "layout.json", None)
    index = {r.id: i for i, r in enumerate(program.pieces)}
    toolpaths = build_toolpaths(pipeline.marker_file(tmp_path / "layout.json"),
                                pipeline.machine)
    marked = build_program(toolpaths, pipeline.machine, title=f"station {tmp_path.name}",
                           markers=PieceMarkers(7, index))  # the builder writes them
    assert [ln for ln in marked.lines if not ln.startswith("G10")] == program.lines
    assert len(marked.check.seconds) == len(marked.lines)
    assert [r.id for r in marked.pieces] == [r.id for r in program.pieces]
    finals = final_moves(marked, index)
    for r in marked.pieces:
        body = marked.lines[r.first_line:r.sync_line]
        one = body.index(f"G10 L2 P6 X7 Y{index[r.id] + 1} Z1")
        assert body[one + 2] == f"G10 L2 P6 X7 Y{index[r.id] + 1} Z2"
        motion = re.compile(r"^G[123] ")
        assert motion.match(body[one + 1])
        assert not any(motion.match(ln) for ln in body[one + 2:])
        assert is_sync_command(body[one].replace(" ", ""))
        assert len(finals[index[r.id]]) >= 2
