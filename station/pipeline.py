"""The work of one job: capture the fabric, plan the cut, stream it, record every piece.

Each step hands the next the objects it made (`Captured`, the garment, the placement, the
layout in `Planned`), loading the garment once per plan, and writes them into the job's
folder for the operator (frame, FABRIC.json, placement, layout, G-code, pictures). The
daemon stores their paths as the job's plan: a job interrupted after planning resumes in
a new process from the files, not by recomputing; one process never reads them back.
Pieces are known to the job store by their layout id, so a resumed job rebuilds its
program for the pieces not yet cut and can never cut one twice.

The cut step also settles the one piece the store cannot know about: the one the
machine may have finished on its buffered moves after the daemon died. The program
carries markers the controller stores in EEPROM around each piece's final move
(`gcode.recovery`), the geometry those markers refer to is saved before streaming
(`save_final_moves`), and on the next start the machine is asked (`wait_at_rest`,
`read_params`, `station.cutting.reconcile`) before anything moves or resets it; the piece
in progress then continues where its cut stopped (`station.cutting.resumed_program`).
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gcode.recovery import (
    FINAL_MOVES,
    MARKER_SYSTEM,
    final_moves,
    head_position,
    read_params,
    save_final_moves,
    wait_at_rest,
)
from solver.jsonfile import read_json
from station.config import Config
from station.cutting import (
    journal_safe_stop,
    reconcile,
    resumed_program,
    stream_with_control,
)
from station.daemon import CONFIRM_FABRIC, JobControl, JobInterrupted
from station.jobstore import Job, JobStore
from station.stripes import stripe_grain, stripe_print

log = logging.getLogger("station.pipeline")

HELD_PLANS = 16  # plans a daemon keeps in memory for jobs paused and resumed in it


@dataclass
class Captured:
    """What capture hands to planning: the FABRIC.json document (written at ``path`` for
    the operator) and the rectified photo of the table, if one was taken."""

    path: str
    fabric: dict[str, Any]
    photo: np.ndarray | None = None
    mm_per_px: float = 1.0

    def __fspath__(self) -> str:
        return self.path

    @classmethod
    def read(cls, path: str | os.PathLike[str], workdir: Path) -> Captured:
        """The capture of a job planned in another process than the one that captured it
        (or after the operator confirmed its print): from the job's files."""
        import cv2

        camera = workdir / "camera.json"
        photo = cv2.imread(str(workdir / "rectified.png")) if camera.is_file() else None
        mm_per_px = float(read_json(camera)["mm_per_px"]) if photo is not None else 1.0
        return cls(os.fspath(path), read_json(path), photo, mm_per_px)


class Planned(dict):
    """The plan as the job store keeps it (the paths of the job's files) and, for the cut
    in the same process, the layout they were written from (``layout_doc``)."""

    def __init__(self, files: dict[str, Any], *, layout_doc: dict[str, Any],
                 program_summary: dict[str, Any]):
        super().__init__(files)
        self.layout_doc = layout_doc
        self.program_summary = program_summary


