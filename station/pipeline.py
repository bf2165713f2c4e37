"""The station's work on one job, as the daemon runs it: the steps of `station.steps`
with the configured machine and the devices the daemon's caller chose.

`StationPipeline` implements `station.daemon.Pipeline`. Inside one process each step
hands the next its objects (`Captured`, `Plan`); a job captured or planned by another
process (the daemon restarted, the operator confirmed a print) goes on from the files
the store names, read here at the edge. Plans made in this process are held by job id,
so that a job paused and resumed here cuts from its objects too.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from gcode.layout import Layout as MachineLayout
from gcode.layout import load_layout, on_table
from gcode.machine import Machine
from gcode.program import Program
from solver.nest.bites import BitePlan
from solver.nest.layout import Layout
from solver.wallpaper import gauss_reduce
from station.config import Config
from station.daemon import JobControl
from station.jobstore import Job, JobStore
from station.order import is_order_file
from station.steps.bites import RollTrack, load_bites, localise
from station.steps.capture import CameraOpener, Captured, capture_fabric, photograph, real_camera
from station.steps.cut import PortOpener, cut_job, serial_port
from station.steps.cutbites import Roll, cut_in_bites
from station.steps.pictures import draw_plan
from station.steps.plan import plan_job
from station.steps.plan_order import plan_order
from station.steps.program import fabric_origin, machine_layout, program_of, station_machine
from station.steps.records import Plan
from station.steps.roll import station_roll
from station.steps.submission import check_job
from station.steps.table import table_window
from vision.localmap import PrintReference

#: makes the station's roll (`station.steps.cutbites.Roll`) from its configuration
RollOpener = Callable[[Config, Machine, CameraOpener, PortOpener], Roll]

HELD_PLANS = 16  # plans a daemon keeps in memory for jobs paused and resumed in it


class StationPipeline:
    """Capture, plan and cut with the configured machine, on the camera and port that
    ``open_camera`` and ``open_port`` open (default: the configured real ones; the
    simulated ones come from `station.simstation`)."""

    def __init__(self, config: Config, *, open_camera: CameraOpener = real_camera,
                 open_port: PortOpener = serial_port, open_roll: RollOpener = station_roll
                 ) -> None:
        self.config = config
        self.open_camera = open_camera
        self.open_port = open_port
        self.open_roll = open_roll
        self._roll: Roll | None = None  # the roll on the table, made at the first bite
        self.machine = station_machine(config)
        self.window = table_window(config, self.machine)  # refused here, not after planning
        # a marker longer than the table is cut in bites only where each advance can be
        # found again on a photograph: not by a station with no camera configured
        self.can_bite = (open_camera is not real_camera
                         or config["camera"]["source"] != "simulated")
        # Plans made here by job id, used only while the store's record is still this
        # one's (another station may have planned the job again since).
        self._planned: dict[int, Plan] = {}

    @property
    def roll(self) -> Roll | None:
        """The roll on the table, once a marker has been cut in bites here."""
        return self._roll

    def check(self, garment: str, fabric: str | None, options: dict[str, Any]) -> None:
        """Refuse at submission what could never run (raises ValueError)."""
        table_window(self.config, self.machine)
        check_job(garment, fabric, options, self.config)

    def _photograph(self):
        return photograph(self.config, self.open_camera)

    def capture(self, job: Job, workdir: Path, control: JobControl) -> Captured:
        return capture_fabric(job, workdir, self.config, self._photograph, control)

    def plan(self, job: Job, captured: Captured | None, workdir: Path, control: JobControl
             ) -> Plan:
        """Plan the job (`station.steps.plan`), then draw its pictures from the plan.
        ``captured`` None: the job's FABRIC.json, captured or confirmed elsewhere."""
        if captured is None:
            captured = Captured.read(job.plan["fabric"], workdir)
        plan_of = plan_order if is_order_file(job.garment) else plan_job  # an order: per garment
        plan = plan_of(job, captured, workdir, self.config, self.machine, control,
                       can_bite=self.can_bite)
        draw_plan(plan, self.machine)
        self._planned.pop(job.id, None)
        self._planned[job.id] = plan
        while len(self._planned) > HELD_PLANS:  # the oldest go: they resume from files
            self._planned.pop(next(iter(self._planned)))
        return plan

    def cut(self, job: Job, plan: Plan | None, store: JobStore, control: JobControl,
            resuming: bool) -> None:
        """Cut the pieces left (`station.steps.cut`): from the plan made in this process,
        else from the job's LAYOUT.json."""
        held = plan if isinstance(plan, Plan) else self._planned.get(job.id)
        if held is None or held.record() != job.plan:
            held = None
        bites = held.bites if held is not None else self._bites_file(job.plan)
        if bites is not None:
            self._cut_in_bites(job, held, bites, store, control, resuming)
        else:
            marker = held.marker if held is not None else self.marker_file(job.plan["layout"])
            cut_job(job, Path(job.plan["layout"]).parent, marker, store, control,
                    config=self.config, machine=self.machine, open_port=self.open_port,
                    resuming=resuming)
        self._planned.pop(job.id, None)  # every piece cut: nothing left to resume

    def _cut_in_bites(self, job: Job, held: Plan | None, bites: BitePlan, store: JobStore,
                      control: JobControl, resuming: bool) -> None:
        """`station.steps.cutbites.cut_in_bites` on this station's roll and machine."""
        job_dir = Path(job.plan["layout"]).parent
        captured = held.captured if held is not None else Captured.read(job.plan["fabric"],
                                                                         job_dir)
        fabric = captured.fabric
        if self._roll is None:
            self._roll = self.open_roll(self.config, self.machine, self.open_camera,
                                        self.open_port)

        def machine_marker(track: RollTrack, bite) -> MachineLayout:
            return machine_layout(track.bite_layout(bites, bite), fabric_origin(self.config),
                                  job.plan["layout"])

        def cut_bite(marker: MachineLayout, pieces: set[str], bite: JobControl) -> None:
            cut_job(job, job_dir, marker, store, bite, config=self.config,
                    machine=self.machine, open_port=self.open_port, resuming=resuming,
                    pieces=pieces)

        reference = print_reference(captured)
        roll = self._roll

        def local_maps(track: RollTrack, bite, photo: np.ndarray) -> RollTrack:
            return localise(track, bite, photo, plan=bites, reference=reference,
                            mm_per_px=roll.mm_per_px,
                            follow=self.config["roll"]["follow_print"])

        cut_in_bites(job, job_dir, bites, store, control, roll=self._roll,
                     lattice=print_lattice(fabric), machine_marker=machine_marker,
                     cut_bite=cut_bite, local_maps=None if reference is None else local_maps)

    @staticmethod
    def _bites_file(record: dict[str, Any]) -> BitePlan | None:
        """A job's bites.json on its layout.json (None: the marker is cut whole)."""
        if not record.get("bites"):
            return None
        return load_bites(Layout.load(record["layout"]), Path(record["bites"]))

    def marker_file(self, path: str | Path) -> MachineLayout:
        """A job's LAYOUT.json, read as untrusted input, on this station's table."""
        return on_table(load_layout(path), fabric_origin(self.config))

    def program_for(self, layout: str | Path, only: set[str] | None) -> Program:
        """The checked program for the pieces ``only`` (None: all) of a LAYOUT.json."""
        program, _ = program_of(self.marker_file(layout), self.machine, only,
                                title=f"station {Path(layout).parent.name}")
        return program


def print_reference(captured: Captured) -> PrintReference | None:
    """The print as planned, that each bite's pieces are placed on (`localise`): the
    capture's photograph folded into one cell of its lattice; None without a photograph
    or on cloth that does not repeat both ways."""
    basis = print_lattice(captured.fabric)
    if captured.photo is None or basis is None or "origin" not in captured.fabric:
        return None
    return PrintReference.from_photo(captured.photo, basis, captured.fabric["origin"],
                                     mm_per_px=captured.mm_per_px)


def print_lattice(fabric: dict[str, Any]) -> np.ndarray | None:
    """(2, 2) columns, the reduced repeat of a job's print (FABRIC.json), that an advance
    is measured modulo; None on plain cloth and stripes (nothing periodic both ways)."""
    if fabric.get("kind") in ("plain", "stripes") or "w1" not in fabric:
        return None
    u1, u2, _ = gauss_reduce(np.asarray(fabric["w1"], float), np.asarray(fabric["w2"], float))
    return np.column_stack([u1, u2])
