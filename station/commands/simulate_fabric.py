"""`station simulate-fabric`: render a print of known symmetry, with its ground truth.

The image is a flat, top-down picture of the fabric (no camera); TRUTH.json holds the
FABRIC.json fields (group, w1, w2, origin, units) in the image's millimetres, so it can
be passed as ``--fabric`` wherever a measured print is expected.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import cv2

from simulators.classics import CLASSIC_GROUPS, CLASSICS, classic_print
from simulators.fabric import Print, random_print, render_print
from solver.wallpaper import GROUP_NAMES
from station.errors import UserError
from untrusted.limits import MAX_REPEAT_MM, MIN_REPEAT_MM


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "simulate-fabric", help="render a print of a chosen wallpaper group, with its truth",
        description="Render a random print of a wallpaper group (or a textile classic) as "
        "a flat image, and write its exact lattice and origin as FABRIC.json fields. "
        "Pixel (col, row) is centred on (col, row) * mm-per-px millimetres.")
    add_print_arguments(p)
    p.add_argument("--rotation", type=float, default=0.0, metavar="DEG",
                   help="turn the lattice by DEG degrees (x towards y)")
    p.add_argument("--origin", nargs=2, type=float, metavar=("X", "Y"),
                   help="where the cell's symmetry origin lies, mm (default: random)")
    p.add_argument("--size", nargs=2, type=float, metavar=("W", "H"), default=(200.0, 150.0),
                   help="fabric area shown, mm (default 200 150)")
    p.add_argument("--mm-per-px", type=float, default=0.25, metavar="S",
                   help="millimetres per pixel (default 0.25)")
    p.add_argument("-o", "--output", required=True, metavar="IMAGE.png")
    p.add_argument("--truth", metavar="TRUTH.json", help="write the ground truth here")
    p.add_argument("--json", action="store_true", help="print the truth as JSON on stdout")
    p.set_defaults(func=run)


def add_print_arguments(p: argparse.ArgumentParser) -> None:
    """Options that choose a print (shared with `station simulate-camera`)."""
    which = p.add_mutually_exclusive_group()
    which.add_argument("--group", choices=GROUP_NAMES, metavar="GROUP",
                       help="wallpaper group of a random print: " + ", ".join(GROUP_NAMES))
    which.add_argument("--classic", choices=CLASSICS, metavar="NAME",
                       help="textile classic: " + ", ".join(
                           f"{k} ({v})" for k, v in CLASSIC_GROUPS.items()))
    p.add_argument("--repeat", type=float, default=40.0, metavar="MM",
                   help="length of the first lattice vector w1, mm (default 40)")
    p.add_argument("--seed", type=int, default=0, help="random seed (motif, lattice shape)")


def make_print(args: argparse.Namespace, *, rotation: float = 0.0,
               origin: tuple[float, float] | None = None) -> Print:
    if not MIN_REPEAT_MM <= args.repeat <= MAX_REPEAT_MM:  # the field's repeats; refuses NaN
        raise UserError(f"--repeat must be {MIN_REPEAT_MM:g} to {MAX_REPEAT_MM:g} mm, "
                        f"got {args.repeat}")
    if args.classic:
        return classic_print(args.classic, args.repeat, rotation=rotation,
                             origin=origin if origin is not None else (0.0, 0.0))
    return random_print(args.group or "p4m", args.repeat, rotation=rotation, origin=origin,
                        seed=args.seed)


def write_image(path: str, img) -> None:
    out = Path(path)
    if not out.parent.is_dir():
        raise UserError(f"{out}: directory {out.parent} does not exist")
    try:
        ok = cv2.imwrite(str(out), img)
    except cv2.error:
        ok = False
    if not ok:
        raise UserError(f"{out}: cannot write an image there (use .png, .jpg or .tif)")


def write_truth(path: str | None, truth: dict[str, Any], as_json: bool) -> None:
    text = json.dumps(truth, indent=2)
    if path:
        try:
            Path(path).write_text(text + "\n")
        except OSError as exc:
            raise UserError(f"{path}: cannot write the truth ({exc.strerror})") from None
    if as_json:
        print(json.dumps(truth))


def run(args: argparse.Namespace) -> int:
    w, h = args.size
    if w <= 0 or h <= 0:
        raise UserError(f"--size must be positive, got {w} {h}")
    if args.mm_per_px <= 0:
        raise UserError(f"--mm-per-px must be positive, got {args.mm_per_px}")
    p = make_print(args, rotation=args.rotation,
                   origin=tuple(args.origin) if args.origin else None)
    print(f"simulate-fabric: rendering {p.name} ({w:g} x {h:g} mm at {args.mm_per_px:g} mm/px)",
          file=sys.stderr)
    img = render_print(p, (w, h), args.mm_per_px)
    write_image(args.output, img)
    truth = p.truth_dict()
    truth.update({"mm_per_px": args.mm_per_px, "image_size_px": [img.shape[1], img.shape[0]],
                  "pixel_convention": "pixel (col, row) is centred on (col, row) * mm_per_px mm",
                  "image": str(args.output)})
    write_truth(args.truth, truth, args.json)
    return 0