class StationPipeline:
    """Capture, plan and cut with the configured camera, machine and defaults."""

    def __init__(self, config: Config, *, simulate: bool = False) -> None:
        self.config = config
        self.simulate = simulate
        from gcode.machine import default_machine, load_machine

        profile = config["machine"]["profile"]
        machine = load_machine(config.resolve(profile)) if profile else default_machine()
        self.machine = with_station_cut(machine, config)
        # Plans made in this process by job id, so that a job paused and resumed here cuts
        # from the objects too; used only while the store's plan is still this one (another
        # station may have planned the job again since).
        self._planned: dict[int, Planned] = {}

    # ------------------------------------------------------------------ checks
    def check(self, garment: str, fabric: str | None, options: dict[str, Any]) -> None:
        """Refuse at submission what could never run (raises ValueError)."""
        from solver.garment import load_garment
        from solver.wallpaper import Wallpaper

        loaded = load_garment(garment, units=options.get("units"))
        if fabric is not None:
            Wallpaper.load(fabric)
        unknown = set(options) - {"units", "reshape", "method", "restarts", "seed",
                                  "grain_lines", "bias", "seam_allowance", "allowance",
                                  "symmetry", "pairs", "symmetrise"}
        if unknown:
            raise ValueError(f"unknown job option {sorted(unknown)[0]!r}")
        lines, bias = options.get("grain_lines", {}), options.get("bias", [])
        if not isinstance(lines, dict) or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in lines.values()):
            raise ValueError('job option grain_lines must be {"piece": degrees}')
        if not isinstance(bias, list) or not all(isinstance(b, (str, int)) for b in bias):
            raise ValueError("job option bias must be a list of pieces")
        with warnings.catch_warnings():  # a guessed grain is reported when the job runs
            warnings.simplefilter("ignore")
            grained(loaded, self.config, options)  # names every piece that does not exist
        from solver.garment.allowance import edge_allowances
        from station.allowance import rules_for_job

        edge_allowances(loaded, rules_for_job(self.config, options), ())  # names must exist
        for key in ("symmetry", "symmetrise"):
            if not isinstance(options.get(key, key == "symmetry"), bool):
                raise ValueError(f"job option {key} must be true or false")
        if "pairs" in options:
            from solver.garment.symmetry import pairs_from_dict

            pairs_from_dict(options["pairs"], loaded, "job option pairs")  # names must exist

    # ------------------------------------------------------------------ capture
    def capture(self, job: Job, workdir: Path, control: JobControl) -> Captured:
        """FABRIC.json of the job: the operator's file, or detected from a photograph;
        handed to :meth:`plan` with the rectified photo, written for the operator."""
        target = workdir / "fabric.json"
        if job.fabric is not None:
            fabric = read_json(job.fabric)
            shutil.copyfile(job.fabric, target)
            return Captured(str(target), fabric)
        import cv2

        start_step(control, "photographing")
        frame, rectified, mm_per_px, truth = self._photograph()
        cv2.imwrite(str(workdir / "frame.png"), frame)
        cv2.imwrite(str(workdir / "rectified.png"), rectified)
        camera = {"mm_per_px": mm_per_px, "frame": str(workdir / "frame.png"),
                  "rectified": str(workdir / "rectified.png"),
                  "truth": (truth.wallpaper.to_dict()
                            if truth is not None and truth.wallpaper is not None else None)}
        control.checkpoint()
        start_step(control, "detecting")
        try:
            from vision.pipeline import detect_fabric, draw_overlay
        except ImportError as exc:  # vision not installed: only the simulator can stand in
            if truth is None or truth.wallpaper is None:
                raise
            log.error("VISION UNAVAILABLE (%s): using the simulated camera's known print", exc)
            fabric = {**truth.wallpaper.to_dict(),
                      "source": "simulator truth: vision unavailable"}
        else:
            detection = detect_fabric(rectified, mm_per_px=mm_per_px,
                                      min_repeat_mm=self.config["camera"]["min_repeat_mm"])
            cv2.imwrite(str(workdir / "detection.png"), draw_overlay(rectified, detection))
            fabric = {**detection.fabric_json(), "source": "detected"}
            camera["detection"] = detection.summary()
            if fabric["group"] is None and fabric.get("kind") not in ("plain", "stripes"):
                raise ValueError("no periodic print found on the table "
                                 f"({detection.lattice.message or detection.lattice.kind}): "
                                 "give the job a FABRIC.json")
        (workdir / "camera.json").write_text(json.dumps(camera, indent=2, default=float))
        target.write_text(json.dumps(fabric, indent=2, default=float))
        below = float(self.config["camera"]["confirm_below"])
        if (fabric.get("source") == "detected" and fabric["group"] is not None
                and fabric["confidence"] < below):
            raise JobInterrupted("paused", f"{CONFIRM_FABRIC}: {fabric['group']} at "
                                 f"confidence {fabric['confidence']:.2f} (below {below:g}); "
                                 f"see detection.png, then `station confirm {job.id} "
                                 "[--group G]`")
        return Captured(str(target), fabric, rectified, float(mm_per_px))

    def _photograph(self):
        """(frame, rectified fabric area, mm per pixel, truth or None).

        The rectified image covers the usable fabric (nest length x width) from the
        fabric's corner on the table, so its pixel (c, r) is fabric point (c, r) * mm/px:
        what is detected there is in the fabric's own millimetres, as nesting wants.
        """
        from vision.camera import open_camera

        c, n = self.config["camera"], self.config["nest"]
        ox, oy = (float(v) for v in self.config["machine"]["fabric_origin"])
        region = (ox, oy, ox + n["length_mm"], oy + n["width_mm"])
        if self.simulate or c["source"] == "simulated":
            camera = open_camera(simulate=True, sim_factory=lambda: simulated_camera(
                self.config), average=c["frames"])
        else:
            camera = open_camera(c["source"], average=c["frames"])
        with camera:
            frame = camera.read()
            truth = getattr(camera, "truth", None)
        if c["calibration"]:
            from vision.calibration import Calibration
            from vision.rectify import rectify

            rectified, _region, mm_per_px = rectify(
                frame, Calibration.load(self.config.resolve(c["calibration"])), region=region)
        elif truth is not None:
            mm_per_px = float(truth.mm_per_px)
            rectified = truth.rectify(frame, region, mm_per_px)
        else:
            raise ValueError("camera.calibration is empty: calibrate the camera "
                             "(station calibrate) or use the simulated camera")
        if truth is not None and (ox, oy) != (0.0, 0.0):
            truth = None  # its print is in table mm; the station speaks fabric mm
        return frame, rectified, mm_per_px, truth

    # ------------------------------------------------------------------ plan
    def plan(self, job: Job, fabric: str | Captured, workdir: Path, control: JobControl
             ) -> Planned:
        """Align, optionally reshape, nest and program; every result is also a file in workdir.

        ``fabric`` is what :meth:`capture` handed over in this process, or the path of the
        job's FABRIC.json when it was captured by another process or confirmed by the
        operator. Each step takes the objects of the step before; the files are written
        for the operator and for a job resumed by another process, never read back here.
        Pictures for people go beside them: the pattern over the print before alignment,
        aligned and reshaped (seams coloured by mismatch), the marker on the fabric photo
        and the toolpath; report.json holds the numbers and the time of each step.
        """
        from solver.fit import fit_report
        from solver.garment.notches import cut_ready
        from solver.placement import Placement
        from solver.wallpaper import Wallpaper
        from station.allowance import rules_for_job
        from station.render import draw_fit, photo_colours

        captured = fabric if isinstance(fabric, Captured) else Captured.read(fabric, workdir)
        garment, garment_path, symmetrised = self._job_garment(job, workdir)
        kind = captured.fabric.get("kind")
        if kind == "plain" or (kind == "stripes" and not job.options.get("match_stripes", True)):
            return self.plan_plain(job, captured, garment, garment_path, workdir, control)
        fabric = (stripe_print(captured.fabric, self.config["align"]["fabric_grain_deg"])
                  if kind == "stripes" else captured.fabric)
        wallpaper = Wallpaper.from_dict(fabric, captured.path)
        report: dict[str, Any] = {"job": job.id, "garment": job.garment,
                                  "fabric": {k: fabric.get(k) for k in (
                                      "group", "w1", "w2", "origin", "source", "confidence",
                                      "kind", "period_mm", "direction_deg", "grain_deg",
                                      "note") if k in fabric}, "seconds": {}}
        if symmetrised is not None:
            report["symmetrise"] = symmetrised.to_dict()
        clock = time.perf_counter()

        def lap(step: str) -> None:
            nonlocal clock
            now = time.perf_counter()
            report["seconds"][step] = round(now - clock, 3)
            clock = now

        before = Placement.identity(garment.n_pieces, wallpaper)
        identity = fit_report(garment, before)
        report["e_fit_identity_mm2"] = identity.e_fit_mm2
        colour_of = photo_colours(captured.photo, captured.mm_per_px, wallpaper)
        draw_fit(garment, before, identity, workdir / "fit-before.png",
                 title=f"before alignment on {wallpaper.group}", colour_of=colour_of)
        start_step(control, "aligning", 0.0)

        def on_restart(k: int, n: int, _e_random: float, _e_aligned: float) -> None:
            control.progress.update(step="aligning", fraction=min(1.0, k / max(n, 1)))
            control.checkpoint()

        garment = grained(garment, self.config, job.options)
        placement = align_garment(garment, wallpaper, self.config, job.options, on_restart,
                                  fabric_grain_deg=fabric.get("grain_deg"))
        placement.garment = str(garment_path)
        report["align"] = placement.report
        aligned = fit_report(garment, placement)
        final_fit = aligned
        rules = rules_for_job(self.config, job.options)
        report["allowance"] = rules.to_dict()
        cuts, notches = cut_ready(garment, rules, placement)
        draw_fit(garment, placement, aligned, workdir / "fit-aligned.png",
                 title=f"aligned on {wallpaper.group}", colour_of=colour_of, cuts=cuts,
                 notches=notches)
        lap("align")
        self._write_report(workdir, report)
        control.checkpoint()
        aligned_garment, aligned_path = garment, garment_path
        if job.options.get("reshape", self.config["reshape"]["enabled"]):
            start_step(control, "reshaping")
            from solver.garment import save_obj
            from solver.garment.symmetry import fit_pairs
            from solver.reshape import ReshapeOptions, reshape

            garment, reshaped = reshape(garment, placement, options=ReshapeOptions(
                max_move_mm=self.config["reshape"]["max_move_mm"]),
                pairs=fit_pairs(garment, [p[:2] for p in placement.pairs]))
            garment_path = workdir / "garment-reshaped.obj"
            save_obj(garment, garment_path)
            placement.garment = str(garment_path)
            report["reshape"] = reshaped.to_dict()
            final_fit = fit_report(garment, placement)
            cuts, notches = cut_ready(garment, rules, placement)  # follows the sew
            draw_fit(garment, placement, final_fit, workdir / "fit-reshaped.png",
                     title=f"reshaped on {wallpaper.group}", colour_of=colour_of, cuts=cuts,
                     notches=notches, original=aligned_garment)
            lap("reshape")
            self._write_report(workdir, report)
            control.checkpoint()
        placement.save(workdir / "placement.json")
        seconds = self.config["nest"]["seconds"]
        start_step(control, "nesting", 0.0)
        t_nest = time.monotonic()

        def on_nest(_message: str) -> None:
            control.progress.update(step="nesting", fraction=min(
                1.0, (time.monotonic() - t_nest) / seconds))

        try:
            layout = nest_placement(garment, placement, self.config, on_nest, job.options)
        except ValueError as exc:
            if garment is aligned_garment:
                raise
            # A reshaped outline the cutter cannot use (e.g. crossing itself) must not stop
            # the job: cut the aligned pattern, and say so.
            log.error("job %d: the reshaped pattern cannot be nested (%s); cutting the "
                      "aligned pattern instead", job.id, exc)
            report["reshape"]["rejected"] = f"not used for cutting: {exc}"
            garment, garment_path, final_fit = aligned_garment, aligned_path, aligned
            placement.garment = str(garment_path)
            placement.save(workdir / "placement.json")
            t_nest = time.monotonic()
            layout = nest_placement(garment, placement, self.config, on_nest, job.options)
        layout.save(workdir / "layout.json")
        report["nest"] = {"length_mm": layout.length, "width_mm": layout.width,
                          "density": layout.density, "pieces": len(layout.pieces)}
        lap("nest")
        self._write_report(workdir, report)
        control.checkpoint()
        planned = self._program(job, captured, garment_path, layout, workdir, control,
                                garment=garment, report=final_fit, photo=captured)
        report["program"] = planned.program_summary
        lap("program")
        self._write_report(workdir, report)
        return planned

    def plan_plain(self, job: Job, captured: Captured, garment, garment_path: Path,
                   workdir: Path, control: JobControl) -> Planned:
        """Plain cloth (the camera found only the weave), or stripes the job does not
        match (option ``match_stripes`` false): nothing to align, so the pieces are nested
        on grain as drawn, then programmed; same files as :meth:`plan`. Stripes set the
        grain (:func:`stripe_grain`)."""
        from solver.placement import Placement
        from solver.wallpaper import Wallpaper

        # Each piece turned so that its grain runs along the cloth's (the roll, unless the
        # station says otherwise); the placement's print is a stand-in that nest_placement
        # drops (plain nesting). The grain rule goes with it, so nesting keeps the grain.
        garment = grained(garment, self.config, job.options)
        a = self.config["align"]
        cloth = stripe_grain(captured.fabric, a["fabric_grain_deg"])
        grain_deg = np.array([g.deg for g in garment.grains()])
        placement = Placement(np.radians(grain_deg - cloth["grain_deg"]),
                              np.zeros((garment.n_pieces, 2)), Wallpaper("p1", (1, 0), (0, 1)),
                              piece_names=list(garment.piece_names),
                              grains=[g.to_dict() for g in garment.grains()],
                              grain_rule={"tolerance_deg": a["grain_tolerance_deg"]
                                          if a["grain_tolerance_deg"] >= 0 else None,
                                          "nap": a["nap"],
                                          "fabric_grain_deg": cloth["grain_deg"]})
        placement.garment = str(garment_path)
        placement.save(workdir / "placement.json")
        start_step(control, "nesting", 0.0)
        layout = nest_placement(garment, placement, self.config, None, job.options,
                                plain=True)
        layout.save(workdir / "layout.json")
        control.checkpoint()
        planned = self._program(job, captured, garment_path, layout, workdir, control)
        self._write_report(workdir, {
            "job": job.id, "garment": job.garment, "fabric": cloth,
            "nest": {"length_mm": layout.length, "width_mm": layout.width,
                     "density": layout.density, "pieces": len(layout.pieces)},
            "program": planned.program_summary})
        return planned

    def _job_garment(self, job: Job, workdir: Path):
        """(garment, path of the job's copy, symmetrise report or None): the submitted
        pattern loaded once, in mm, symmetrised if the job asks (:func:`symmetrise_job`),
        and copied beside the job's files (with its licence note) for the operator and for
        a job resumed by another process."""
        from solver.garment import load_garment, save_obj

        garment = load_garment(job.garment, units=job.options.get("units"))
        garment, symmetrised = symmetrise_job(garment, job.options)
        garment_path = workdir / "garment.obj"
        save_obj(garment, garment_path)
        keep_licence_note(Path(job.garment), workdir)
        return garment, garment_path, symmetrised

    def _program(self, job: Job, captured: Captured, garment_path: Path, layout, workdir: Path,
                 control: JobControl, *, garment=None, report=None,
                 photo: Captured | None = None) -> Planned:
        """Program the nested layout (job.nc) and draw the toolpath and the marker (on the
        photo when there is one); the plan's files, with the layout for :meth:`cut`."""
        from station.render import draw_marker, draw_toolpath, garment_credit

        start_step(control, "programming")
        doc = layout.to_dict()
        program = self.program_for(doc, None, job_dir=workdir)
        program.write(workdir / "job.nc")
        credit = garment_credit(job.garment)  # the submitted file's licence, not the copy's
        draw_toolpath(program, self.machine, workdir / "toolpath.png", credit=credit)
        draw_marker(doc, workdir / "marker.png", garment=garment, report=report,
                    photo=None if photo is None else photo.photo,
                    photo_mm_per_px=1.0 if photo is None else photo.mm_per_px, credit=credit)
        planned = Planned({"fabric": captured.path, "garment": str(garment_path),
                           "placement": str(workdir / "placement.json"),
                           "layout": str(workdir / "layout.json"),
                           "program": str(workdir / "job.nc"),
                           "report": str(workdir / "report.json"),
                           "pieces": [p.id for p in layout.pieces]},
                          layout_doc=doc, program_summary=program.summary())
        self._planned.pop(job.id, None)
        self._planned[job.id] = planned
        while len(self._planned) > HELD_PLANS:  # the oldest go: they resume from files
            self._planned.pop(next(iter(self._planned)))
        return planned

    @staticmethod
    def _write_report(workdir: Path, report: dict[str, Any]) -> None:
        """report.json after every step, so a failed job still shows what it got to."""
        (workdir / "report.json").write_text(json.dumps(report, indent=2, default=float))

    def program_for(self, layout: str | Path | dict, only: set[str] | None, *,
                    job_dir: Path | None = None):
        """The checked program for the pieces ``only`` (None: all) of a layout: the
        nesting's own layout document while planning (no trip through the disk), the
        job's LAYOUT.json when a stopped job resumes."""
        from gcode.program import build_program

        toolpaths, where = self.toolpaths_for(layout, only, job_dir=job_dir)
        return build_program(toolpaths, self.machine, title=f"station {where.name}")

    def toolpaths_for(self, layout: str | Path | dict, only: set[str] | None, *,
                      job_dir: Path | None = None):
        """(toolpaths of the pieces ``only`` in cut order, the job's folder)."""
        from gcode.layout import layout_from_dict, load_layout
        from gcode.toolpath import build_toolpaths

        if isinstance(layout, dict):
            where = job_dir or Path(".")
            layout = layout_from_dict(layout, str(where / "layout.json"))
        else:
            where = Path(layout).parent
            layout = load_layout(layout)
        origin = self.config["machine"]["fabric_origin"]
        layout.origin = (float(origin[0]), float(origin[1]))
        return build_toolpaths(layout, self.machine, only=only), where

    # ------------------------------------------------------------------ cut
    @property
    def port_name(self) -> str:
        """The port as the log names it (the emulator's long URL shortened)."""
        port = self.config["serial"]["port"]
        return port.split("?", 1)[0] if "://" in port else port

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
        """Stream the pieces not yet cut; each becomes cut only at its sync point.

        Before anything is sent the machine is asked what it did while nobody was
        listening (see `gcode.recovery` and `reconcile`): the piece in flight when the last
        daemon died may have finished on the machine's buffered moves.
        """
        from gcode.stream import BEAM_OFF, Streamer, StreamError

        pieces = store.pieces(job.id)
        index = {p["name"]: p["piece"] for p in pieces}
        with self.open_port() as port:
            start_step(control, "connecting")
            port.write(BEAM_OFF)  # before anything else: a lost link may have left M4 S700
            rest = wait_at_rest(port, stop=lambda: control.stop.is_set()
                                or control.abort.is_set())
            control.checkpoint(hold_in_place=True)  # stopped or aborted while waiting
            streamer = Streamer(port, on_piece=None, name=self.port_name,
                                rx_buffer=self.machine.rx_buffer,
                                acceleration=self.machine.acceleration,
                                rapid_feed=self.machine.rapid_feed)
            alarm = rest is not None and rest.state == "Alarm"
            try:
                # at rest and silent already (or not answering): no need to wait long
                streamer.connect(quiet=0.2)
            except StreamError as exc:
                if "ALARM" not in str(exc):
                    raise
                alarm = True
                alarm_text = str(exc)
            else:
                alarm_text = ""
            params = read_params(streamer)
            self.reconcile(job, plan, store, rest, alarm, params)
            if alarm:
                # Position was lost (reset, power cut): home if the machine can, else unlock.
                homing = streamer.read_settings().get(22, 0.0) >= 1
                store.log(job.id, "machine", f"{alarm_text or 'controller in ALARM'}; "
                          f"{'homing' if homing else 'unlocking'}")
                start_step(control, "homing" if homing else "unlocking")
                if homing:
                    streamer.command("$H", timeout=120.0)
                else:
                    streamer.unlock()
            todo = {p["name"] for p in store.pieces(job.id) if p["state"] != "cut"}
            if not todo:
                return
            # What the marker said is in the store now: clear it, so that a piece cut again
            # cannot be judged by a marker its earlier, interrupted attempt left.
            cleared, _ = streamer.command(f"G10 L2 P{MARKER_SYSTEM} X0 Y0 Z0")
            if cleared.kind != "ok":
                raise RuntimeError(f"the controller refused to clear the piece marker: "
                                   f"{cleared.raw}")
            # the layout planned in this process, else (resumed after a restart) LAYOUT.json
            held = plan if isinstance(plan, Planned) else self._planned.get(job.id)
            layout = held.layout_doc if held is not None and held == plan else plan["layout"]
            job_dir = Path(plan["layout"]).parent
            toolpaths, _ = self.toolpaths_for(layout, todo, job_dir=job_dir)
            here = head_position(rest, alarm, params)
            program, journal = resumed_program(toolpaths, self.machine, store, job, index,
                                               job_dir, here, f"station {job_dir.name}")
            journal.follow(program, self.machine.cut.feed / 60.0, streamer.time_scale)
            # The geometry a marker refers to, saved before a line goes out: the toolpath
            # order (and so where each contour starts and ends) depends on which pieces
            # are left, so the next start must judge by this program, not a fresh one.
            save_final_moves(job_dir / FINAL_MOVES, job.id, final_moves(program, index))

            def on_piece(piece) -> None:
                store.set_piece_state(job.id, index[piece.id], piece.state)
                journal.on_piece(index[piece.id], piece.state)

            planned = program.check.estimated_seconds if program.check is not None else None

            def on_progress(p) -> None:
                journal.update(p.lines_acked, streamer.status, params)
                # The streamer's ETA extrapolates the time taken so far; before there is
                # enough of it, the program's own time estimate stands in.
                eta = p.eta_seconds
                if eta is None and planned is not None and stage[0] == "cutting":
                    eta = planned * (1.0 - p.fraction)
                control.progress.update(step=stage[0], fraction=p.fraction,
                                        seconds_left=eta, machine=p.state,
                                        lines_sent=p.lines_sent, lines_total=p.lines_total,
                                        pieces_cut=len(index) - len(todo) + p.pieces_cut,
                                        pieces_total=len(index))

            streamer.on_progress = on_progress
            stage = ["checking ($C)"]
            if self.config["machine"]["check_mode"] and not resuming:
                start_step(control, stage[0], 0.0)
                checked = streamer.run(program, check=True)
                if not checked.completed:
                    raise ValueError(f"the controller's check mode ($C) refused the program: "
                                     f"{checked.reason} {checked.errors[:1]}")
            streamer.on_piece = on_piece
            stage[0] = "cutting"
            start_step(control, "cutting", 0.0)
            result = stream_with_control(streamer, program, control)
            if control.stop.is_set():
                journal_safe_stop(journal, result, streamer.status, params, job_dir)
        if control.abort.is_set():
            raise JobInterrupted("aborted", "aborted by the operator (safe stop)")
        if control.stop.is_set():
            raise JobInterrupted("paused", "interrupted: the daemon stopped (safe stop)")
        if not result.completed:
            raise RuntimeError(f"cut stopped: {result.reason} "
                               f"{(result.fault or {}).get('detail', '')}".strip())
        self._planned.pop(job.id, None)  # every piece cut: nothing left to resume

    #: what the machine finished after the last daemon stopped listening (station.cutting)
    reconcile = staticmethod(reconcile)


