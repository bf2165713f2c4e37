"""The cut step bite by bite (issue 35): every piece cut once, in bite order, after each
advance measured on the simulated roll; the operator's wait; a kill between bites."""

from __future__ import annotations

import io
import os

import numpy as np
import pytest
import serial

import simulators.grbl  # noqa: F401  (the emulator's grblsim:// URLs)
from gcode.machine import machine_from_dict
from simulators.classics import classic_print
from simulators.fabric import random_print
from simulators.grbl.registry import forget, lookup
from simulators.roll import Conveyor, RollCamera, RollPrint
from solver.nest import NestProblem, Piece
from solver.nest.layout import build_layout
from station.config import load_config
from station.daemon import JobControl, JobInterrupted, wait_until
from station.jobstore import JobStore
from station.progress import follow
from station.steps.bites import (
    CUT_IN_VIEW_MM,
    ROLL_MARGIN_MM,
    operator_advance_mm,
    plan_job_bites,
)
from station.steps.capture import real_camera
from station.steps.cutbites import BiteJournal, cut_in_bites, roll_moved
from station.steps.roll import CameraRoll
from station.steps.table import TableWindow

WINDOW = TableWindow(0.0, 0.0, 600.0, 400.0)


class SimRoll:
    """A roll on the simulated conveyor, counting the advances it was asked for."""

    mm_per_px = 1.0

    def __init__(self, conveyor: bool = True) -> None:
        design = random_print("p2", 50.0, seed=4)
        self.lattice = np.column_stack([design.wallpaper.w1, design.wallpaper.w2])
        self.conveyor = Conveyor(pivot=(299.5, 199.5), seed=8)
        self.camera = RollCamera(RollPrint(design, width=WINDOW.width), self.conveyor,
                                 (WINDOW.x0, WINDOW.y0, WINDOW.x1, WINDOW.y1))
        self.feeds: list[float] = []
        self.feed = self._feed if conveyor else None

    def _feed(self, mm: float) -> None:
        self.feeds.append(mm)
        self.conveyor.advance(mm)

    def photograph(self) -> np.ndarray:
        return self.camera.photograph()

    def settle(self) -> None:
        """The simulated conveyor's moves are over when `advance` returns."""


