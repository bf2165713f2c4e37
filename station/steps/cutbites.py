"""Step 6 for a marker longer than the table: cut it bite by bite (issue 35).

For each bite in order: bring it onto the table (`station.steps.bites.find_bite`: the
roll advanced by the machine profile's conveyor, or by the operator while the job waits
at "advance the fabric N mm" until `station resume`; the window photographed; the real
advance and skew measured from the print, or from the last bite's kerfs where the
print says nothing along the roll), then cut its pieces where the cloth now lies
(`station.steps.cut.cut_job`, restricted to the bite), and photograph the window again
with the bite's kerfs in it. The journal of the bites (``bites-state.json``, the last
photograph ``bite-photo.npy`` and the one after its cut ``bite-cut-photo.npy``, in the
job's folder) is written before every advance, after every measurement and after every
photograph of a cut, so a job paused, stopped
or killed between bites resumes at the right bite, without advancing the roll twice;
each piece is recorded cut in the job store at its sync point as ever, with its bite.

An advance asked for before this process (of the operator, or sent to the conveyor by a
daemon that died) may never have run: a power cut or a reset between the command and
the move, an operator who resumed without advancing. Measured near the commanded
advance, a periodic print would still match a whole number of repeats away, so before
believing it the photograph is also measured against no advance at all
(`roll_moved`): the roll found where it was is advanced again (or the operator asked
again), and a print that cannot tell leaves the job paused, saying so. The job's log
records every advance asked for and measured; the status names the bite being cut.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Protocol

import numpy as np

from gcode.layout import Layout as MachineLayout
from solver.nest.bites import Bite, BitePlan
from station.daemon import JobControl, JobInterrupted
from station.jobstore import Job, JobStore
from station.steps.bites import (
    OPERATOR_ADVANCE,
    ROLL_MARGIN_MM,
    BiteStep,
    RollTrack,
    bites_report,
    find_bite,
)
from vision.advance import Advance, measure_advance

STATE_FILE = "bites-state.json"
PHOTO_FILE = "bite-photo.npy"
#: the window photographed again once the bite was cut: its kerfs measure the next
#: advance where the print cannot (`station.steps.bites.measure_bite_advance`)
CUT_PHOTO_FILE = "bite-cut-photo.npy"
#: each bite as handed to the cut: ``{"track": (2, 3) marker -> window mm, "pieces":
#: {piece id: (2, 3) pattern -> window mm}}`` (local maps included)
BITE_PIECES_FILE = "bite-{index}-pieces.json"


#: the photographs show the same cloth under one explanation (advanced, or not moved)
#: when its residual is under this share of the other's: the same cloth leaves only the
#: camera's noise, cloth a whole advance away on a periodic print leaves the print's own
#: irregularity on top. Measured on the simulated roll (plaid 80 mm, p2 50 mm), the
#: other explanation left 1.5 to 4 times the same cloth's; a roll moved part of the
#: way, 0.9 to 1.8 times (the advance then also measures more than ``ROLL_MARGIN_MM``
#: off the commanded one, or the two explanations differ by less than this share).
SAME_CLOTH_SHARE = 0.8
#: a motion this small (mm, degrees) between two photographs is the roll at rest (the
#: measurement's own error is 0.02 mm and 0.002 degrees)
AT_REST_MM, AT_REST_DEG = 0.1, 0.01


class Roll(Protocol):
    """How the station moves and sees the roll between bites: ``feed`` advances it by
    the mm given (None: the operator does, at `OPERATOR_ADVANCE`); ``photograph`` gives
    the table window rectified, pixel (c, r) at window mm (c, r) * ``mm_per_px``;
    ``settle`` waits until a move an earlier process sent to the conveyor is over."""

    feed: Callable[[float], None] | None
    mm_per_px: float

    def photograph(self) -> np.ndarray: ...

    def settle(self) -> None: ...


#: cuts ``pieces`` (names) of a bite from the machine marker where the bite now lies,
#: under the control it is given (the bite's, `BiteControl`)
CutBite = Callable[[MachineLayout, set[str], JobControl], None]
#: the track with a local map of the print under each piece of the bite, measured on the
#: bite's photograph (`station.steps.bites.localise`)
LocalMaps = Callable[[RollTrack, Bite, np.ndarray], RollTrack]


@dataclass
class BiteJournal:
    """What the job's folder remembers of the bites: the last one brought onto the table
    (its track, photograph and, once cut, its photograph after the cut), the bites
    measured so far and how (`BiteStep.how`, by index), and the bite whose advance was
    asked for (of the operator, or sent to the conveyor) but not yet measured."""

    step: BiteStep | None
    measured: list[Bite]
    advancing: int | None = None
    how: dict[int, dict] = field(default_factory=dict)

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
        how = {int(b["index"]): {"advance_source": b.get("advance_source"),
                                 "advance_unmeasured": b.get("advance_unmeasured", [])}
               for b in data["measured"]}
        step = None
        if measured:
            track = RollTrack(np.asarray(data["track"], float).reshape(2, 3))
            cut = job_dir / CUT_PHOTO_FILE
            step = BiteStep(track, measured[-1], np.load(job_dir / PHOTO_FILE),
                            np.load(cut) if data.get("cut_photo_bite") == measured[-1].index
                            and cut.is_file() else None)
        return cls(step, measured, data.get("advancing"), how)

    def save(self, job_dir: Path) -> None:
        """Written whole, then renamed: a kill mid-write leaves the previous journal."""
        cut_bite = None
        if self.step is not None:
            _save_array(job_dir / PHOTO_FILE, self.step.photograph)
            if self.step.cut_photograph is not None:
                _save_array(job_dir / CUT_PHOTO_FILE, self.step.cut_photograph)
                cut_bite = self.step.bite.index
        data = {"measured": bites_report(self.measured, self.how),
                "advancing": self.advancing, "cut_photo_bite": cut_bite,
                "track": None if self.step is None
                else self.step.track.marker_to_window.tolist()}
        tmp = job_dir / (STATE_FILE + ".tmp")
        tmp.write_text(json.dumps(data, indent=1))
        tmp.replace(job_dir / STATE_FILE)


def _save_array(path: Path, array: np.ndarray) -> None:
    """``array`` to ``path``, written whole, then renamed."""
    tmp = path.with_suffix(".tmp.npy")
    np.save(tmp, array)
    tmp.replace(path)


@dataclass
class BiteControl(JobControl):
    """The job's control while it cuts a bite: the same flags and progress, and every
    step the cut announces ("connecting", "cutting", ...) names the bite, so that the
    status and `station watch` say "cutting, bite 2 of 3"."""

    bite: str = field(default="", kw_only=True)

    @classmethod
    def of(cls, control: JobControl, bite: str) -> BiteControl:
        return cls(control.job_id, control.pause, control.abort, control.stop,
                   control.progress, bite=bite)

    def start_step(self, step: str, fraction: float | None = None) -> None:
        super().start_step(step, fraction)
        self.progress["bite"] = self.bite


def cut_in_bites(job: Job, job_dir: Path, plan: BitePlan, store: JobStore,
                 control: JobControl, *, roll: Roll, lattice: np.ndarray | None,
                 machine_marker: Callable[[RollTrack, Bite], MachineLayout],
                 cut_bite: CutBite, local_maps: LocalMaps | None = None) -> list[Bite]:
    """Cut ``plan`` bite by bite (see the module's docstring); the bites as measured.
    ``machine_marker`` makes a bite's machine marker from the track, ``cut_bite`` cuts
    pieces of it under the control it is given (the bite's); ``local_maps`` (None: none)
    places each piece on the print under it, measured again from the journalled
    photograph on a resume, so identically."""
    store.set_piece_bites(job.id, plan.bite_of())
    journal = BiteJournal.load(job_dir, plan)
    for bite in plan.bites:
        reached = journal.step.bite.index if journal.step is not None else -1
        if bite.index < reached:
            continue
        named = BiteControl.of(control, f"{bite.index + 1} of {len(plan.bites)}")
        if bite.index > reached:
            control.checkpoint()
            named.start_step("finding the print")
            journal = _bring(journal, bite, plan, roll, lattice, job_dir,
                             lambda text, b=named.bite:
                             store.log(job.id, "bite", f"bite {b}: {text}"))
            _write_bites(job_dir, journal)
        left = {p["name"] for p in store.pieces(job.id) if p["state"] != "cut"}
        todo = left & set(bite.pieces)
        if todo:
            track = journal.step.track
            if local_maps is not None:
                track = local_maps(track, bite, journal.step.photograph)
            marker = machine_marker(track, bite)
            _record_pieces(job_dir, bite, marker, track)
            cut_bite(marker, todo, named)
        if bite.index + 1 < len(plan.bites) and journal.step.cut_photograph is None:
            # the bite's kerfs, for the next advance where the print cannot measure it
            journal = replace(journal, step=replace(journal.step,
                                                    cut_photograph=roll.photograph()))
            journal.save(job_dir)
    return journal.measured


def _bring(journal: BiteJournal, bite: Bite, plan: BitePlan, roll: Roll,
           lattice: np.ndarray | None, job_dir: Path, log: Callable[[str], None]
           ) -> BiteJournal:
    """``bite`` on the table and measured, journalled. Without a conveyor the job first
    waits for the operator (JobInterrupted, paused); `station resume` comes back here
    with the roll advanced. An advance already asked for is asked for again only when
    the print shows the roll where it was (`_advanced_photograph`)."""
    previous = journal.step
    if previous is None:  # the first bite: the marker lies where it was planned
        step = find_bite(None, bite, advance=_already_advanced, photograph=roll.photograph,
                         lattice=lattice, mm_per_px=roll.mm_per_px)
        step = BiteStep(step.track, replace(bite, advance_commanded_mm=0.0), step.photograph)
    else:
        commanded = previous.track.advance_for(bite, plan)
        photo = _advanced_photograph(journal, previous, bite, plan, roll, lattice, log)
        if photo is None:  # not asked for yet, or asked for and never run
            again = journal.advancing == bite.index
            journal = replace(journal, advancing=bite.index)
            journal.save(job_dir)  # before the roll moves: a kill now must not move it twice
            if roll.feed is None:
                raise JobInterrupted("paused", OPERATOR_ADVANCE.format(mm=commanded)
                                     + " (then: station resume)"
                                     + ("; the print showed it had not moved" if again else ""))
            log(f"advancing the roll {commanded:.3f} mm")
            roll.feed(commanded)
            photo = roll.photograph()
        step = find_bite(previous, bite, advance=_already_advanced, photograph=lambda: photo,
                         lattice=lattice, mm_per_px=roll.mm_per_px, plan=plan)
    journal = BiteJournal(step, [*journal.measured, step.bite], None,
                          {**journal.how, bite.index: step.how()})
    journal.save(job_dir)
    if previous is not None:  # logged once journalled: a restart now does not measure again
        log(_advance_line(step))
    return journal


def _advance_line(step: BiteStep) -> str:
    """The job log's line of one advance: commanded, measured (and from what) or not."""
    b = step.bite
    measured = ("not measured: the print says nothing along the roll and no cut lay in "
                "the strip" if b.advance_measured_mm is None
                else f"{b.advance_measured_mm:.3f} mm measured from the {step.source}")
    skew = "not measured" if b.skew_deg is None else f"{b.skew_deg:.4f} deg"
    return f"advance {b.advance_commanded_mm:.3f} mm commanded, {measured}, skew {skew}"


def _advanced_photograph(journal: BiteJournal, previous: BiteStep, bite: Bite,
                         plan: BitePlan, roll: Roll, lattice: np.ndarray | None,
                         log: Callable[[str], None]) -> np.ndarray | None:
    """The window's photograph when the advance to ``bite`` was asked for before this
    turn and the roll really made it; None when it was not asked for yet, or when the
    print shows the roll where it was (the advance never ran). A print that cannot tell
    leaves the job paused (JobInterrupted), its reason saying what to look at."""
    if journal.advancing != bite.index:
        return None
    roll.settle()  # a conveyor the last daemon started may still be moving
    photo = roll.photograph()
    commanded = previous.track.advance_for(bite, plan)
    moved = roll_moved(previous.photograph, photo, commanded_mm=commanded, lattice=lattice,
                       mm_per_px=roll.mm_per_px, cut=previous.cut_photograph)
    if moved is None:
        raise JobInterrupted("paused", f"bite {bite.index + 1}: the print cannot tell "
                             f"whether the roll advanced "
                             f"{commanded:.1f} mm or not at all since the last bite: look "
                             "whether the last bite's cuts still lie in the window, then "
                             "station resume")
    if not moved:
        log(f"the roll had not moved since the advance of {commanded:.3f} mm was asked "
            "for (never run): asking again")
        return None
    return photo


def roll_moved(before: np.ndarray, after: np.ndarray, *, commanded_mm: float,
               lattice: np.ndarray | None, mm_per_px: float,
               cut: np.ndarray | None = None) -> bool | None:
    """Whether the roll advanced by about ``commanded_mm`` between the two photographs
    (True), did not move (False), or the print cannot tell (None: it moved part of the
    way, or the print repeats too perfectly). Both explanations are measured; the one
    that shows the same cloth leaves the smaller residual (`SAME_CLOTH_SHARE`); "not
    moved" also needs the motion found near zero to be nil (`AT_REST_MM`), "advanced"
    a slip within the room kept for one (`ROLL_MARGIN_MM`): a print matched whole
    repeats from where the roll really lies measures a slip of up to half a repeat.
    The motion found near zero is no rival when it lies beyond that room from rest: the
    print matched whole repeats away, so the roll moved. (A stop within the room of a
    whole number of repeats short of the advance then looks advanced: a print that
    repeats that perfectly cannot tell it.) Where the print says nothing along the roll,
    each explanation is measured on ``cut`` instead (the window photographed after the
    last bite's cut, None: none), from the kerfs."""
    still = _explained(before, after, 0.0, lattice, mm_per_px, cut)
    moved = _explained(before, after, commanded_mm, lattice, mm_per_px, cut)
    at_rest = still is not None and max(abs(still.advance_mm), abs(still.across_mm)) \
        < AT_REST_MM and abs(still.skew_deg) < AT_REST_DEG
    if at_rest and (moved is None or still.residual < SAME_CLOTH_SHARE * moved.residual):
        return False
    rival = still is not None and abs(still.advance_mm) <= ROLL_MARGIN_MM
    if not at_rest and moved is not None and abs(moved.slip_mm) <= ROLL_MARGIN_MM and (
            not rival or moved.residual < SAME_CLOTH_SHARE * still.residual):
        return True
    return None


def _explained(before: np.ndarray, after: np.ndarray, commanded_mm: float,
               lattice: np.ndarray | None, mm_per_px: float, cut: np.ndarray | None = None
               ) -> Advance | None:
    """The motion measured near ``commanded_mm``, from the print, else from the kerfs of
    ``cut`` (the photograph after the last cut); None where the photographs do not match
    near it at all, or neither measures the advance along the roll."""
    for first in (before, cut):
        if first is None:
            continue
        try:
            found = measure_advance(first, after, commanded_mm=commanded_mm,
                                    mm_per_px=mm_per_px, lattice=lattice)
        except ValueError:
            return None
        if found.along_measured:
            return found
    return None


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


def _write_bites(job_dir: Path, journal: BiteJournal) -> None:
    """The job's report.json gains the bites measured so far, and how (`bites_report`)."""
    path = job_dir / "report.json"
    try:
        report = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        report = {}
    report["bites"] = bites_report(journal.measured, journal.how)
    path.write_text(json.dumps(report, indent=2, default=float))
