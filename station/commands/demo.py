"""`station demo`: one whole job on the simulated station, through the real daemon.

A daemon (the same `Daemon` and `StationPipeline` as `station serve --simulate`) runs in
this process with a job store and control socket in a temporary folder; the demo submits
the example garment over the socket like the console does, follows it with progress bars,
and copies what the job produced into the output folder. Nothing here plans or cuts by
itself, so the demo proves the product rather than a parallel script.
"""

from __future__ import annotations

import argparse
import json
import logging
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from simulators.grbl import lookup
from simulators.grbl.trace import trace_rows
from solver.garment import load_garment
from solver.wallpaper import Wallpaper
from station.control import request
from station.daemon import CONFIRM_SEAMS, setup_logging
from station.fleetdemo import run as run_fleet
from station.order import is_order_file, read_order
from station.progress import follow
from station.simseams import measure_seams
from station.simstation import (
    SimulatedRoll,
    copy_job_files,
    read_json_or_empty,
    start_simulated_station,
)
from station.steps.bites import operator_advance_mm
from station.steps.program import fabric_origin

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "tshirt-iso.obj"

#: What the demo leaves in --out, from the job's folder (missing optional ones are named).
FILES = {
    "frame.png": "camera frame",
    "rectified.png": "frame rectified onto the fabric (mm grid)",
    "detection.png": "detection overlay: lattice and symmetry elements",
    "fit-before.png": "pattern on the print before alignment, seams by mismatch",
    "fit-aligned.png": "pattern aligned",
    "fit-reshaped.png": "pattern aligned and reshaped",
    "marker.png": "the marker on the fabric photo, seams by mismatch",
    "toolpath.png": "the toolpath",
    "job.nc": "the G-code",
    "fabric.json": "the print as detected (FABRIC.json)",
    "placement.json": "the alignment (PLACEMENT.json)",
    "layout.json": "the marker (LAYOUT.json)",
}


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo", help="run one whole job on the simulated station",
        description="Photograph a simulated plaid with the synthetic camera, detect its "
        "print, align, reshape and nest the example t-shirt, and cut it on the GRBL "
        "emulator, all through the station daemon; write every picture, the G-code and a "
        "report to --out and print a summary.")
    p.add_argument("--out", default="demo-out", metavar="DIR", help="output folder")
    p.add_argument("--garment", default=str(EXAMPLE), help="garment (default: the example "
                   "Berkeley t-shirt, in metres)")
    p.add_argument("--units", choices=("m", "cm", "mm", "in"),
                   help="the garment file's units (default: what the file says; the example "
                   "t-shirt is in metres)")
    p.add_argument("--restarts", type=int, help="alignment restarts (default 8; fleet 2)")
    p.add_argument("--nest-seconds", type=float,
                   help="time for nesting, loading and verifying included (default 4; "
                   "fleet 3)")
    p.add_argument("--no-reshape", action="store_true", help="skip reshaping (a fleet "
                   "demo always does)")
    p.add_argument("--speed", type=float, default=20.0,
                   help="emulated machine's speed-up (simulated s per wall s)")
    p.add_argument("--copies", type=int, default=1, metavar="N",
                   help="an order of N copies of the garment, nested in one marker and cut "
                   "in bites when it is longer than the table (the simulated roll slips)")
    p.add_argument("--by-hand", action="store_true",
                   help="no conveyor: the job waits at 'advance the fabric N mm' and the demo "
                   "plays the operator (advances the simulated roll, then station resume)")
    p.add_argument("--fleet", type=int, default=0, metavar="N",
                   help="N simulated stations sharing one PostgreSQL job store (started "
                   "here), each with its own emulator and camera")
    p.add_argument("--jobs", type=int, default=8, metavar="M",
                   help="jobs to queue for the fleet (with --fleet)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    garment = Path(args.garment)
    if not garment.is_file():
        raise FileNotFoundError(f"{garment}: no such garment file")
    if args.units is None and garment.resolve() == EXAMPLE.resolve():
        args.units = "m"  # the Berkeley example does not say its units
    if is_order_file(garment):  # a bad order or garment is one line before any station starts
        read_order(garment)
    else:
        load_garment(garment, units=args.units)
    if _settle_args(args):
        return run_fleet(args)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    setup_logging(logging.WARNING)
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="station-demo-") as tmp:
        daemon, worker = start_simulated_station(args, f"demo-{id(args)}", {
            "store": {"path": f"{tmp}/jobs.db", "work_dir": f"{tmp}/jobs"},
            "control": {"socket": f"{tmp}/station.sock"},
        })
        sock = daemon.control.path
        submitted = garment.resolve() if args.copies == 1 else copies_order(
            garment, args.copies, args.units, Path(tmp))
        try:
            job = request(sock, "submit", garment=str(submitted), fabric=None,
                          options={"units": args.units} if args.copies == 1 else {}
                          )["job"]["id"]
            print(f"station demo: job {job} submitted to the simulated station "
                  f"(store and socket in {tmp})", file=sys.stderr)
            status = follow_by_hand(sock, job, daemon)  # the operator answers what it asks
            events = request(sock, "log", job=job, limit=100000)["events"]
        finally:
            daemon.shutdown()
            worker.join(30)
            daemon.control.stop()
        workdir = Path(tmp) / "jobs" / f"job-{job}"
        copied = copy_job_files(workdir, out, FILES)
        plan_report = read_json_or_empty(workdir / "report.json")
        camera = read_json_or_empty(workdir / "camera.json")
        fabric = read_json_or_empty(workdir / "fabric.json")
        pieces = pieces_cut(daemon.store.pieces(job), events)
        roll = daemon.pipeline.roll
        simulated = isinstance(roll, SimulatedRoll)
        truth = roll.truth() if simulated else None
        emulator = lookup(f"demo-{id(args)}")
        seams = measure_seams(workdir, roll.print, roll.conveyor.poses,
                              trace=None if emulator is None else trace_rows(emulator),
                              origin=fabric_origin(daemon.pipeline.config)
                              ) if simulated else {}
        daemon.store.close()
    seconds = time.monotonic() - t0
    summary = summarise(status, plan_report, camera, fabric, seconds)
    summary["bites"] = plan_report.get("bites")
    summary["advances_truth"] = truth  # the simulated conveyor's, slips included
    summary["pieces"] = pieces
    summary.update(seams)  # the print across the seams as cut on the simulated cloth
    # pieces whose seams are expected off the print by over the tolerance, and by how much
    summary["pieces_distorted"] = [
        {"piece": r["piece"], "seam_error_expected_mm": r["seam_error_expected_mm"]}
        for r in plan_report.get("local_maps") or [] if r.get("distorted")]
    missing = [name for name in FILES if name not in copied]
    report = {"summary": summary, "job": status, "plan": plan_report, "camera": camera,
              "files": {name: FILES[name] for name in copied}, "missing": missing,
              "events": events}
    (out / "report.json").write_text(json.dumps(report, indent=2, default=float))
    print_summary(summary, out, missing)
    return 0 if status["state"] == "done" else 1


