"""ChArUco calibration on simulated board views; table mapping; rectification."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from simulators.camera import (
    Board,
    CameraModel,
    Pose,
    SyntheticCamera,
    calibration_poses,
    render_rectified,
)
from vision.calibration import BoardSpec, Calibration, detect_board
from vision.rectify import rectify, visible_region

BOARD = dict(squares=(9, 6), square_mm=30.0, marker_mm=22.0)


@pytest.fixture(scope="module")
def session():
    """Ten varied board views plus one of the board lying on the table (shifted, turned)."""
    cam = CameraModel.default((960, 720))
    board = Board(**BOARD)
    poses = calibration_poses(board, 10, camera=cam, seed=1)
    views = [SyntheticCamera(board=board, camera=cam, poses=[p], seed=i).read()
             for i, p in enumerate(poses)]
    table_board = Board(**BOARD, shift=(100.0, 50.0), rotation=3.0)
    table = SyntheticCamera(board=table_board, camera=cam, seed=5, poses=[
        Pose.overhead((235.0, 140.0), 500.0, tilt_deg=8.0, tilt_azimuth_deg=30.0)])
    table_view = table.read()
    cal = Calibration.from_views(views, table_view, BoardSpec(**BOARD),
                                 board_origin=(100.0, 50.0), board_rotation=3.0)
    return cam, cal, table


def test_focal_length_within_one_percent(session):
    cam, cal, _ = session
    assert cal.views >= 8
    assert cal.focal_px == pytest.approx(cam.K[0, 0], rel=0.01)
    assert cal.camera_matrix[1, 1] == pytest.approx(cam.K[1, 1], rel=0.01)
    assert cal.reprojection_rms_px < 0.5


def test_table_points_within_half_a_millimetre(session):
    _, cal, table = session
    gx, gy = np.meshgrid(np.linspace(40, 430, 9), np.linspace(-40, 320, 7))
    grid = np.column_stack([gx.ravel(), gy.ravel()])
    px = table.truth.table_to_image(grid)
    w, h = cal.resolution
    seen = np.all((px >= 0) & (px <= [w - 1, h - 1]), axis=1)
    assert seen.sum() > 40
    err = np.hypot(*(cal.image_to_table(px[seen]) - grid[seen]).T)
    assert err.max() < 0.5
    back = cal.table_to_image(grid[seen])
    assert np.abs(back - px[seen]).max() < 0.3
    assert cal.table_rms_mm < 0.2


def test_save_and_load_round_trip(session, tmp_path):
    _, cal, _ = session
    path = tmp_path / "cal.json"
    cal.save(path)
    again = Calibration.load(path)
    assert np.allclose(again.camera_matrix, cal.camera_matrix)
    assert np.allclose(again.homography, cal.homography)
    assert again.board == cal.board
    pts = np.array([[100.0, 200.0], [500.0, 300.0]])
    assert np.allclose(again.image_to_table(pts), cal.image_to_table(pts))


def test_bad_calibration_files_name_the_fault(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(ValueError, match="bad.json: not valid JSON"):
        Calibration.load(bad)
    bad.write_text(json.dumps({"dist_coeffs": [0] * 5, "resolution": [10, 10]}))
    with pytest.raises(ValueError, match="camera_matrix"):
        Calibration.load(bad)
    with pytest.raises(FileNotFoundError):
        Calibration.load(tmp_path / "missing.json")


GOOD = {"camera_matrix": [[800, 0, 320], [0, 800, 240], [0, 0, 1]],
        "dist_coeffs": [0.0] * 5, "resolution": [480, 360],
        "homography_undistorted_px_to_mm": [[0.25, 0, 0], [0, 0.25, 0], [0, 0, 1]]}


@pytest.mark.parametrize("change,match", [
    # blamed on the photo before, or an OpenCV assertion (exit 70), or a 16 s rectification
    ({"homography_undistorted_px_to_mm": [[0, 0, 0], [0, 0, 0], [0, 0, 1]]},
     "does not enclose a table region"),
    ({"homography_undistorted_px_to_mm": [[1e-300, 0, 0], [0, 1e-300, 0], [0, 0, 1]]},
     "mm per pixel must be positive"),
    ({"homography_undistorted_px_to_mm": [[1, 0, 0], [0, 1, 0], [1, 1, 1]]},
     "would rectify into"),
    ({"camera_matrix": [[0, 0, 0], [0, 0, 0], [0, 0, 0]]}, "fx, fy > 0"),
    ({"dist_coeffs": [0.0] * 3}, "OpenCV's models take 4, 5, 8, 12 or 14"),
])
def test_calibration_whose_maps_are_no_camera_is_refused(tmp_path, capsys, change, match):
    from station.cli import main

    bad = tmp_path / "cal.json"
    bad.write_text(json.dumps({**GOOD, **change}))
    image = tmp_path / "frame.png"
    cv2.imwrite(str(image), np.full((360, 480, 3), 128, np.uint8))
    assert main(["detect", str(image), "--calibration", str(bad)]) == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert f"{bad}: " in last and match in last, last


def test_no_board_in_a_blank_image():
    ids, px, mm = detect_board(np.full((200, 300, 3), 128, np.uint8), BoardSpec(**BOARD))
    assert len(ids) == 0 and px.shape == (0, 2)


def test_rectified_frame_matches_the_true_top_down_view(session):
    cam, cal, table = session
    frame = table.read()
    region = (120.0, 60.0, 330.0, 200.0)
    img, reg, s = rectify(frame, cal, region=region, mm_per_px=1.0)
    ref = render_rectified(None, region, 1.0, board=table.board)
    # Compare edges of the board picture: misregistration shows as large differences.
    diff = np.abs(img.astype(float) - ref.astype(float)).mean()
    assert img.shape == ref.shape and diff < 25
    vis = visible_region(cal)
    assert vis[0] < 120 and vis[2] > 330


def test_rectify_refuses_a_frame_of_another_size(session):
    _, cal, _ = session
    with pytest.raises(ValueError, match="calibration is for"):
        rectify(np.zeros((10, 10, 3), np.uint8), cal)


def test_cli_calibrate_simulated_and_from_a_folder(tmp_path, capsys):
    import cv2

    from station.cli import main

    out = tmp_path / "cal.json"
    rc = main(["simulate-calibration", "--views", "6", "--squares", "9", "6",
               "-o", str(out), "--json"])
    assert rc == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["views"] >= 5 and summary["reprojection_rms_px"] < 0.5
    cal = Calibration.load(out)
    from simulators.camera import CameraModel
    assert cal.focal_px == pytest.approx(CameraModel.default().K[0, 0], rel=0.02)
    # The same from a folder of saved images (last file = the table view).
    folder = tmp_path / "views"
    folder.mkdir()
    board = Board(**BOARD)
    cam = CameraModel.default((640, 480))
    for i, pose in enumerate(calibration_poses(board, 6, camera=cam, seed=4)):
        frame = SyntheticCamera(board=board, camera=cam, poses=[pose], seed=i).read()
        cv2.imwrite(str(folder / f"view{i:02d}.png"), frame)
    table = SyntheticCamera(board=board, camera=cam, seed=9).read()
    cv2.imwrite(str(folder / "zz_table.png"), table)
    out2 = tmp_path / "cal2.json"
    assert main(["calibrate", "--images", str(folder), "--squares", "9", "6",
                 "-o", str(out2)]) == 0
    assert Calibration.load(out2).focal_px == pytest.approx(cam.K[0, 0], rel=0.02)
    assert main(["calibrate", "--images", str(tmp_path / "nope")]) == 2


def test_a_board_beyond_any_print_is_refused_before_rendering(tmp_path, capsys):
    """--squares 100000 100000 allocated past 6 GB before anything was said."""
    from station.cli import main

    assert main(["simulate-calibration", "--squares", "100000", "100000",
                 "-o", str(tmp_path / "c.json")]) == 2
    err = capsys.readouterr().err
    assert "--squares must be 2 to 50 columns and rows" in err and err.count("\n") == 1
