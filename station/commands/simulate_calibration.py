"""`station simulate-calibration`: `station calibrate` on views the synthetic camera renders.

A check of the whole calibration chain against a known camera (the simulated camera's
intrinsics are the truth), and the only place a simulated board reaches calibration.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from simulators.camera import Board, SyntheticCamera, calibration_poses
from station.commands.calibrate import add_board_arguments, board_spec, calibrate_and_report
from vision.calibration import BoardSpec


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "simulate-calibration", help="calibrate the synthetic camera from rendered ChArUco views",
        description="Render views of a ChArUco board in varied poses and one lying flat on "
        "the table with the synthetic camera, then calibrate from them as `station "
        "calibrate` does from real ones.")
    add_board_arguments(p, views="views to render (default 12)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    spec = board_spec(args)
    print(f"rendering {args.views} synthetic board views", file=sys.stderr)
    views, table = simulated_views(spec, args.views)
    return calibrate_and_report(args, views, table, spec)


def simulated_views(spec: BoardSpec, n: int) -> tuple[list[np.ndarray], np.ndarray]:
    """``n`` views of the board in calibration poses, then one flat on the table, from above."""
    board = Board(squares=tuple(spec.squares), square_mm=spec.square_mm,
                  marker_mm=spec.marker_mm, dictionary=spec.dictionary)
    poses = calibration_poses(board, n, seed=1)
    with SyntheticCamera(board=board, poses=poses, seed=2) as sim:
        views = [sim.read() for _ in poses]
    with SyntheticCamera(board=board, seed=3) as sim:
        table = sim.read()
    return views, table
