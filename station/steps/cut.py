"""Step 6 of a job: the cut, and the cut record it leaves in the job store.

`cut_job` opens the port (the daemon's caller chose how: a serial device, or the
emulator under a simulation entry point), asks the machine what it did while nobody was
listening (`station.cutting.reconcile`: the piece in flight when the last daemon died may
have finished on the machine's buffered moves), homes or unlocks it if its position was
lost, and streams the pieces not yet cut. Each piece becomes cut in the store only at
its sync point; the piece in progress resumes where its cut stopped
(`station.cutting.resumed_program`).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import serial

from gcode.layout import Layout as MachineLayout
from gcode.machine import Machine
from gcode.program import Program
from gcode.recovery import (
    FINAL_MOVES,
    MARKER_SYSTEM,
    final_moves,
    head_position,
    read_params,
    save_final_moves,
    wait_at_rest,
)
from gcode.stream import BEAM_OFF, Streamer, StreamError
from gcode.toolpath import build_toolpaths
from station.config import Config
from station.cutting import (
    PieceJournal,
    journal_safe_stop,
    reconcile,
    resumed_program,
    stream_with_control,
)
from station.daemon import JobControl, JobInterrupted
from station.jobstore import Job, JobStore

#: opens the station's port from its configuration (the daemon's caller chooses it)
PortOpener = Callable[[Config], serial.SerialBase]


def serial_port(config: Config) -> serial.SerialBase:
    """The configured port: a device path, or a pyserial URL of a handler installed."""
    port, baud = config["serial"]["port"], config["serial"]["baud"]
    if "://" in port:
        return serial.serial_for_url(port, baudrate=baud, timeout=0.02)
    return serial.Serial(port, baud, timeout=0.02)


def port_name(config: Config) -> str:
    """The port as the log names it (a long URL shortened)."""
    port = config["serial"]["port"]
    return port.split("?", 1)[0] if "://" in port else port


def cut_job(job: Job, job_dir: Path, marker: MachineLayout, store: JobStore,
            control: JobControl, *, config: Config, machine: Machine,
            open_port: PortOpener, resuming: bool, pieces: set[str] | None = None) -> None:
    """Stream the pieces of ``marker`` not yet cut (of ``pieces`` only, a bite's, when
    given); each becomes cut at its sync point."""
    index = {p["name"]: p["piece"] for p in store.pieces(job.id)}
    with open_port(config) as port:
        control.start_step("connecting")
        streamer, rest, alarm, params = _connect(port, control, machine, port_name(config))
        reconcile(job, job_dir, store, rest, bool(alarm), params)
        if alarm:
            _regain_position(streamer, job, store, control, alarm)
        left = {p["name"] for p in store.pieces(job.id) if p["state"] != "cut"}
        todo = left if pieces is None else left & pieces
        if not todo:
            return
        # What the marker said is in the store now: clear it, so that a piece cut again
        # cannot be judged by a marker its earlier, interrupted attempt left.
        cleared, _ = streamer.command(f"G10 L2 P{MARKER_SYSTEM} X0 Y0 Z0")
        if cleared.kind != "ok":
            raise RuntimeError(f"the controller refused to clear the piece marker: "
                               f"{cleared.raw}")
        toolpaths = build_toolpaths(marker, machine, only=todo)
        program, journal = resumed_program(toolpaths, machine, store, job, index, job_dir,
                                           head_position(rest, bool(alarm), params),
                                           f"station {job_dir.name}")
        journal.follow(program, machine.cut.feed / 60.0, streamer.time_scale)
        # The geometry a marker refers to, saved before a line goes out: the toolpath
        # order (and so where each contour starts and ends) depends on which pieces
        # are left, so the next start must judge by this program, not a fresh one.
        save_final_moves(job_dir / FINAL_MOVES, job.id, final_moves(program, index))
        result = _stream(streamer, program, journal, store, job, index, len(left), params,
                         control, check=config["machine"]["check_mode"] and not resuming)
        if control.stop.is_set():
            journal_safe_stop(journal, result, streamer.status, params, job_dir)
    if control.abort.is_set():
        raise JobInterrupted("aborted", "aborted by the operator (safe stop)")
    if control.stop.is_set():
        raise JobInterrupted("paused", "interrupted: the daemon stopped (safe stop)")
    if not result.completed:
        raise RuntimeError(f"cut stopped: {result.reason} "
                           f"{(result.fault or {}).get('detail', '')}".strip())


def _connect(port: serial.SerialBase, control: JobControl, machine: Machine, name: str
             ) -> tuple[Streamer, Any, str, dict[str, tuple[float, ...]]]:
    """(streamer, the status read at rest before anything reset the controller, the alarm
    it is in ("" if none), ``$#``). The beam goes off first of all: a lost link may have
    left M4 S700."""
    port.write(BEAM_OFF)
    rest = wait_at_rest(port, stop=lambda: control.stop.is_set() or control.abort.is_set())
    control.checkpoint(hold_in_place=True)  # stopped or aborted while waiting
    streamer = Streamer(port, on_piece=None, name=name, rx_buffer=machine.rx_buffer,
                        acceleration=machine.acceleration, rapid_feed=machine.rapid_feed)
    alarm = "controller in ALARM" if rest is not None and rest.state == "Alarm" else ""
    try:
        streamer.connect(quiet=0.2)  # at rest and silent already (or not answering)
    except StreamError as exc:
        if "ALARM" not in str(exc):
            raise
        alarm = str(exc)
    return streamer, rest, alarm, read_params(streamer)


def _regain_position(streamer: Streamer, job: Job, store: JobStore, control: JobControl,
                     alarm: str) -> None:
    """Position was lost (reset, power cut): home if the machine can, else unlock."""
    homing = streamer.read_settings().get(22, 0.0) >= 1
    store.log(job.id, "machine", f"{alarm}; {'homing' if homing else 'unlocking'}")
    control.start_step("homing" if homing else "unlocking")
    if homing:
        streamer.command("$H", timeout=120.0)
    else:
        streamer.unlock()


def _stream(streamer: Streamer, program: Program, journal: PieceJournal, store: JobStore,
            job: Job, index: dict[str, int], left: int, params: dict[str, tuple[float, ...]],
            control: JobControl, *, check: bool):
    """Run the program (first in check mode ($C) if ``check``), recording each piece at its
    sync point and the progress for the console; the streamer's result."""
    planned = program.check.estimated_seconds if program.check is not None else None
    stage = ["checking ($C)"]

    def on_piece(piece) -> None:
        store.set_piece_state(job.id, index[piece.id], piece.state)
        journal.on_piece(index[piece.id], piece.state)

    def on_progress(p) -> None:
        journal.update(p.lines_acked, streamer.status, params)
        # The streamer's ETA extrapolates the time taken so far; before there is
        # enough of it, the program's own time estimate stands in.
        eta = p.eta_seconds
        if eta is None and planned is not None and stage[0] == "cutting":
            eta = planned * (1.0 - p.fraction)
        control.progress.update(step=stage[0], fraction=p.fraction, seconds_left=eta,
                                machine=p.state, lines_sent=p.lines_sent,
                                lines_total=p.lines_total,
                                pieces_cut=len(index) - left + p.pieces_cut,
                                pieces_total=len(index))

    streamer.on_progress = on_progress
    if check:
        control.start_step(stage[0], 0.0)
        checked = streamer.run(program, check=True)
        if not checked.completed:
            raise ValueError(f"the controller's check mode ($C) refused the program: "
                             f"{checked.reason} {checked.errors[:1]}")
    streamer.on_piece = on_piece
    stage[0] = "cutting"
    control.start_step("cutting", 0.0)
    return stream_with_control(streamer, program, control)
