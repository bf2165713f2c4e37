"""The cut's bookkeeping with the machine: what it did while nobody listened, and how far
it got within a piece.

`reconcile` records the piece the machine may have finished on its buffered moves after
the daemon died (from the EEPROM markers, see `gcode.recovery`).
`resumed_program` builds the program of the pieces left, the one in progress resumed
where its cut stopped (`gcode.resume`), and `PieceJournal` keeps that place in the job
store while the machine cuts. `stream_with_control` runs the streamer while relaying the
operator's pause, resume and stop.
"""

from __future__ import annotations

import logging
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from gcode.machine import Machine
from gcode.program import PieceMarkers, Program, build_program
from gcode.recovery import (
    FINAL_MOVES,
    head_position,
    load_final_moves,
    piece_finished,
    read_marker,
)
from gcode.resume import (
    OVERLAP_MM,
    STROKES,
    PieceStrokes,
    advance,
    load_strokes,
    piece_strokes,
    resumed_toolpath,
    save_strokes,
    stroke_syncs,
    strokes_before,
)
from gcode.toolpath import PieceToolpath
from station.daemon import JobControl
from station.jobstore import Job, JobStore

log = logging.getLogger("station.cut")

#: journal a piece's progress at most this often (s) and only when it moved (mm)
JOURNAL_EVERY_S = 0.25
JOURNAL_STEP_MM = 1.0


def reconcile(job: Job, job_dir: Path, store: JobStore, rest, alarm: bool,
              params: dict[str, tuple[float, ...]]) -> None:
    """Record the piece the machine finished after the last daemon stopped listening.

    The marker (G59) names the last piece whose final move was reached: phase 2 means
    its final move finished (GRBL writes it only after the motion before it), phase 1
    means every move but the final one finished, and then the head at rest (no alarm:
    the position is trusted) at the final move's end, not its start, proves the final
    move ran too. Anything else leaves the piece unfinished: it resumes where it stopped.
    ``rest`` is the status read before anything reset the controller, ``alarm`` says
    whether its position can be trusted, ``params`` is ``$#``; ``job_dir`` holds the
    final moves saved before the program went out.
    """
    marker = read_marker(params)
    if marker is None or marker.job != job.id:
        return
    piece = marker.piece
    record = next((p for p in store.pieces(job.id) if p["piece"] == piece), None)
    if record is None or record["state"] == "cut" or marker.phase not in (1, 2):
        return
    path = load_final_moves(job_dir / FINAL_MOVES, job.id).get(piece)
    done, why = piece_finished(marker.phase, path, head_position(rest, alarm, params))
    if done:
        store.set_piece_state(job.id, piece, "cut")
    store.log(job.id, "recovery", f"piece {piece} ({record['name']}): the machine "
              f"reports {'it cut' if done else 'it not cut'}: {why}")
    log.warning("job %d piece %d: recovered from the machine: %s", job.id, piece,
                "cut" if done else "not cut")


def resumed_program(toolpaths: list[PieceToolpath], machine: Machine, store: JobStore,
                    job: Job, index: dict[str, int], job_dir: Path, here: np.ndarray | None,
                    title: str) -> tuple[Program, PieceJournal]:
    """The program of ``toolpaths`` (the pieces left) with each piece cut partly before
    resumed `OVERLAP_MM` before where it stopped, first; and the journal that keeps its
    progress. Every piece's strokes are saved before a line goes out (a piece in progress
    keeps those of its first attempt: they are what its progress is measured on).

    ``here``: the head's trusted rest position. After a kill the machine ran on through
    its buffered lines, so the head rests at a line's end further along the piece in
    flight than the journal: the first point of its strokes under the head is where it
    stopped. After a safe stop the journal is exact and the head may rest mid-rapid,
    over a stroke not cut yet: then the head is not asked.
    """
    saved, stopped = load_strokes(job_dir / STROKES, job.id)
    records = {p["piece"]: p for p in store.pieces(job.id)}
    in_flight = next((k for k in saved if records.get(k, {}).get("state") != "cut"), None)
    if stopped is not None and here is not None and float(np.hypot(*(here - stopped[1]))) < 0.05:
        here = None
    resumable = machine.cut.passes == 1  # a second pass retraces the first: cut in full
    first, rest, strokes, bases, dones = [], [], {}, {}, {}
    for tp in toolpaths:
        k = index[tp.id]
        ref = saved.get(k) if resumable else None
        done = float(records[k]["cut_mm"] or 0.0)
        if ref is not None and k == in_flight:
            moved = advance(ref, done, here)
            if moved > done:
                store.log(job.id, "recovery", f"piece {k} ({tp.name}): the head rests "
                          f"{moved - done:.1f} mm further along its cut than the journal")
                done = moved
                store.set_piece_progress(job.id, k, done, ref.total_mm)
        if ref is not None and done > 0.0:
            resumed, bases[k] = resumed_toolpath(tp, ref, done, machine)
            first.append(resumed)
            dones[k] = done
            strokes[k] = ref
            store.log(job.id, "resume", f"piece {k} ({tp.name}) continues at "
                      f"{done:.1f} of {ref.total_mm:.1f} mm, {OVERLAP_MM:g} mm back")
        else:
            rest.append(tp)
            strokes[k], bases[k] = piece_strokes(tp), 0
    program = build_program(first + rest, machine, title=title,
                            markers=PieceMarkers(job.id, index))
    order = {index[tp.id]: strokes[index[tp.id]] for tp in first + rest}
    save_strokes(job_dir / STROKES, job.id, order)
    journal = PieceJournal(store, job.id, order, bases, program, index)
    for k, done in dones.items():
        journal.start_at(k, done)
    return program, journal