def _settle_args(args: argparse.Namespace) -> bool:
    """Fill the defaults that depend on --fleet and refuse what is not positive; whether
    this is a fleet demo."""
    fleet = args.fleet > 0
    args.restarts = args.restarts if args.restarts is not None else (2 if fleet else 8)
    args.nest_seconds = (args.nest_seconds if args.nest_seconds is not None
                         else 3.0 if fleet else 4.0)
    if fleet:
        args.no_reshape = True  # eight reshapes would take minutes; the single demo shows it
    if args.restarts < 1 or args.nest_seconds <= 0 or args.speed <= 0 or args.copies < 1:
        raise ValueError("--restarts, --nest-seconds, --speed and --copies must be positive")
    return fleet


def follow_by_hand(sock: Path, job: int, daemon) -> dict[str, Any]:
    """`follow` the job, playing the operator whenever it waits: for the roll to be
    advanced (the simulated roll moved by the mm asked, slipping, then `resume`), or at
    "confirm seams" (a CAD pattern's seams confirmed as found, as seams.png shows them)."""
    status = follow(sock, job)
    while status["state"] == "paused":
        if status["reason"].startswith(CONFIRM_SEAMS):
            print("station demo: the operator looks at seams.png and confirms the seams",
                  file=sys.stderr)
            request(sock, "confirm", job=job)
        elif (mm := operator_advance_mm(status["reason"])) is not None:
            print(f"station demo: the operator advances the fabric {mm:.1f} mm and resumes",
                  file=sys.stderr)
            daemon.pipeline.roll.advance(mm)
            request(sock, "resume", job=job)
        else:
            break
        status = follow(sock, job)
    return status