# ---------------------------------------------------------------------- planning steps
def with_station_cut(machine, config: Config):
    """The profile with station.toml's [cut] (kerf, feed, power, passes) in force, checked
    against the profile's ranges; a refusal names the file and the key."""
    cut = config["cut"]
    try:
        return machine.with_cut(kerf=float(cut["kerf_mm"]), feed=float(cut["feed_mm_min"]),
                                power=float(cut["power"]), passes=int(cut["passes"]))
    except ValueError as exc:
        where = config.path or "station.toml"
        detail = str(exc).split(": ", 1)[-1]
        raise ValueError(f"{where}: [cut] does not fit the machine profile "
                         f"{machine.source}: {detail}") from None


def keep_licence_note(garment: Path, workdir: Path) -> None:
    """Copy the garment library's README beside the job's copy of the pattern, so every
    picture drawn from the copy still carries the acknowledgement its licence asks for."""
    from station.render import garment_credit

    if garment_credit(garment) is None:
        return
    for name in ("README.txt", "BERKELEY-README.txt"):
        note = garment.resolve().parent / name
        if note.is_file():
            shutil.copyfile(note, workdir / "BERKELEY-README.txt")
            return


def start_step(control: JobControl, step: str, fraction: float | None = None) -> None:
    """Announce a step in the job's progress (what `station status` and `watch` show);
    ``fraction`` only where the step can measure how far it is."""
    control.progress.clear()
    control.progress.update(step=step, **({} if fraction is None else {"fraction": fraction}))


