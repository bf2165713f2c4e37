"""`station calibrate`: camera intrinsics and the table plane from ChArUco board views.

The views come from a folder of images or from the camera; `station simulate-calibration`
(`station.commands.simulate_calibration`) renders them with the synthetic camera and
shares the rest from here.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from station.errors import UserError
from untrusted import read_image
from vision.calibration import BoardSpec, Calibration
from vision.camera import CameraError, open_camera

_IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff"}

MAX_VIEWS = 200  # OpenCV's calibration gains nothing beyond a few dozen views

#: a printed ChArUco board has far fewer: 7 x 5 is usual, 20 x 15 is already fine
MAX_BOARD_SQUARES = 50


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "calibrate", help="calibrate the camera to the table with a ChArUco board",
        description="Compute the camera's intrinsics and lens distortion from views of a "
        "ChArUco board held in varied poses, and the table plane's map to machine mm from "
        "one view of the board lying flat on the table. Views come from a folder of "
        "images (the table view is TABLE, or the folder's last image in name order) or "
        "from the camera (--camera); `station simulate-calibration` renders them.")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--images", metavar="DIR", help="folder of board views")
    src.add_argument("--camera", metavar="SOURCE",
                     help="camera: device index, video file or GStreamer pipeline")
    p.add_argument("--table", metavar="IMAGE",
                   help="view of the board lying on the table (with --images)")
    add_board_arguments(p, views="views to take from the camera (default 12)")
    p.set_defaults(func=run)


def add_board_arguments(p: argparse.ArgumentParser, *, views: str) -> None:
    """The board, the number of views and the output: shared with simulate-calibration."""
    p.add_argument("--views", type=int, default=12, help=views)
    p.add_argument("--squares", type=int, nargs=2, default=(7, 5), metavar=("COLS", "ROWS"))
    p.add_argument("--square-mm", type=float, default=30.0)
    p.add_argument("--marker-mm", type=float, default=22.0)
    p.add_argument("--dictionary", default="DICT_5X5_100")
    p.add_argument("--board-origin", type=float, nargs=2, default=(0.0, 0.0),
                   metavar=("X", "Y"), help="machine mm of the board's corner (0, 0)")
    p.add_argument("--board-rotation", type=float, default=0.0, metavar="DEG",
                   help="turn of the board's x axis against the machine's x axis")
    p.add_argument("-o", "--output", default="calibration.json", metavar="CAL.json")
    p.add_argument("--json", action="store_true", help="print one JSON summary object")


def board_spec(args: argparse.Namespace) -> BoardSpec:
    """The board and the number of views, checked before any view is taken or rendered."""
    if not all(2 <= n <= MAX_BOARD_SQUARES for n in args.squares):
        # 100000 x 100000 squares allocated past 6 GB before anything was said
        raise UserError(f"--squares must be 2 to {MAX_BOARD_SQUARES} columns and rows, got "
                        f"{args.squares[0]} {args.squares[1]}")
    try:
        spec = BoardSpec(tuple(args.squares), args.square_mm, args.marker_mm, args.dictionary)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    if not 2 <= args.views <= MAX_VIEWS:
        raise UserError(f"--views must be 2 to {MAX_VIEWS}")
    return spec


def run(args: argparse.Namespace) -> int:
    spec = board_spec(args)
    if args.images:
        views, table = _folder_views(Path(args.images), args.table)
    else:
        views, table = _camera_views(args.camera, args.views)
    return calibrate_and_report(args, views, table, spec)


def _folder_views(folder: Path, table: str | None) -> tuple[list[np.ndarray], np.ndarray]:
    if not folder.is_dir():
        raise FileNotFoundError(f"{folder}: folder not found")
    files = sorted(f for f in folder.iterdir() if f.suffix.lower() in _IMAGE_SUFFIXES)
    if table:
        table_path = Path(table)
        files = [f for f in files if f.resolve() != table_path.resolve()]
    elif files:
        table_path = files.pop()
    else:
        raise UserError(f"{folder}: no images")
    views = [read_image(f) for f in files]
    return views, read_image(table_path)


def _camera_views(source: str, n: int) -> tuple[list[np.ndarray], np.ndarray]:
    """``n`` views of the board held by the operator, then one lying on the table."""
    views = []
    try:
        with open_camera(source, average=2) as cam:
            for k in range(n):
                input(f"view {k + 1}/{n}: hold the board in a new pose, Enter ")
                views.append(cam.read())
            input("lay the board flat on the table at its set position, Enter ")
            table = cam.read()
    except CameraError as exc:  # the device, not the program: one line, exit 2
        raise UserError(str(exc)) from None
    return views, table


def calibrate_and_report(args: argparse.Namespace, views: list[np.ndarray], table: np.ndarray,
                         spec: BoardSpec) -> int:
    """Calibrate from the views, write ``args.output`` and say how well it fits."""
    print(f"calibrating from {len(views)} views", file=sys.stderr)
    cal = Calibration.from_views(views, table, spec, board_origin=tuple(args.board_origin),
                                 board_rotation=args.board_rotation)
    cal.save(args.output)
    summary = {"output": str(args.output), "views": cal.views,
               "focal_px": round(cal.focal_px, 3),
               "reprojection_rms_px": round(cal.reprojection_rms_px, 4),
               "table_rms_mm": round(cal.table_rms_mm, 4),
               "mm_per_px": round(cal.mm_per_px(), 5)}
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"wrote {args.output}: {cal.views} views, reprojection RMS "
              f"{cal.reprojection_rms_px:.3f} px, table RMS {cal.table_rms_mm:.3f} mm, "
              f"{cal.mm_per_px():.4f} mm/px at the centre")
    return 0
