"""`station detect`: the print's lattice, wallpaper group and origin from a photo."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import cv2

from station.cliargs import picture_path
from station.errors import UserError
from untrusted import read_image
from untrusted.limits import MAX_REPEAT_MM
from vision.calibration import Calibration
from vision.pipeline import detect_fabric, draw_overlay
from vision.rectify import rectify


def register(sub) -> None:
    p = sub.add_parser(
        "detect", help="find the print's lattice, wallpaper group and origin in a photo",
        description="Detect the repeat (w1, w2), the wallpaper group and the origin of the "
        "print in IMAGE, in machine millimetres. IMAGE is a camera frame (give "
        "--calibration: it is rectified onto the table first) or a top-down image with "
        "a known pixel size (--mm-per-px).")
    p.add_argument("image", help="photo of the fabric (any format OpenCV reads)")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--calibration", metavar="CAL.json",
                     help="camera calibration from `station calibrate`")
    src.add_argument("--mm-per-px", type=float, metavar="S",
                     help="pixel size of an already top-down image, mm")
    p.add_argument("-o", "--output", metavar="FABRIC.json",
                   help="write the fabric description here")
    p.add_argument("--json", action="store_true",
                   help="print one JSON object: group, w1, w2, origin, confidence, seconds")
    p.add_argument("--png", metavar="OUT.png", type=picture_path,
                   help="write the image with lattice, symmetry elements and distortion grid")
    p.add_argument("--skew-tol", type=float, default=1.0, metavar="DEG",
                   help="warn when the cloth is skewed more than this (default 1 degree)")
    p.add_argument("--bow-tol", type=float, default=3.0, metavar="MM",
                   help="warn when the cloth bows more than this (default 3 mm)")
    p.add_argument("--min-repeat", type=float, default=3.0, metavar="MM",
                   help="shortest repeat of a print; finer ones are the weave and the "
                   "cloth is reported as plain (default 3 mm)")
    p.set_defaults(func=run)


def run(args) -> int:
    # checked before any work: NaN passes "<= 0", and 1e-300 mm per pixel or a 1e300 mm
    # repeat made the detector fail deep inside (exit 70)
    if args.mm_per_px is not None and not 1e-3 <= args.mm_per_px <= 100.0:
        raise UserError(f"--mm-per-px must be 0.001 to 100 mm per pixel, got {args.mm_per_px}")
    if not 0.0 <= args.min_repeat <= MAX_REPEAT_MM:
        raise UserError(f"--min-repeat must be 0 to {MAX_REPEAT_MM:g} mm, got "
                        f"{args.min_repeat}")
    path = Path(args.image)
    image = read_image(path)
    offset = (0.0, 0.0)
    if args.calibration:
        cal = Calibration.load(args.calibration)
        print(f"rectifying {path.name} onto the table", file=sys.stderr)
        try:
            image, region, mm_per_px = rectify(image, cal)
        except ValueError as exc:
            raise UserError(f"{path}: {exc}") from None
        offset = region[:2]
    else:
        mm_per_px = args.mm_per_px
    det = detect_fabric(image, mm_per_px=mm_per_px, offset=offset,
                        skew_tol_deg=args.skew_tol, bow_tol_mm=args.bow_tol,
                        min_repeat_mm=args.min_repeat)
    if det.distortion.warning:
        print(f"station detect: warning: {det.distortion.warning}", file=sys.stderr)
    if det.wallpaper is None:
        print(f"station detect: {det.lattice.message or 'no 2-D lattice'}", file=sys.stderr)
    if args.output:
        Path(args.output).write_text(json.dumps(det.fabric_json(), indent=2) + "\n")
    if args.png:
        if not cv2.imwrite(str(args.png), draw_overlay(image, det)):
            raise UserError(f"{args.png}: cannot write the picture")
    if args.json:
        print(json.dumps(det.summary()))
    elif det.wallpaper is not None:
        wp = det.wallpaper
        print(f"{wp.group} (confidence {det.classification.confidence:.2f}): "
              f"w1 = {wp.w1.round(3).tolist()} mm, w2 = {wp.w2.round(3).tolist()} mm, "
              f"origin = {wp.origin.round(3).tolist()} mm")
    return 0
