"""The cut's bookkeeping with the machine: what it did while nobody listened, and how far
it got within a piece.

`reconcile` records the piece the machine may have finished on its buffered moves after
the daemon died (from the EEPROM markers, see `gcode.recovery.with_markers`).
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
from gcode.program import Program, build_program
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
)
from gcode.toolpath import PieceToolpath
from station.daemon import JobControl
from station.jobstore import Job, JobStore

log = logging.getLogger("station.pipeline")

#: journal a piece's progress at most this often (s) and only when it moved (mm)
JOURNAL_EVERY_S = 0.25
JOURNAL_STEP_MM = 1.0


def reconcile(job: Job, plan: dict[str, Any], store: JobStore, rest, alarm: bool,
              params: dict[str, tuple[float, ...]]) -> None:
    """Record the piece the machine finished after the last daemon stopped listening.

    The marker (G59) names the last piece whose final move was reached: phase 2 means
    its final move finished (GRBL writes it only after the motion before it), phase 1
    means every move but the final one finished, and then the head at rest (no alarm:
    the position is trusted) at the final move's end, not its start, proves the final
    move ran too. Anything else leaves the piece unfinished: it resumes where it stopped.
    ``rest`` is the status read before anything reset the controller, ``alarm`` says
    whether its position can be trusted, ``params`` is ``$#``.
    """
    marker = read_marker(params)
    if marker is None or marker.job != job.id:
        return
    piece = marker.piece
    record = next((p for p in store.pieces(job.id) if p["piece"] == piece), None)
    if record is None or record["state"] == "cut" or marker.phase not in (1, 2):
        return
    path = load_final_moves(Path(plan["layout"]).parent / FINAL_MOVES, job.id).get(piece)
    done, why = piece_finished(marker.phase, path, head_position(rest, alarm, params))
    if done:
        store.set_piece_state(job.id, piece, "cut")
    store.log(job.id, "recovery", f"piece {piece} ({record['name']}): the machine "
              f"reports {'it cut' if done else 'it not cut'}: {why}")
    log.warning("job %d piece %d: recovered from the machine: %s", job.id, piece,
                "cut" if done else "not cut")


def resumed_program(toolpaths: list[PieceToolpath], machine: Machine, store: JobStore,
                    job: Job, index: dict[str, int], job_dir: Path, here: np.ndarray | None,
                    title: str) -> tuple[Program, dict[int, PieceStrokes]]:
    """The program of ``toolpaths`` (the pieces left) with each piece cut partly before
    resumed `OVERLAP_MM` before where it stopped, first; and every piece's strokes, saved
    before a line goes out (a piece in progress keeps the strokes of its first attempt).

    ``here``: the head's trusted rest position, which carries the journal of the piece in
    flight to where the machine's buffered moves really stopped.
    """
    saved = load_strokes(job_dir / STROKES, job.id)
    records = {p["piece"]: p for p in store.pieces(job.id)}
    in_flight = next((k for k in saved if records.get(k, {}).get("state") != "cut"), None)
    resumable = machine.cut.passes == 1  # a second pass retraces the first: cut in full
    first, rest, strokes = [], [], {}
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
            first.append(resumed_toolpath(tp, ref, done, machine))
            strokes[k] = ref
            store.log(job.id, "resume", f"piece {k} ({tp.name}) continues at "
                      f"{done:.1f} of {ref.total_mm:.1f} mm, {OVERLAP_MM:g} mm back")
        else:
            rest.append(tp)
            strokes[k] = piece_strokes(tp)
    program = build_program(first + rest, machine, title=title)
    save_strokes(job_dir / STROKES, job.id, {index[tp.id]: strokes[index[tp.id]]
                                             for tp in first + rest})
    return program, strokes


class PieceJournal:
    """Journals how far the machine has cut into the piece in flight, from the head
    positions the streamer's status reports give (call `on_piece` and `on_progress`).

    Progress may grow only by what the cutting feed covers in the machine time since the
    head was last seen on the piece's path (``feed_mm_s``, ``time_scale``: machine seconds
    per wall second), so a rapid crossing a later stroke never skips the strokes between.
    """

    def __init__(self, store: JobStore, job_id: int, strokes: dict[int, PieceStrokes],
                 params: dict[str, tuple[float, ...]], feed_mm_s: float,
                 time_scale: float = 1.0) -> None:
        self.store = store
        self.job_id = job_id
        self.strokes = strokes
        self.params = params
        self.feed_mm_s = feed_mm_s
        self.time_scale = time_scale
        self.in_flight: list[int] = []  # pieces sent and not yet proven cut, in order
        self.done = {k: 0.0 for k in strokes}
        self._seen = time.monotonic()  # when the head was last seen on the path
        self._written: dict[int, tuple[float, float]] = {}  # piece -> (mm, when)

    def start_at(self, piece: int, mm: float) -> None:
        self.done[piece] = mm
        self._written[piece] = (mm, time.monotonic())

    def on_piece(self, piece: int, state: str) -> None:
        if state == "cutting" and piece not in self.in_flight:
            self.in_flight.append(piece)
        elif state == "cut" and piece in self.in_flight:
            self.in_flight.remove(piece)

    def on_progress(self, status) -> None:
        now = time.monotonic()
        if not self.in_flight or status is None:
            self._seen = now
            return
        k = self.in_flight[0]
        here = head_position(status, False, self.params)
        most = 1.5 * self.feed_mm_s * self.time_scale * (now - self._seen) + 1.0
        reached = advance(self.strokes[k], self.done[k], here, most)
        back = max(self.done[k] - 0.5, 0.0)
        if reached > self.done[k] or advance(self.strokes[k], back, here, 1.0) > back:
            self._seen = now  # on the path: moving along it, or held where it stopped
        self.done[k] = reached
        mm, when = self._written.get(k, (0.0, 0.0))
        if reached - mm >= JOURNAL_STEP_MM and now - when >= JOURNAL_EVERY_S:
            self.store.set_piece_progress(self.job_id, k, reached, self.strokes[k].total_mm)
            self._written[k] = (reached, now)


def stream_with_control(streamer, program, control: JobControl):
    """Run the streamer in a worker thread while this one relays pause/resume/stop."""
    out: dict[str, Any] = {}
    worker = threading.Thread(target=lambda: out.update(result=streamer.run(program)),
                              name="stream", daemon=True)
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
    return out["result"]