def simulated_camera(config: Config, print_name: str = "plaid", repeat_mm: float = 80.0,
                     seed: int = 3):
    """The dry run's camera: a plaid sheet covering the usable fabric, seen from above."""
    from simulators.camera import Sheet, SyntheticCamera
    from simulators.classics import classic_print

    n = config["nest"]
    ox, oy = (float(v) for v in config["machine"]["fabric_origin"])
    sheet = Sheet(classic_print(print_name, repeat_mm, origin=(13.0, 21.0)),
                  size=(n["length_mm"], n["width_mm"]), shift=(ox, oy))
    return SyntheticCamera(sheet, seed=seed)


def align_garment(garment, wallpaper, config: Config, options: dict[str, Any],
                  progress=None, fabric_grain_deg: float | None = None):
    """The best placement of the print on every piece (solver.align), on grain as the
    configuration says; ``fabric_grain_deg`` (FABRIC.json's) wins over the station's.

    ``progress(k, n, e_random, e_aligned)`` is called as each random restart finishes.
    """
    from solver.align import align
    from solver.align.symmetric import align_symmetric
    from solver.garment.symmetry import mirror_pairs, pairs_from_dict

    a = config["align"]
    grain = a["grain_tolerance_deg"]
    fabric_grain = a["fabric_grain_deg"] if fabric_grain_deg is None else fabric_grain_deg
    common = dict(method=options.get("method", a["method"]),
                  restarts=int(options.get("restarts", a["restarts"])),
                  seed=int(options.get("seed", a["seed"])),
                  reflect=a["reflect"], grain_tol_deg=grain if grain >= 0 else None,
                  progress=progress)
    pairs = []
    if options.get("symmetry", a["symmetry"]):
        declared, vetoed = pairs_from_dict(options.get("pairs", {}), garment,
                                           "job option pairs")
        pairs = mirror_pairs(garment, declared=declared, vetoed=vetoed)
    if pairs:
        return align_symmetric(garment, wallpaper, pairs, grain_deg=fabric_grain,
                               nap=a["nap"], **common)
    return align(garment, wallpaper, nap=a["nap"], fabric_grain_deg=fabric_grain, **common)