def copies_order(garment: Path, copies: int, units: str | None, folder: Path) -> Path:
    """An order of ``copies`` of ``garment``, written in ``folder`` beside a copy of it
    (an order names its patterns relative to itself)."""
    shutil.copyfile(garment, folder / garment.name)
    order = folder / "order.toml"
    lines = ['name = "demo"', "[[garment]]", f"pattern = {json.dumps(garment.name)}",
             f"copies = {copies}", *([f'units = "{units}"'] if units else [])]
    order.write_text("\n".join(lines) + "\n")
    return order


def pieces_cut(pieces: list[dict[str, Any]], events: list[dict[str, Any]]
               ) -> list[dict[str, Any]]:
    """The report's ``pieces``: each piece's bite (None: the marker was cut whole) and how
    many times the job's log says it was cut (exactly once, or something went wrong)."""
    cut_events = [e["message"] for e in events if e.get("kind") == "piece"]
    return [{"piece": p["name"], "bite": p.get("bite"),
             "times_cut": sum(m == f"piece {p['piece']} ({p['name']}) cut" for m in cut_events)}
            for p in pieces]


def lattice_error(detected: dict[str, Any], truth: dict[str, Any]) -> float | None:
    """Largest distance (mm) between the detected and true lattices' reduced basis
    vectors, matched up to order and sign (the same lattice has many bases)."""

    try:
        d = Wallpaper.from_dict(detected).reduced()
        t = Wallpaper.from_dict(truth).reduced()
    except (KeyError, TypeError, ValueError):
        return None
    tv = np.array([t.w1, -t.w1, t.w2, -t.w2, t.w1 + t.w2, -(t.w1 + t.w2), t.w1 - t.w2,
                   t.w2 - t.w1])
    return float(max(np.hypot(*(tv - v).T).min() for v in (d.w1, d.w2)))


def summarise(status: dict[str, Any], plan: dict[str, Any], camera: dict[str, Any],
              fabric: dict[str, Any], seconds: float) -> dict[str, Any]:
    align = plan.get("align") or {}
    reshape = plan.get("reshape") or {}
    truth = camera.get("truth")
    pieces = status.get("pieces", {})
    return {
        "state": status.get("state"),
        "reason": status.get("reason"),
        "fabric_source": fabric.get("source"),
        "group_detected": fabric.get("group"),
        "group_truth": truth.get("group") if truth else None,
        "confidence": fabric.get("confidence"),
        "lattice_error_mm": lattice_error(fabric, truth) if truth and fabric.get("group")
        else None,
        "e_fit_random_cm2": align.get("e_fit_random_cm2"),
        "e_fit_aligned_cm2": align.get("e_fit_aligned_cm2"),
        "e_fit_reshaped_cm2": (reshape["e_fit_after_mm2"] / 100.0
                               if "e_fit_after_mm2" in reshape else None),
        "reshape_rejected": reshape.get("rejected"),
        "off_grain_max_deg": align.get("off_grain_max_deg"),
        "grain_tol_deg": align.get("grain_tol_deg"),
        "grain_guessed": align.get("grain_guessed") or [],
        "reshape_max_move_mm": reshape.get("max_displacement_mm"),
        "reshape_area_change_max_pct": reshape.get("area_change_max_pct"),
        "nest_density": (plan.get("nest") or {}).get("density"),
        "allowance": plan.get("allowance"),
        "pieces_cut": pieces.get("cut", 0),
        "pieces_total": sum(pieces.values()) if pieces else 0,
        "step_seconds": plan.get("seconds"),
        "seconds": round(seconds, 1),
    }


