"""`station simulate-camera`: a synthetic camera frame of fabric (or a ChArUco board) on
the table, with its ground truth.

TRUTH.json holds the camera matrix, distortion, pose (rvec/tvec, table -> camera), the
table-to-image homography of the undistorted image and, for a print, its lattice and
origin in *table* millimetres as top-level FABRIC.json fields (usable as ``--fabric``).
With skew, bow or a fold those fields are the nominal (rigid) placement and
``sheet.rigid`` is false; ``lattice_affine`` includes the skew.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from simulators.camera import (
    Board,
    CameraModel,
    Imaging,
    Pose,
    Sheet,
    SyntheticCamera,
    calibration_poses,
)
from station.commands.simulate_fabric import (
    add_print_arguments,
    make_print,
    write_image,
    write_truth,
)
from station.errors import UserError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "simulate-camera", help="photograph simulated fabric or a ChArUco board, with truth",
        description="Render what a camera above the cutting table sees: a printed fabric "
        "sheet (turned, shifted, optionally skewed, bowed or folded) or, with --charuco, a "
        "calibration board, through a distorting lens with uneven light, noise, blur and "
        "JPEG compression. Writes the frame and its exact ground truth.")
    add_print_arguments(p)
    p.add_argument("--charuco", action="store_true",
                   help="photograph a ChArUco calibration board instead of fabric")
    p.add_argument("--views", type=int, default=1, metavar="N",
                   help="with --charuco: N calibration views (FRAME_000.png, ...)")
    p.add_argument("--resolution", nargs=2, type=int, default=(1280, 960), metavar=("W", "H"))
    p.add_argument("--hfov", type=float, default=62.0, metavar="DEG",
                   help="horizontal field of view (default 62)")
    p.add_argument("--rotation", type=float, default=0.0, metavar="DEG",
                   help="turn of the fabric (or board) on the table")
    p.add_argument("--shift", nargs=2, type=float, default=(0.0, 0.0), metavar=("X", "Y"),
                   help="table position of the fabric's (board's) corner, mm")
    p.add_argument("--sheet", nargs=2, type=float, default=(900.0, 600.0), metavar=("W", "H"),
                   help="fabric sheet size, mm (default 900 600)")
    p.add_argument("--skew", type=float, default=0.0, metavar="DEG", help="weft skew")
    p.add_argument("--bow", type=float, default=0.0, metavar="MM", help="weft bow at mid-width")
    p.add_argument("--fold", nargs=3, type=float, metavar=("X", "DEPTH", "WIDTH"),
                   help="a fold across the sheet at fabric x = X mm hiding DEPTH mm")
    p.add_argument("--height", type=float, metavar="MM",
                   help="camera height above the table (default: frame the subject)")
    p.add_argument("--tilt", type=float, default=0.0, metavar="DEG",
                   help="camera tilt off the vertical")
    p.add_argument("--noise", type=float, default=2.0, help="sensor noise sd, grey levels")
    p.add_argument("--blur", type=float, default=0.6, help="optical blur sigma, px")
    p.add_argument("--jpeg", type=int, default=92, metavar="Q",
                   help="JPEG quality, 0 for none (default 92)")
    p.add_argument("-o", "--output", required=True, metavar="FRAME.png")
    p.add_argument("--truth", metavar="TRUTH.json", help="write the ground truth here")
    p.add_argument("--json", action="store_true", help="print the truth as JSON on stdout")
    p.set_defaults(func=run)


def _frame_path(path: str, k: int, n: int) -> str:
    if n == 1:
        return path
    p = Path(path)
    return str(p.with_name(f"{p.stem}_{k:03d}{p.suffix}"))


def _camera_and_imaging(args: argparse.Namespace) -> tuple[CameraModel, Imaging]:
    """The lens and the imaging chain, every option checked before anything is rendered."""
    if not 1 <= args.views <= 100:
        raise UserError(f"--views must be 1..100, got {args.views}")
    if args.views > 1 and not args.charuco:
        raise UserError("--views is for --charuco calibration sessions")
    if not 0 <= args.jpeg <= 100:
        raise UserError(f"--jpeg must be 0..100, got {args.jpeg}")
    if not 1 <= args.hfov <= 170:  # also refuses NaN
        raise UserError(f"--hfov must be 1..170 degrees, got {args.hfov}")
    if not (0 <= args.noise <= 255 and 0 <= args.blur <= 50):
        raise UserError(f"--noise must be 0..255 and --blur 0..50, got {args.noise} and "
                        f"{args.blur}")
    try:
        camera = CameraModel.default(tuple(args.resolution), hfov_deg=args.hfov)
    except ValueError as exc:
        raise UserError(f"--resolution: {exc}") from None
    return camera, Imaging(noise=args.noise, blur=args.blur, jpeg_quality=args.jpeg or None)


def run(args: argparse.Namespace) -> int:
    camera, imaging = _camera_and_imaging(args)
    sheet = board = None
    if args.charuco:
        board = Board(rotation=args.rotation, shift=tuple(args.shift))
    else:
        if min(args.sheet) <= 0:
            raise UserError(f"--sheet must be positive, got {args.sheet}")
        sheet = Sheet(make_print(args, origin=(0.0, 0.0) if args.classic else None),
                      size=tuple(args.sheet), rotation=args.rotation, shift=tuple(args.shift),
                      skew=args.skew, bow=args.bow,
                      fold=tuple(args.fold) if args.fold else None)
    poses = None
    if args.views > 1:
        poses = calibration_poses(board, args.views, camera=camera, seed=args.seed)
    cam = SyntheticCamera(sheet, board=board, camera=camera, poses=poses, imaging=imaging,
                          seed=args.seed)
    if poses is None and (args.height or args.tilt):
        if args.height is not None and args.height <= 0:
            raise UserError(f"--height must be positive, got {args.height}")
        above = cam.poses[0].centre  # the default pose looks straight down from here
        cam.poses = [Pose.overhead(above[:2], args.height or -above[2], tilt_deg=args.tilt)]
    frames = []
    with cam:
        for k in range(args.views):
            out = _frame_path(args.output, k, args.views)
            print(f"simulate-camera: frame {k + 1}/{args.views} -> {out}", file=sys.stderr)
            write_image(out, cam.read())
            t = cam.truth.to_dict()
            t["image"] = out
            if cam.truth.wallpaper is not None:
                t = {**cam.truth.wallpaper.to_dict(), **t}  # FABRIC.json fields on top
            frames.append(t)
    write_truth(args.truth, frames[0] if len(frames) == 1 else {"frames": frames}, args.json)
    return 0
