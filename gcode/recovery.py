"""Knowing what the machine did while nobody listened: piece markers, final moves, rest.

When the daemon dies the machine goes on with the moves in its buffers (up to 128 bytes
of lines and 15 planned blocks), so the piece in flight may finish after the last answer
anybody read. So the program builder, asked with `gcode.program.PieceMarkers`, brackets
each piece's final move with G59 writes (``G10 L2 P6 X<job> Y<piece + 1> Z<phase>``), which
GRBL keeps in EEPROM across resets and power cuts and writes only after every move before
it has finished (FORCE_BUFFER_SYNC_DURING_EEPROM_WRITE); the checker checks them with
everything else, and the streamer sends each alone, once every line before it is answered,
and nothing after it until it is answered:

* phase 1, before the final move: written only once every move but the final one has run;
  while it stands, nothing but the final move can move the head;
* phase 2, after the final move: written only once the final move has run, and no line of
  the next piece is sent before it is answered;
* cleared (zeros) before every stream, once the store holds what it said: a piece cut
  again must not be judged by the marker of its interrupted earlier attempt.

The geometry those markers refer to is saved before streaming (`save_final_moves`), since
where a contour starts and ends depends on which pieces were left to cut; on the next
start the machine is asked (`wait_at_rest`, `read_params`) before anything moves or resets
it; `read_marker` and `piece_finished` judge its answer (phase 2 proves the piece cut;
phase 1 only with the head resting, position trusted, at the final move's end), and the
station records the verdict in the job store. Only the 1-2 ms between the final move's
answer and the phase-2 block going out, followed by a loss of position before the restart,
leaves a finished piece unproven: it is cut again, and the operator is told in the log.
A piece interrupted before its final move resumes where its cut stopped (`gcode.resume`).
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gcode.blocks import MARKER_SYSTEM
from gcode.grbl import Response, Status
from gcode.program import Program, program_moves
from gcode.session import GrblSession, ResponseReader

__all__ = ["FINAL_MOVES", "MARKER_SYSTEM", "Marker", "distance_to_path", "final_moves",
           "head_position", "load_final_moves", "piece_finished", "read_marker",
           "read_params", "save_final_moves", "wait_at_rest"]

FINAL_MOVES = "final-moves.json"


def final_moves(program: Program, index: dict[str, int]) -> dict[int, np.ndarray]:
    """Store piece index -> (k, 2) points of that piece's final cutting move in ``program``."""
    number_to_piece = {r.number: index[r.id] for r in program.pieces}
    out: dict[int, np.ndarray] = {}
    for _, on, number, pts in program_moves(program):
        if on and number in number_to_piece:
            out[number_to_piece[number]] = pts  # the last cutting move of the piece wins
    return out


def save_final_moves(path: Path, job_id: int, moves: dict[int, np.ndarray]) -> None:
    """Write the final moves durably (temporary file, fsync, rename) before streaming."""
    tmp = path.with_suffix(".tmp")
    with open(tmp, "w") as f:
        json.dump({"job": job_id, "moves": {str(k): np.round(v, 4).tolist()
                                            for k, v in moves.items()}}, f)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def load_final_moves(path: Path, job_id: int) -> dict[int, np.ndarray]:
    """What `save_final_moves` wrote for this job ({} if nothing)."""
    try:
        doc = json.loads(path.read_text())
    except (FileNotFoundError, json.JSONDecodeError):
        return {}
    if doc.get("job") != job_id:
        return {}
    return {int(k): np.asarray(v, float) for k, v in doc.get("moves", {}).items()}


def distance_to_path(p: np.ndarray, path: np.ndarray) -> float:
    """Distance from point ``p`` to the polyline ``path``."""
    if len(path) == 0:
        return float("inf")
    if len(path) == 1:
        return float(np.hypot(*(p - path[0])))
    a, b = path[:-1], path[1:]
    d = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, d) / np.maximum(np.einsum("ij,ij->i", d, d),
                                                             1e-12), 0.0, 1.0)
    return float(np.hypot(*(a + t[:, None] * d - p).T).min())


@dataclass(frozen=True)
class Marker:
    """What the marker system (G59) says: the job, the piece (store index) whose final move
    was reached, and the phase (1: every move but the final one finished, 2: all did)."""

    job: int
    piece: int
    phase: int