def cut_ready_parts(s: dict[str, Any]) -> list[str]:
    """The parts of the demo's one "cut-ready" line, one per concern: the seam allowance
    here; grain and the largest reshape move add their own part to the same list."""
    parts = []
    a = s.get("allowance")
    if a:
        parts.append(f"seam allowance {a['seam_mm']:g} mm (hems {a['hem_mm']:g}, openings "
                     f"{a['opening_mm']:g})")
    return parts


def seam_lines(s: dict[str, Any]) -> list[str]:
    """The summary's seam line: the print's mismatch across the seams on the simulated
    cloth at the 90th percentile, as cut, uncompensated and planned (none: no bites)."""
    cut, matched = s.get("seam_mismatch_mm"), s.get("seam_matched")
    if not cut or not matched:
        return []

    def p90(d: dict[str, Any] | None) -> str:
        return f"{d['p90']:.2f}" if d and d.get("p90") is not None else "n/a"

    return [f"  seams p90     {p90(cut)} mm as cut on the cloth, "
            f"{p90(s.get('seam_mismatch_uncompensated_mm'))} uncompensated, "
            f"{p90(s.get('seam_mismatch_planned_mm'))} as planned; where the plan matched "
            f"({matched['seam_mismatch_mm']['seams']} edges) {p90(matched['seam_mismatch_mm'])}"
            f" mm, {p90(matched.get('seam_mismatch_uncompensated_mm'))} uncompensated"]


def print_summary(s: dict[str, Any], out: Path, missing: list[str]) -> None:
    def num(v, fmt: str) -> str:
        return "n/a" if v is None else format(v, fmt)

    lines = [f"station demo: job {s['state']}" + (f" ({s['reason']})" if s["reason"] else "")]
    if s["fabric_source"] != "detected":
        lines.append("  !!! VISION UNAVAILABLE: the print below is the simulator's KNOWN TRUTH, "
                     "not a detection !!!")
    lines += [
        f"  print         {s['group_detected']} detected (truth {s['group_truth']}), "
        f"confidence {num(s['confidence'], '.2f')}, lattice error "
        f"{num(s['lattice_error_mm'], '.2f')} mm",
        f"  E_fit         random {num(s['e_fit_random_cm2'], '.1f')} cm^2 / aligned "
        f"{num(s['e_fit_aligned_cm2'], '.1f')} cm^2 / reshaped "
        f"{num(s['e_fit_reshaped_cm2'], '.2f')} cm^2",
    ]
    if s.get("reshape_rejected"):
        lines.append(f"  !!! reshaped pattern {s['reshape_rejected']}; the aligned one was cut")
    tol = s.get("grain_tol_deg")
    parts = cut_ready_parts(s) + [
        f"grain: largest off-grain {num(s.get('off_grain_max_deg'), '.2f')} deg "
        f"({'free rotation' if tol is None else f'tolerance {tol:g} deg'}"
        f"{', guessed for ' + ', '.join(s['grain_guessed']) if s.get('grain_guessed') else ''})",
        f"reshape: largest move {num(s.get('reshape_max_move_mm'), '.1f')} mm, area "
        f"{num(s.get('reshape_area_change_max_pct'), '.2f')} %"]
    lines.append(f"  cut-ready     {'; '.join(parts)}")
    lines += [
        f"  nest density  {num(s['nest_density'] and 100 * s['nest_density'], '.1f')}%",
        f"  pieces cut    {s['pieces_cut']}/{s['pieces_total']}"
        + (f" in {len(s['bites'])} bites" if s.get("bites") else ""),
        *seam_lines(s),
        f"  time          {s['seconds']:.1f} s",
        f"  files in      {out}/ (report.json has everything)",
    ]
    if missing:
        lines.append(f"  not produced: {', '.join(missing)}")
    print("\n".join(lines))