def _plan():
    """Twelve 120 x 150 mm pieces in two rows, 0.8 m of marker: two bites of the window."""
    pieces = [Piece(f"r{i}", [[0, 0], [120, 0], [120, 150], [0, 150]]) for i in range(12)]
    problem = NestProblem(pieces, width=WINDOW.width, gap=5.0)
    moves = [np.array([[1.0, 0.0, 5.0 + 130.0 * (i // 2)], [0.0, 1.0, 5.0 + 160.0 * (i % 2)]])
             for i in range(12)]
    return plan_job_bites(build_layout(problem, problem.items(), moves), WINDOW, None)


def _job(tmp_path, plan):
    store = JobStore(tmp_path / "jobs.db")
    job = store.submit("squares.json", None, {})
    store.set_pieces(job.id, [p.id for p in plan.layout.pieces])
    return store, job


def _cutter(store, job, calls):
    """A cut that records every piece cut in the store (which refuses a second cut)."""
    index = {p["name"]: p["piece"] for p in store.pieces(job.id)}

    def cut_bite(marker, pieces, _control=None):
        calls.append((marker, set(pieces)))
        for name in sorted(pieces):
            store.set_piece_state(job.id, index[name], "cut")

    return cut_bite


def _run(tmp_path, store, job, plan, roll, calls):
    return cut_in_bites(job, tmp_path, plan, store, JobControl(job.id), roll=roll,
                        lattice=roll.lattice,
                        machine_marker=lambda track, bite: track.bite_layout(plan, bite),
                        cut_bite=_cutter(store, job, calls))


def test_each_bite_is_cut_once_where_the_roll_really_lies(tmp_path):
    plan = _plan()
    assert len(plan.bites) == 2
    store, job = _job(tmp_path, plan)
    roll, calls = SimRoll(), []
    measured = _run(tmp_path, store, job, plan, roll, calls)
    assert [pieces for _, pieces in calls] == [set(b.pieces) for b in plan.bites]
    assert all(p["state"] == "cut" for p in store.pieces(job.id))
    assert {p["name"]: p["bite"] for p in store.pieces(job.id)} == plan.bite_of()
    assert roll.feeds == [measured[1].advance_commanded_mm]
    poses = roll.conveyor.poses
    assert measured[1].advance_measured_mm == pytest.approx(poses[1].along - poses[0].along,
                                                            abs=0.3)
    assert measured[1].skew_deg == pytest.approx(poses[1].angle_deg, abs=0.05)
    for marker, _ in calls:  # every piece within the window, margin kept, after the slip
        xs = np.concatenate([p.outline[:, 0] for p in marker.pieces])
        assert xs.min() > WINDOW.x0 and xs.max() < WINDOW.x1
    report = (tmp_path / "report.json").read_text()
    assert '"advance_measured_mm"' in report


def test_without_a_conveyor_the_job_waits_for_the_operator(tmp_path):
    plan = _plan()
    store, job = _job(tmp_path, plan)
    roll, calls = SimRoll(conveyor=False), []
    with pytest.raises(JobInterrupted) as waiting:
        _run(tmp_path, store, job, plan, roll, calls)
    assert waiting.value.state == "paused"
    mm = operator_advance_mm(waiting.value.reason)
    # the second bite leaves room: the first bite's cut is kept in view across the advance
    assert mm == pytest.approx(plan.bites[0].end_mm - CUT_IN_VIEW_MM, abs=0.05)
    assert mm < plan.bites[1].start_mm - ROLL_MARGIN_MM
    assert [pieces for _, pieces in calls] == [set(plan.bites[0].pieces)]
    roll.conveyor.advance(mm)  # the operator's hands, slip included
    measured = _run(tmp_path, store, job, plan, roll, calls)  # `station resume`
    assert [pieces for _, pieces in calls] == [set(b.pieces) for b in plan.bites]
    poses = roll.conveyor.poses
    assert measured[1].advance_measured_mm == pytest.approx(poses[1].along, abs=0.3)


def test_a_kill_right_after_the_advance_neither_advances_nor_cuts_twice(tmp_path):
    plan = _plan()
    store, job = _job(tmp_path, plan)
    roll, calls = SimRoll(), []

    def killed(mm: float) -> None:  # the conveyor moves, then the power goes
        SimRoll._feed(roll, mm)
        raise KeyboardInterrupt

    roll.feed = killed
    with pytest.raises(KeyboardInterrupt):
        _run(tmp_path, store, job, plan, roll, calls)
    assert BiteJournal.load(tmp_path, plan).advancing == 1
    roll.feed = roll._feed
    _run(tmp_path, store, job, plan, roll, calls)  # the next daemon, same job folder
    assert len(roll.feeds) == 1
    assert [pieces for _, pieces in calls] == [set(b.pieces) for b in plan.bites]
    assert all(p["state"] == "cut" for p in store.pieces(job.id))


def test_a_kill_within_a_bite_resumes_it_on_the_same_marker(tmp_path):
    plan = _plan()
    store, job = _job(tmp_path, plan)
    roll, calls = SimRoll(), []
    index = {p["name"]: p["piece"] for p in store.pieces(job.id)}
    first_try = {}

    cut_whole = _cutter(store, job, calls)

    def cut_bite(marker, pieces, _control):  # the second bite: two cut, then the power goes
        if not pieces <= set(plan.bites[1].pieces):
            return cut_whole(marker, pieces)
        first_try.update({p.id: p.outline for p in marker.pieces})
        for name in sorted(pieces)[:2]:
            store.set_piece_state(job.id, index[name], "cut")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        cut_in_bites(job, tmp_path, plan, store, JobControl(job.id), roll=roll,
                     lattice=roll.lattice,
                     machine_marker=lambda track, bite: track.bite_layout(plan, bite),
                     cut_bite=cut_bite)
    _run(tmp_path, store, job, plan, roll, calls)  # the next daemon
    assert len(roll.feeds) == 1
    marker, pieces = calls[-1]
    assert pieces == set(sorted(plan.bites[1].pieces)[2:])  # only what was left
    for p in marker.pieces:  # the journalled track: the very outlines of the first try
        np.testing.assert_array_equal(p.outline, first_try[p.id])
    assert all(p["state"] == "cut" for p in store.pieces(job.id))


def test_an_operator_who_resumes_without_advancing_is_asked_again(tmp_path):
    plan = _plan()
    store, job = _job(tmp_path, plan)
    roll, calls = SimRoll(conveyor=False), []
    with pytest.raises(JobInterrupted) as first:
        _run(tmp_path, store, job, plan, roll, calls)
    with pytest.raises(JobInterrupted) as again:  # `station resume`, the roll untouched
        _run(tmp_path, store, job, plan, roll, calls)
    assert again.value.state == "paused" and "had not moved" in again.value.reason
    assert operator_advance_mm(again.value.reason) == operator_advance_mm(first.value.reason)
    assert [pieces for _, pieces in calls] == [set(plan.bites[0].pieces)]
    roll.conveyor.advance(operator_advance_mm(again.value.reason))
    measured = _run(tmp_path, store, job, plan, roll, calls)
    assert measured[1].advance_measured_mm == pytest.approx(roll.conveyor.poses[1].along,
                                                            abs=0.3)
    assert [pieces for _, pieces in calls] == [set(b.pieces) for b in plan.bites]


def test_the_print_tells_a_roll_advanced_from_one_that_never_moved_or_moved_part_way():
    roll = SimRoll()
    before = roll.photograph()
    commanded = 430.0
    judged = {}
    for name, moved_mm in (("still", 0.0), ("advanced", commanded), ("part way", 200.0),
                           ("most of the way", 300.0)):
        roll.conveyor.poses[1:] = []
        if moved_mm:
            roll.conveyor.advance(moved_mm)
        judged[name] = roll_moved(before, roll.photograph(), commanded_mm=commanded,
                                  lattice=roll.lattice, mm_per_px=1.0)
    assert judged == {"still": False, "advanced": True, "part way": None,
                      "most of the way": None}


def test_a_roll_found_moved_part_way_leaves_the_job_paused_saying_why(tmp_path):
    plan = _plan()
    store, job = _job(tmp_path, plan)
    roll, calls = SimRoll(), []

    def power_cut(mm: float) -> None:  # the conveyor stops part way, the daemon dies
        # half a repeat (25 mm) off any whole number of repeats short of the advance: a
        # stop within the slip of one would look advanced to the print alone
        roll.conveyor.advance(mm - 275.0)
        raise KeyboardInterrupt

    roll.feed = power_cut
    with pytest.raises(KeyboardInterrupt):
        _run(tmp_path, store, job, plan, roll, calls)
    roll.feed = roll._feed
    with pytest.raises(JobInterrupted) as paused:
        _run(tmp_path, store, job, plan, roll, calls)
    assert paused.value.state == "paused"
    assert paused.value.reason.startswith("bite 2: the print cannot tell whether the roll "
                                          "advanced")
    assert roll.feeds == [] and len(calls) == 1  # nothing advanced or cut on a guess


def test_the_status_names_the_bite_being_cut(tmp_path):
    plan = _plan()
    store, job = _job(tmp_path, plan)
    control, seen = JobControl(job.id), []
    cut_whole = _cutter(store, job, [])

    def cut_bite(marker, pieces, bite_control):
        bite_control.start_step("cutting", 0.0)  # as `station.steps.cut.cut_job` does
        seen.append(dict(control.progress))  # what the daemon's status answer shows
        cut_whole(marker, pieces)

    roll = SimRoll()
    cut_in_bites(job, tmp_path, plan, store, control, roll=roll, lattice=roll.lattice,
                 machine_marker=lambda track, bite: track.bite_layout(plan, bite),
                 cut_bite=cut_bite)
    assert seen == [{"step": "cutting", "fraction": 0.0, "bite": "1 of 2"},
                    {"step": "cutting", "fraction": 0.0, "bite": "2 of 2"}]
    # `station watch`: a bar per bite
    statuses = iter([{"state": "cutting", "reason": "", "pieces": {"cut": 0, "pending": 12},
                      "progress": progress} for progress in seen]
                    + [{"state": "done", "reason": "", "pieces": {"cut": 12}}])
    shown = io.StringIO()
    follow(lambda _job: next(statuses), job.id, stream=shown, interval=0.0)
    assert shown.getvalue().splitlines() == ["  cutting, bite 1 of 2 ...",
                                             "  cutting, bite 2 of 2 ...", "  done"]


def test_a_restarted_station_waits_for_the_relay_conveyor_a_dead_daemon_left_running(
        tmp_path):
    """GRBL reports Idle through a dwell: the relay's run (M8, G4, M9) is waited for by
    the line queued after it, not by the status."""
    name = f"relay-{os.getpid()}"
    url = f"grblsim://?name={name}&speed=10&force_origin=1"
    dead = serial.serial_for_url(url, timeout=0.05)  # the daemon that died
    try:
        dead.write(b"M8\nG4 P4.000\nM9\nG4 P0\n")
        emulator = lookup(name)
        assert wait_until(lambda: emulator.parser_state.flood, 5, 0.01)
        assert emulator.state == "Idle"  # the relay runs the roll, and the status says Idle
        machine = machine_from_dict({"conveyor": {"kind": "relay", "mm_per_s": 100.0}})
        roll = CameraRoll(load_config(None), machine, real_camera,
                          lambda _config: serial.serial_for_url(url, timeout=0.05))
        roll.settle()
        assert not emulator.parser_state.flood  # the relay's M9 has run
    finally:
        dead.close()
        forget(name)


def test_on_stripes_along_the_roll_the_last_cut_tells_an_advance_from_none():
    conveyor = Conveyor(pivot=(199.5, 149.5), seed=8)
    camera = RollCamera(RollPrint(classic_print("stripes", 20.0, rotation=90.0),
                                  width=300.0), conveyor, (0.0, 0.0, 400.0, 300.0))
    before = camera.photograph()
    t = np.linspace(0.0, 2 * np.pi, 90, endpoint=False)
    ring = np.column_stack([360.0 + 30.0 * np.cos(t), 150.0 + 100.0 * np.sin(t)])
    camera.burn(np.column_stack([ring, np.roll(ring, -1, axis=0)]))  # the last bite's cut
    cut = camera.photograph()
    judged = {}
    for name, moved_mm in (("still", 0.0), ("advanced", 330.0)):
        conveyor.poses[1:] = []
        if moved_mm:
            conveyor.advance(moved_mm)
        judged[name] = roll_moved(before, camera.photograph(), commanded_mm=330.0,
                                  lattice=None, mm_per_px=1.0, cut=cut)
    assert judged == {"still": False, "advanced": True}  # told by the kerfs
    # the stripes alone cannot tell
    assert roll_moved(before, camera.photograph(), commanded_mm=330.0, lattice=None,
                      mm_per_px=1.0) is None
