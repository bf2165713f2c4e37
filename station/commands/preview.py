"""`station preview JOB -o OUT.png`: the job's marker on the fabric, seams by mismatch.

The daemon tells where the job's plan lives (over the control socket, like every console
command); the picture is drawn from those files: the rectified photo of the fabric when
the job photographed it, else the lattice of the job's FABRIC.json on plain cloth.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import cv2

from solver.fit import fit_report
from solver.garment import load_garment
from solver.nest.layout import Layout
from solver.placement import Placement
from station.cliargs import add_config_argument, load_config_arg, picture_path
from station.control import ControlError, request
from station.errors import UserError
from station.render import draw_marker, garment_credit


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "preview", help="picture of a job's marker on the fabric",
        description="Draw the job's pieces where they lie on the fabric photo (or the "
        "print's lattice when the job was given a FABRIC.json), seams coloured from green "
        "(matching) to red (20 mm or more off).")
    p.add_argument("job", type=int, metavar="JOB")
    p.add_argument("-o", "--output", required=True, metavar="OUT.png", type=picture_path)
    p.add_argument("--width", type=int, default=1600, help="picture width in pixels")
    add_config_argument(p)
    p.add_argument("--socket", metavar="PATH", help="control socket (default: from the config)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.width < 100:
        raise ValueError(f"--width must be at least 100 pixels, got {args.width}")
    if args.socket:
        sock = Path(args.socket)
    else:
        config = load_config_arg(args)
        sock = config.resolve(config["control"]["socket"])
    try:
        answer = request(sock, "plan", job=args.job)
    except ControlError as exc:
        raise UserError(str(exc)) from None
    plan = answer.get("plan") or {}
    if "layout" not in plan:
        raise UserError(f"job {args.job} has no marker yet (it is {answer['state']})")
    preview(plan, args.output, width_px=args.width)
    print(f"station preview: job {args.job} -> {args.output}", file=sys.stderr)
    return 0


def preview(plan: dict, output: str | Path, *, width_px: int = 1600) -> None:
    """Draw the marker of a planned job (its plan dict) into ``output``."""
    try:
        layout = Layout.load(plan["layout"])
        garment = load_garment(plan["garment"])
        placement = Placement.load(plan["placement"])
    except FileNotFoundError as exc:
        raise UserError(f"the job's files are gone: {exc}") from None
    workdir = Path(plan["layout"]).parent
    photo = cv2.imread(str(workdir / "rectified.png"))
    mm_per_px = 1.0
    camera = workdir / "camera.json"
    if photo is not None and camera.is_file():
        mm_per_px = float(json.loads(camera.read_text())["mm_per_px"])
    else:
        photo = None  # the job was given a FABRIC.json: its lattice on plain cloth
    draw_marker(layout, output, garment=garment, report=fit_report(garment, placement),
                photo=photo, photo_mm_per_px=mm_per_px, width_px=width_px,
                credit=garment_credit(plan["garment"]))