def symmetrise_job(garment, options: dict[str, Any]):
    """The job's garment with its left/right pairs (the job's ``pairs`` option heard) made
    one pattern each when the job asks (``symmetrise``), and the record of it (or None)."""
    if not options.get("symmetrise", False):
        return garment, None
    from solver.garment.symmetrise import symmetrise
    from solver.garment.symmetry import mirror_pairs, pairs_from_dict

    declared, vetoed = pairs_from_dict(options.get("pairs", {}), garment, "job option pairs")
    sym = symmetrise(garment, mirror_pairs(garment, declared=declared, vetoed=vetoed))
    return sym.garment, sym


def grained(garment, config: Config, options: dict[str, Any]):
    """``garment`` with the job's grain lines and bias pieces and the station's up axis."""
    up = config["align"]["up"]
    return garment.with_grain(lines=options.get("grain_lines"), bias=options.get("bias", ()),
                              up=None if up == "auto" else up)


def nest_placement(garment, placement, config: Config, progress=None, options=None, *,
                   plain: bool = False):
    """Nest the aligned pieces' cut lines on the fabric in view, each kept on its print
    position (``plain``: on plain cloth, free of any print); ``options`` are the job's
    (its seam allowances)."""
    from solver.nest.budget import Deadline
    from solver.nest.layout import verify_layout
    from solver.nest.solve import nest
    from solver.nest.sources import placement_problem
    from station.allowance import rules_for_job

    n = config["nest"]
    deadline = Deadline(n["seconds"])  # making the cut lines and verifying count too
    problem = placement_problem(garment, placement, width=n["width_mm"],
                                length=n["length_mm"], gap=n["gap_mm"],
                                allowance=rules_for_job(config, options or {}), plain=plain)
    layout = nest(problem, time_limit=deadline, seed=0, progress=progress)
    faults = verify_layout(layout, problem)
    if faults:
        raise ValueError(f"the marker failed verification: {faults[0]}")
    return layout
