"""Step 6 for a marker longer than the table: cut it bite by bite (issue 35).

For each bite in order: bring it onto the table (`station.steps.bites.find_bite`: the
roll advanced by the machine profile's conveyor, or by the operator while the job waits
at "advance the fabric N mm" until `station resume`; the window photographed; the real
advance and skew measured from the print), then cut its pieces where the cloth now lies
(`station.steps.cut.cut_job`, restricted to the bite). The journal of the bites
(``bites-state.json`` and the last photograph, ``bite-photo.npy``, in the job's folder)
is written before every advance and after every measurement, so a job paused, stopped
or killed between bites resumes at the right bite, without advancing the roll twice;
each piece is recorded cut in the job store at its sync point as ever, with its bite.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Protocol

import numpy as np

from gcode.layout import Layout as MachineLayout
from solver.nest.bites import Bite, BitePlan
from station.daemon import JobControl, JobInterrupted
from station.jobstore import Job, JobStore
from station.steps.bites import OPERATOR_ADVANCE, BiteStep, RollTrack, bites_report, find_bite

STATE_FILE = "bites-state.json"
PHOTO_FILE = "bite-photo.npy"
#: each bite as handed to the cut: ``{"track": (2, 3) marker -> window mm, "pieces":
#: {piece id: (2, 3) pattern -> window mm}}`` (local maps included)
BITE_PIECES_FILE = "bite-{index}-pieces.json"


class Roll(Protocol):
    """How the station moves and sees the roll between bites: ``feed`` advances it by
    the mm given (None: the operator does, at `OPERATOR_ADVANCE`); ``photograph`` gives
    the table window rectified, pixel (c, r) at window mm (c, r) * ``mm_per_px``."""

    feed: Callable[[float], None] | None
    mm_per_px: float

    def photograph(self) -> np.ndarray: ...


#: cuts ``pieces`` (names) of a bite from the machine marker where the bite now lies
CutBite = Callable[[MachineLayout, set[str]], None]
#: the track with a local map of the print under each piece of the bite, measured on the
#: bite's photograph (`station.steps.bites.localise`)
LocalMaps = Callable[[RollTrack, Bite, np.ndarray], RollTrack]


@dataclass
class BiteJournal:
    """What the job's folder remembers of the bites: the last one brought onto the table
    (its track and photograph), the bites measured so far, and the bite whose advance was
    asked for (of the operator, or sent to the conveyor) but not yet measured."""

    step: BiteStep | None
    measured: list[Bite]
    advancing: int | None = None

    @classmethod
    def load(cls, job_dir: Path, plan: BitePlan) -> BiteJournal:
        path = job_dir / STATE_FILE
        if not path.is_file():
            return cls(None, [])
        data = json.loads(path.read_text())
        measured = [replace(plan.bites[int(b["index"])],
                            advance_commanded_mm=float(b["advance_commanded_mm"]),
                            advance_measured_mm=b["advance_measured_mm"],
                            skew_deg=b["skew_deg"]) for b in data["measured"]]
        step = None
        if measured:
            track = RollTrack(np.asarray(data["track"], float).reshape(2, 3))
            step = BiteStep(track, measured[-1], np.load(job_dir / PHOTO_FILE))
        return cls(step, measured, data.get("advancing"))

    def save(self, job_dir: Path) -> None:
        """Written whole, then renamed: a kill mid-write leaves the previous journal."""
        if self.step is not None:
            tmp = job_dir / (PHOTO_FILE + ".tmp.npy")
            np.save(tmp, self.step.photograph)
            tmp.replace(job_dir / PHOTO_FILE)
        data = {"measured": bites_report(self.measured), "advancing": self.advancing,
                "track": None if self.step is None
                else self.step.track.marker_to_window.tolist()}
        tmp = job_dir / (STATE_FILE + ".tmp")
        tmp.write_text(json.dumps(data, indent=1))
        tmp.replace(job_dir / STATE_FILE)


def cut_in_bites(job: Job, job_dir: Path, plan: BitePlan, store: JobStore,
                 control: JobControl, *, roll: Roll, lattice: np.ndarray | None,
                 machine_marker: Callable[[RollTrack, Bite], MachineLayout],
                 cut_bite: CutBite, local_maps: LocalMaps | None = None) -> list[Bite]:
    """Cut ``plan`` bite by bite (see the module's docstring); the bites as measured.
    ``machine_marker`` makes a bite's machine marker from the track, ``cut_bite`` cuts
    pieces of it; ``local_maps`` (None: none) places each piece on the print under it,
    measured again from the journalled photograph on a resume, so identically."""
    store.set_piece_bites(job.id, plan.bite_of())
    journal = BiteJournal.load(job_dir, plan)
    for bite in plan.bites:
        reached = journal.step.bite.index if journal.step is not None else -1
        if bite.index < reached:
            continue
        if bite.index > reached:
            control.checkpoint()
            journal = _bring(journal, bite, roll, lattice, job_dir)
            _write_bites(job_dir, journal.measured)
        left = {p["name"] for p in store.pieces(job.id) if p["state"] != "cut"}
        todo = left & set(bite.pieces)
        if todo:
            control.start_step(f"cutting bite {bite.index + 1} of {len(plan.bites)}")
            track = journal.step.track
            if local_maps is not None:
                track = local_maps(track, bite, journal.step.photograph)
            marker = machine_marker(track, bite)
            _record_pieces(job_dir, bite, marker, track)
            cut_bite(marker, todo)
    return journal.measured


def _bring(journal: BiteJournal, bite: Bite, roll: Roll, lattice: np.ndarray | None,
           job_dir: Path) -> BiteJournal:
    """``bite`` on the table and measured, journalled. Without a conveyor the job first
    waits for the operator (JobInterrupted, paused); `station resume` comes back here
    with the roll advanced. An advance already sent is never sent again."""
    previous = journal.step
    advanced = journal.advancing == bite.index
    if previous is not None and not advanced:
        journal = replace(journal, advancing=bite.index)
        journal.save(job_dir)  # before the roll moves: a kill now must not move it twice
        if roll.feed is None:
            raise JobInterrupted("paused", OPERATOR_ADVANCE.format(
                mm=previous.track.advance_for(bite)) + " (then: station resume)")
    feed = roll.feed if previous is not None and not advanced else _already_advanced
    step = find_bite(previous, bite, advance=feed, photograph=roll.photograph,
                     lattice=lattice, mm_per_px=roll.mm_per_px)
    if previous is None:
        step = BiteStep(step.track, replace(bite, advance_commanded_mm=0.0), step.photograph)
    journal = BiteJournal(step, [*journal.measured, step.bite], None)
    journal.save(job_dir)
    return journal


def _record_pieces(job_dir: Path, bite: Bite, marker: MachineLayout, track: RollTrack
                   ) -> None:
    """``bite-K-pieces.json``: where each piece of the bite was cut, as its map from the
    pattern to the window (what a report or an inspection holds against the cloth), and
    report.json's ``local_maps``: what each piece's local map did."""
    (job_dir / BITE_PIECES_FILE.format(index=bite.index)).write_text(json.dumps({
        "track": track.marker_to_window.tolist(),
        "pieces": {p.id: np.asarray(p.transform, float).tolist() for p in marker.pieces}}))
    path = job_dir / "report.json"
    report = json.loads(path.read_text()) if path.is_file() else {}
    done = {row["piece"] for row in track.local}
    report["local_maps"] = [r for r in report.get("local_maps", []) if r["piece"] not in done
                            ] + track.local
    path.write_text(json.dumps(report, indent=2, default=float))


def _already_advanced(_mm: float) -> None:
    """The roll was advanced before this process came back (by the operator, or by the
    conveyor before a restart): only measure it."""


def _write_bites(job_dir: Path, measured: list[Bite]) -> None:
    """The job's report.json gains the bites measured so far (`bites_report`)."""
    path = job_dir / "report.json"
    try:
        report = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        report = {}
    report["bites"] = bites_report(measured)
    path.write_text(json.dumps(report, indent=2, default=float))