def journal_safe_stop(journal: PieceJournal, result, status, params, job_dir: Path) -> None:
    """After a safe stop: the exact progress, and where the head was left (it may rest
    mid-rapid, over a stroke not cut yet), so that the next start does not ask it."""
    at = journal.update(result.lines_acked, status, params, force=True)
    if at is not None:
        save_strokes(job_dir / STROKES, journal.job_id, journal.strokes, stopped=at)


class PieceJournal:
    """Journals how far the machine has cut into the piece in flight: whole strokes once
    their stroke sync is answered (`gcode.program.STROKE_SYNC`), and within the stroke in
    progress, the head's position on it from the streamer's status reports."""

    def __init__(self, store: JobStore, job_id: int, strokes: dict[int, PieceStrokes],
                 bases: dict[int, int], program: Program, index: dict[str, int]) -> None:
        self.store = store
        self.job_id = job_id
        self.strokes = strokes
        self.bases = bases  # piece -> its first stroke in this program (resumed: later)
        self.index = index
        self.follow(program)
        self.in_flight: list[int] = []  # pieces sent and not yet proven cut, in order
        self.done = {k: 0.0 for k in strokes}
        self._grew = time.monotonic()  # when progress last grew
        self._piece: int | None = None  # the piece it grew on
        self._written: dict[int, tuple[float, float]] = {}  # piece -> (mm, when)

    def start_at(self, piece: int, mm: float) -> None:
        """The piece resumes at ``mm`` (already in the store)."""
        self.done[piece] = mm
        self._written[piece] = (mm, time.monotonic())

    def follow(self, program: Program, feed_mm_s: float = np.inf, time_scale: float = 1.0
               ) -> None:
        """Count stroke syncs in ``program`` as streamed (its recovery markers shift every
        ordinal after them); progress within a stroke grows at
        most by what ``feed_mm_s`` cuts in the machine time since it last grew
        (``time_scale``: machine seconds per wall second)."""
        self.syncs = {self.index[pid]: wire for pid, wire in stroke_syncs(program).items()}
        self.feed_mm_s = feed_mm_s
        self.time_scale = time_scale

    def on_piece(self, piece: int, state: str) -> None:
        if state == "cutting" and piece not in self.in_flight:
            self.in_flight.append(piece)
        elif state == "cut" and piece in self.in_flight:
            self.in_flight.remove(piece)

    def update(self, lines_acked: int, status, params: dict[str, tuple[float, ...]],
               force: bool = False) -> tuple[int, np.ndarray] | None:
        """Take the streamer's answered line count and last status; (piece, head) of the
        piece in flight, if any."""
        if not self.in_flight:
            return None
        k = self.in_flight[0]
        now = time.monotonic()
        cut = self.bases[k] + int(np.searchsorted(self.syncs[k], lines_acked))
        synced = strokes_before(self.strokes[k], cut)
        if synced > self.done[k] or k != self._piece:
            # a new stroke (or piece) begins: the head may still be on the rapid to it
            self.done[k], self._grew, self._piece = max(synced, self.done[k]), now, k
        here = head_position(status, False, params) if status is not None else None
        most = 1.5 * self.feed_mm_s * self.time_scale * (now - self._grew) + 2.0
        reached = advance(self.strokes[k], self.done[k], here, stroke=cut, most_mm=most)
        if reached > self.done[k]:
            self.done[k], self._grew = reached, now
        mm, when = self._written.get(k, (0.0, 0.0))
        if self.done[k] > mm and (force or (self.done[k] - mm >= JOURNAL_STEP_MM
                                            and now - when >= JOURNAL_EVERY_S)):
            self.store.set_piece_progress(self.job_id, k, self.done[k],
                                          self.strokes[k].total_mm)
            self._written[k] = (self.done[k], now)
        return None if here is None else (k, here)


def stream_with_control(streamer, program, control: JobControl):
    """Run the streamer in a worker thread while this one relays pause/resume/stop. What
    the run raises (a controller refused before anything moved: $32=0, an alarm) is raised
    here, so that the job records it."""
    out: dict[str, Any] = {}

    def work() -> None:
        try:
            out["result"] = streamer.run(program)
        except Exception as exc:  # noqa: BLE001 - handed to the caller's thread as it is
            out["error"] = exc

    worker = threading.Thread(target=work, name="stream", daemon=True)
    worker.start()
    held = False
    while worker.is_alive():
        if control.abort.is_set() or control.stop.is_set():
            streamer.stop()
        elif control.pause.is_set() and not held:
            streamer.pause()
            held = True
        elif not control.pause.is_set() and held:
            streamer.resume()
            held = False
        worker.join(0.05)
    if "error" in out:
        raise out["error"]
    return out["result"]