def read_marker(params: dict[str, tuple[float, ...]]) -> Marker | None:
    """The marker in ``$#``'s answer (None when cleared or absent)."""
    m = params.get(f"G{53 + MARKER_SYSTEM}")
    if m is None or len(m) < 3 or round(m[0]) == 0:
        return None
    return Marker(int(round(m[0])), int(round(m[1])) - 1, int(round(m[2])))


def head_position(rest: Status | None, alarm: bool,
                  params: dict[str, tuple[float, ...]]) -> np.ndarray | None:
    """Where the head rests in the program's (G54) coordinates; None when the position is
    not to be trusted (an alarm: reset, power cut) or was not reported."""
    if rest is None or alarm or rest.mpos is None:
        return None
    g54 = params.get("G54", (0.0, 0.0, 0.0))
    return np.asarray(rest.mpos[:2], float) - np.asarray(g54[:2], float)


def piece_finished(phase: int, path: np.ndarray | None, here: np.ndarray | None
                   ) -> tuple[bool, str]:
    """(cut?, why) of the piece a marker names, from its final move ``path`` and the
    trusted rest position ``here``.

    Phase 2 is written only after the final move (GRBL syncs before an EEPROM write). The
    one contradiction a trusted position can show is a head stopped on the final move
    short of its end: then believe the head (an emulator that stores the offset when it
    parses the line, not when it runs it, gets this right too). Phase 1 proves the final
    move ran only with the head at rest at its end, not its start.
    """
    if path is None or len(path) < 2:
        path = np.zeros((0, 2))
        start = end = np.full(2, np.inf)  # unknown geometry: nothing is proven by it
    else:
        start, end = path[0], path[-1]
    at_end = here is not None and float(np.hypot(*(here - end))) < 0.02
    on_move = here is not None and distance_to_path(here, path) < 0.05
    if phase == 2:
        done = not (on_move and not at_end)
        return done, ("its sync point executed (marker written after its final move)" if done
                      else "the marker says finished but the head stopped on its final move")
    done = at_end and float(np.hypot(*(start - end))) > 0.05
    return done, ("the head rests at the end of its final move" if done else
                  "its final move may not have run (head elsewhere or position lost): "
                  "cut again in full")


def wait_at_rest(port, timeout: float = 120.0, stop=None) -> Status | None:
    """The controller's status once its buffered moves are over, before anyone resets it.

    Only the real-time ``?`` is sent, which changes nothing; a machine still running the
    moves a dead daemon left in its buffers is waited for. What the line still holds from
    before (answers and reports nobody read, e.g. a report of the head resting between
    two moves) is drained first, and the rest is believed only when two fresh reports
    agree. None if the controller does not answer (or ``stop()`` turns true).
    """
    try:
        port.reset_input_buffer()
    except (AttributeError, OSError):
        pass
    quiet_until = time.monotonic() + 0.3
    drain_end = time.monotonic() + 5.0
    while time.monotonic() < min(quiet_until, drain_end):
        if port.read(port.in_waiting or 1):
            quiet_until = time.monotonic() + 0.3
    seen = None
    previous = None
    end = time.monotonic() + timeout
    silent_until = time.monotonic() + 1.5
    last: Status | None = None

    def on_status(r: Response) -> None:
        nonlocal last
        last = r.status

    reader = ResponseReader(port)  # only reports matter here; everything else is dropped
    reader.register_response("status", on_status)
    while time.monotonic() < end:
        if stop is not None and stop():
            return None
        port.write(b"?")
        last = None
        reader.wait(lambda: False, 0.15)  # the newest report of the next 0.15 s
        if last is None:
            if seen is None and time.monotonic() > silent_until:
                return None
            continue
        seen = last
        resting = last.state in ("Idle", "Alarm", "Check", "Sleep") or (
            last.state == "Hold" and last.substate == 0)
        key = (last.state, last.position())
        if resting and previous == key:
            return last
        previous = key if resting else None
    return seen


def read_params(streamer: GrblSession) -> dict[str, tuple[float, ...]]:
    """``$#``: the controller's stored offsets by name (G54..G59, G28, G30, G92...)."""
    r, pushed = streamer.command("$#")
    out: dict[str, tuple[float, ...]] = {}
    if r.kind != "ok":
        return out
    for p in pushed:
        if p.kind == "param" and p.text:
            key, _, body = p.text.partition(":")
            try:
                out[key] = tuple(float(v) for v in body.split(":")[0].split(","))
            except ValueError:
                continue
    return out
