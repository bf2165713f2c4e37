"""The work of one job: capture the fabric, plan the cut, stream it, record every piece.

Each step writes its results into the job's folder (frame, FABRIC.json, placement,
layout, G-code, pictures) and returns their paths, which the daemon stores as the job's
plan: a job interrupted after planning resumes from the files, not by recomputing.
Pieces are known to the job store by their layout id, so a resumed job rebuilds its
program for the pieces not yet cut and can never cut one twice.
"""

from __future__ import annotations

import json
import logging
import shutil
from pathlib import Path
from typing import Any

from station.config import Config
from station.daemon import JobControl, JobInterrupted
from station.jobstore import Job, JobStore

log = logging.getLogger("station.pipeline")


class StationPipeline:
    """Capture, plan and cut with the configured camera, machine and defaults."""

    def __init__(self, config: Config, *, simulate: bool = False) -> None:
        self.config = config
        self.simulate = simulate
        from gcode.machine import default_machine, load_machine

        profile = config["machine"]["profile"]
        self.machine = (load_machine(config.resolve(profile)) if profile
                        else default_machine())

    # ------------------------------------------------------------------ checks
    def check(self, garment: str, fabric: str | None, options: dict[str, Any]) -> None:
        """Refuse at submission what could never run (raises ValueError)."""
        from solver.garment import load_garment
        from solver.wallpaper import Wallpaper

        load_garment(garment, units=options.get("units"))
        if fabric is not None:
            Wallpaper.load(fabric)
        unknown = set(options) - {"units", "reshape", "method", "restarts", "seed"}
        if unknown:
            raise ValueError(f"unknown job option {sorted(unknown)[0]!r}")

    # ------------------------------------------------------------------ capture
    def capture(self, job: Job, workdir: Path, control: JobControl) -> str:
        """FABRIC.json of the job: the operator's file, or detected from a photograph."""
        target = workdir / "fabric.json"
        if job.fabric is not None:
            shutil.copyfile(job.fabric, target)
            return str(target)
        frame, mm_per_px, origin = self._photograph(workdir)
        control.checkpoint()
        from vision.detect import detect_fabric

        result = detect_fabric(frame, mm_per_px=mm_per_px, origin=origin)
        if result.get("group") is None:
            raise ValueError("no periodic print found on the table: give the job a FABRIC.json")
        target.write_text(json.dumps(result, indent=2))
        return str(target)

    def _photograph(self, workdir: Path):
        import cv2
        from vision.camera import open_camera

        with open_camera(self.config, simulate=self.simulate) as camera:
            frame = camera.read()
            rectified, mm_per_px, origin = camera.rectified(frame)
        cv2.imwrite(str(workdir / "frame.png"), frame)
        cv2.imwrite(str(workdir / "rectified.png"), rectified)
        return rectified, mm_per_px, origin

    # ------------------------------------------------------------------ plan
    def plan(self, job: Job, fabric: str, workdir: Path, control: JobControl) -> dict[str, Any]:
        """Align, optionally reshape, nest and program; every result is a file in workdir."""
        from solver.fit import fit_report
        from solver.garment import load_garment, save_obj
        from solver.placement import Placement
        from solver.wallpaper import Wallpaper
        from station.render import draw_fit

        garment = load_garment(job.garment, units=job.options.get("units"))
        wallpaper = Wallpaper.load(fabric)
        # The job's own copy of the pattern, in mm: later steps need no units.
        garment_path = workdir / "garment.obj"
        save_obj(garment, garment_path)
        garment = load_garment(garment_path)
        report: dict[str, Any] = {}
        before = Placement.identity(garment.n_pieces, wallpaper)
        report["e_fit_identity_mm2"] = fit_report(garment, before).e_fit_mm2
        control.progress.update(step="aligning")
        placement = align_garment(garment, wallpaper, self.config, job.options)
        placement.garment = str(garment_path)
        report["align"] = placement.report
        aligned = fit_report(garment, placement)
        draw_fit(garment, placement, aligned, workdir / "fit-aligned.png",
                 title=f"aligned on {wallpaper.group}")
        control.checkpoint()
        if job.options.get("reshape", self.config["reshape"]["enabled"]):
            control.progress.update(step="reshaping")
            from solver.reshape import reshape

            garment, reshaped = reshape(garment, placement)
            garment_path = workdir / "garment-reshaped.obj"
            save_obj(garment, garment_path)
            placement.garment = str(garment_path)
            report["reshape"] = reshaped.to_dict()
            draw_fit(garment, placement, fit_report(garment, placement),
                     workdir / "fit-reshaped.png", title=f"reshaped on {wallpaper.group}")
            control.checkpoint()
        placement.save(workdir / "placement.json")
        control.progress.update(step="nesting")
        layout = nest_placement(workdir / "placement.json", self.config)
        layout.save(workdir / "layout.json")
        report["nest"] = {"length_mm": layout.length, "width_mm": layout.width,
                          "density": layout.density, "pieces": len(layout.pieces)}
        control.checkpoint()
        control.progress.update(step="programming")
        program = self.program_for(workdir / "layout.json", None)
        program.write(workdir / "job.nc")
        report["program"] = program.summary()
        (workdir / "report.json").write_text(json.dumps(report, indent=2, default=float))
        return {"fabric": fabric, "garment": str(garment_path),
                "placement": str(workdir / "placement.json"),
                "layout": str(workdir / "layout.json"), "program": str(workdir / "job.nc"),
                "report": str(workdir / "report.json"),
                "pieces": [p.id for p in layout.pieces]}

    def program_for(self, layout_path: str | Path, only: set[str] | None):
        from gcode.layout import load_layout
        from gcode.program import build_program
        from gcode.toolpath import build_toolpaths

        layout = load_layout(layout_path)
        origin = self.config["machine"]["fabric_origin"]
        layout.origin = (float(origin[0]), float(origin[1]))
        toolpaths = build_toolpaths(layout, self.machine, only=only)
        title = f"station {Path(layout_path).parent.name}"
        return build_program(toolpaths, self.machine, title=title)

    # ------------------------------------------------------------------ cut
    def open_port(self):
        import serial

        import simulators.grbl  # noqa: F401  (registers grblsim://)

        port = self.config["serial"]["port"]
        if "://" in port:
            return serial.serial_for_url(port, baudrate=self.config["serial"]["baud"],
                                         timeout=0.02)
        return serial.Serial(port, self.config["serial"]["baud"], timeout=0.02)

    def cut(self, job: Job, plan: dict[str, Any], store: JobStore, control: JobControl,
            resuming: bool) -> None:
        """Stream the pieces not yet cut; each becomes cut only at its sync point."""
        from gcode.stream import Streamer, StreamError

        index = {name: p["piece"] for p in store.pieces(job.id) for name in [p["name"]]}
        todo = {p["name"] for p in store.pieces(job.id) if p["state"] != "cut"}
        if not todo:
            return
        program = self.program_for(plan["layout"], todo)

        def on_piece(piece) -> None:
            store.set_piece_state(job.id, index[piece.id], piece.state)

        def on_progress(p) -> None:
            control.progress.update(step="cutting", fraction=p.fraction,
                                    seconds_left=p.eta_seconds, machine=p.state,
                                    lines_sent=p.lines_sent, lines_total=p.lines_total)

        with self.open_port() as port:
            streamer = Streamer(port, on_piece=on_piece, on_progress=on_progress,
                                name=self.config["serial"]["port"])
            try:
                streamer.connect()
            except StreamError as exc:
                if "ALARM" not in str(exc):
                    raise
                # Position was lost (reset, power cut): home if the machine can, else unlock.
                homing = streamer.read_settings().get(22, 0.0) >= 1
                store.log(job.id, "machine", f"{exc}; {'homing' if homing else 'unlocking'}")
                if homing:
                    streamer.command("$H", timeout=120.0)
                else:
                    streamer.unlock()
            if self.config["machine"]["check_mode"] and not resuming:
                checked = streamer.run(program, check=True)
                if not checked.completed:
                    raise ValueError(f"the controller's check mode ($C) refused the program: "
                                     f"{checked.reason} {checked.errors[:1]}")
            result = self._stream(streamer, program, control)
        if control.abort.is_set():
            raise JobInterrupted("aborted", "aborted by the operator (safe stop)")
        if control.stop.is_set():
            raise JobInterrupted("paused", "interrupted: the daemon stopped (safe stop)")
        if not result.completed:
            raise RuntimeError(f"cut stopped: {result.reason} "
                               f"{(result.fault or {}).get('detail', '')}".strip())

    @staticmethod
    def _stream(streamer, program, control: JobControl):
        """Run the streamer in a worker thread while this one relays pause/resume/stop."""
        import threading

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


# ---------------------------------------------------------------------- planning steps
def align_garment(garment, wallpaper, config: Config, options: dict[str, Any]):
    """The best placement of the print on every piece (solver.align)."""
    from solver.align.api import align

    a = config["align"]
    grain = a["grain_tolerance_deg"]
    return align(garment, wallpaper,
                 method=options.get("method", a["method"]),
                 restarts=int(options.get("restarts", a["restarts"])),
                 seed=int(options.get("seed", a["seed"])),
                 reflect=a["reflect"], grain_tolerance_deg=grain if grain >= 0 else None)


def nest_placement(placement_path: Path, config: Config):
    """Nest the aligned pieces on the fabric in view, each kept on its print position."""
    from solver.nest.layout import verify_layout
    from solver.nest.solve import nest
    from solver.nest.sources import load_problem

    n = config["nest"]
    problem = load_problem([placement_path], width=n["width_mm"], length=n["length_mm"],
                           gap=n["gap_mm"])
    layout = nest(problem, time_limit=n["seconds"], seed=0)
    faults = verify_layout(layout, problem)
    if faults:
        raise ValueError(f"the marker failed verification: {faults[0]}")
    return layout
