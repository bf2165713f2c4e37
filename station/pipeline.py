"""The station's work on one job, as the daemon runs it: the steps of `station.steps`
with the configured machine and the devices the daemon's caller chose.

`StationPipeline` implements `station.daemon.Pipeline`. Inside one process each step
hands the next its objects (`Captured`, `Plan`); a job captured or planned by another
process (the daemon restarted, the operator confirmed a print) goes on from the files
the store names, read here at the edge. Plans made in this process are held by job id,
so that a job paused and resumed here cuts from its objects too.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from gcode.layout import Layout as MachineLayout
from gcode.layout import load_layout
from gcode.program import Program
from station.config import Config
from station.daemon import JobControl
from station.jobstore import Job, JobStore
from station.steps.capture import CameraOpener, Captured, capture_fabric, photograph, real_camera
from station.steps.cut import PortOpener, cut_job, serial_port
from station.steps.pictures import draw_plan
from station.steps.plan import plan_job
from station.steps.program import fabric_origin, program_of, station_machine
from station.steps.records import Plan
from station.steps.submission import check_job

HELD_PLANS = 16  # plans a daemon keeps in memory for jobs paused and resumed in it


class StationPipeline:
    """Capture, plan and cut with the configured machine, on the camera and port that
    ``open_camera`` and ``open_port`` open (default: the configured real ones; the
    simulated ones come from `station.simstation`)."""

    def __init__(self, config: Config, *, open_camera: CameraOpener = real_camera,
                 open_port: PortOpener = serial_port) -> None:
        self.config = config
        self.open_camera = open_camera
        self.open_port = open_port
        self.machine = station_machine(config)
        # Plans made here by job id, used only while the store's record is still this
        # one's (another station may have planned the job again since).
        self._planned: dict[int, Plan] = {}

    def check(self, garment: str, fabric: str | None, options: dict[str, Any]) -> None:
        """Refuse at submission what could never run (raises ValueError)."""
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
        plan = plan_job(job, captured, workdir, self.config, self.machine, control)
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
        if held is not None and held.record() == job.plan:
            marker = held.marker
        else:
            marker = self.marker_file(job.plan["layout"])
        cut_job(job, Path(job.plan["layout"]).parent, marker, store, control,
                config=self.config, machine=self.machine, open_port=self.open_port,
                resuming=resuming)
        self._planned.pop(job.id, None)  # every piece cut: nothing left to resume

    def marker_file(self, path: str | Path) -> MachineLayout:
        """A job's LAYOUT.json, read as untrusted input, on this station's table."""
        marker = load_layout(path)
        marker.origin = fabric_origin(self.config)
        return marker

    def program_for(self, layout: str | Path, only: set[str] | None) -> Program:
        """The checked program for the pieces ``only`` (None: all) of a LAYOUT.json."""
        program, _ = program_of(self.marker_file(layout), self.machine, only,
                                title=f"station {Path(layout).parent.name}")
        return program
