"""The synthetic camera: geometry that agrees with OpenCV, truth that is exact, and the
interface of the real camera."""

from __future__ import annotations

import json
import math

import cv2
import numpy as np
import pytest

from simulators.camera import (
    Board,
    CameraModel,
    Imaging,
    Pose,
    Sheet,
    SyntheticCamera,
    calibration_poses,
    render_rectified,
)
from simulators.classics import classic_print
from simulators.fabric import random_print
from solver.wallpaper import Wallpaper
from station.cli import main as station

SMALL = (480, 360)


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.corrcoef(a.astype(float).ravel(), b.astype(float).ravel())[0, 1])


@pytest.fixture(scope="module")
def sheet() -> Sheet:
    return Sheet(random_print("p31m", 30.0, seed=3), size=(500.0, 380.0), rotation=9.0,
                 shift=(40.0, -25.0))


def test_frame_shows_the_print_where_the_truth_says(sheet):
    with SyntheticCamera(sheet, camera=CameraModel.default(SMALL), seed=1) as cam:
        frame = cam.read()
        truth = cam.truth
    assert frame.shape == (SMALL[1], SMALL[0], 3) and frame.dtype == np.uint8
    region, s = (60.0, 30.0, 300.0, 230.0), 1.5
    seen = truth.rectify(frame, region, s)
    ideal = render_rectified(sheet, region, s)
    assert _corr(seen, ideal) > 0.85
    # negative control: half a repeat off, the same comparison fails
    off = render_rectified(sheet, (75.0, 30.0, 315.0, 230.0), s)
    assert _corr(seen, off) < 0.5
    # the truth's wallpaper is the print moved onto the table
    wp = truth.wallpaper
    expected = sheet.print.truth.moved(math.radians(9.0), (40.0, -25.0))
    assert np.allclose(wp.basis, expected.basis) and np.allclose(wp.origin, expected.origin)
    assert truth.sheet["rigid"] is True


def test_homography_is_the_undistorted_projection(sheet):
    cam = SyntheticCamera(sheet, camera=CameraModel.default(SMALL),
                          poses=[Pose.overhead((250, 180), 700, tilt_deg=20,
                                               tilt_azimuth_deg=40, yaw_deg=15)])
    cam.read()
    t = cam.truth
    pts = np.random.default_rng(0).uniform([-200, -200], [700, 600], (400, 2))
    distorted = t.table_to_image(pts)
    keep = np.all((distorted >= 0) & (distorted < SMALL), axis=1)
    pts, distorted = pts[keep], distorted[keep]
    assert len(pts) > 30
    und = cv2.undistortPoints(distorted.reshape(-1, 1, 2), t.camera.K, t.camera.dist,
                              P=t.camera.K).reshape(-1, 2)
    h = np.column_stack([pts, np.ones(len(pts))]) @ t.homography.T
    assert np.allclose(h[:, :2] / h[:, 2:], und, atol=0.02)
    # the lens really distorts: without the model the points would be off by pixels
    assert np.abs(distorted - und).max() > 1.0


def test_charuco_corners_are_found_where_the_truth_puts_them():
    board = Board(shift=(100.0, 80.0), rotation=-8.0)
    poses = calibration_poses(board, 3, camera=CameraModel.default(SMALL), seed=4)
    cam = SyntheticCamera(board=board, camera=CameraModel.default(SMALL), poses=poses, seed=2)
    detector = cv2.aruco.CharucoDetector(board.cv_board())
    for _ in poses:
        frame = cam.read()
        t = cam.truth
        corners, ids, _, _ = detector.detectBoard(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY))
        # views push the board into the frame corners: markers cut by the frame edge
        # hide some corners that are themselves in view
        assert ids is not None and len(ids) >= max(10, 0.6 * len(t.charuco_ids))
        where = dict(zip(t.charuco_ids.tolist(), t.charuco_image))
        err = [np.hypot(*(c - where[i])) for c, i in zip(corners.reshape(-1, 2), ids.ravel())]
        assert np.median(err) < 0.35 and max(err) < 1.0


def test_calibration_from_synthetic_views_recovers_the_camera():
    board = Board()
    model = CameraModel.default((640, 480))
    poses = calibration_poses(board, 7, camera=model, seed=1)
    cam = SyntheticCamera(board=board, camera=model, poses=poses, seed=3)
    cvb = board.cv_board()
    detector = cv2.aruco.CharucoDetector(cvb)
    obj, img = [], []
    for _ in poses:
        corners, ids, _, _ = detector.detectBoard(cv2.cvtColor(cam.read(), cv2.COLOR_BGR2GRAY))
        o, i = cvb.matchImagePoints(corners, ids)
        obj.append(o)
        img.append(i)
    rms, k, dist, _, _ = cv2.calibrateCamera(obj, img, model.resolution, None, None,
                                             flags=cv2.CALIB_FIX_K3)
    assert rms < 0.3
    assert k[0, 0] == pytest.approx(model.K[0, 0], rel=0.01)
    assert k[1, 1] == pytest.approx(model.K[1, 1], rel=0.01)
    assert np.hypot(k[0, 2] - model.K[0, 2], k[1, 2] - model.K[1, 2]) < 4.0
    assert dist[0, 0] == pytest.approx(model.dist[0], abs=0.02)  # k1: the barrel
    # near the frame's corner the found model undistorts where the true one does
    near_corner = np.array([[[48.0, 36.0]]])
    a = cv2.undistortPoints(near_corner, model.K, model.dist, P=model.K)
    b = cv2.undistortPoints(near_corner, k, dist, P=model.K)
    assert np.hypot(*(a - b).ravel()) < 3.0


def test_skew_bow_and_fold_move_the_fabric_as_specified():
    p = classic_print("gingham", 20.0)
    flat = Sheet(p, size=(400.0, 300.0), rotation=20.0, shift=(10.0, 5.0), skew=3.0)
    pts = np.random.default_rng(1).uniform(0, 300, (50, 2))
    aff = flat.fabric_to_table_affine()
    table = pts @ aff[:2, :2].T + aff[:2, 2]
    fx, fy = flat.table_to_fabric(table[:, 0], table[:, 1])
    assert np.allclose(np.column_stack([fx, fy]), pts, atol=1e-9)
    # a weft line (constant fabric y) runs at the skew angle in the sheet's frame
    sheet_x = np.array([1.0, 0.0])
    weft = aff[:2, :2] @ sheet_x
    assert math.degrees(math.atan2(weft[1], weft[0])) == pytest.approx(20.0 + 3.0, abs=1e-6)

    bowed = Sheet(p, size=(400.0, 300.0), bow=12.0)
    x = np.array([0.0, 200.0, 400.0])
    _, fy = bowed.table_to_fabric(x, np.full(3, 100.0))
    assert np.allclose(fy, [100.0, 88.0, 100.0])  # the weft sags 12 mm at mid-width

    folded = Sheet(p, size=(400.0, 300.0), fold=(150.0, 30.0, 4.0))
    fx, _ = folded.table_to_fabric(np.array([100.0, 200.0]), np.zeros(2))
    assert np.allclose(fx, [100.0, 230.0], atol=1e-6)  # 30 mm hidden in the fold
    frame = SyntheticCamera(folded, camera=CameraModel.default(SMALL)).read()
    assert frame.shape == (SMALL[1], SMALL[0], 3)


def test_light_noise_and_jpeg_are_applied_and_seeded(sheet):
    model = CameraModel.default(SMALL)
    ideal = SyntheticCamera(sheet, camera=model, imaging=Imaging.ideal()).read()
    lit = SyntheticCamera(sheet, camera=model, imaging=Imaging(
        light_ramp=(0.0, 0.0), vignetting=0.4, blur=0.0, noise=0.0, jpeg_quality=None)).read()
    ratio = lit.astype(float) / np.maximum(ideal.astype(float), 1.0)
    assert ratio[170:190, 230:250].mean() > 0.97  # centre untouched
    assert ratio[:20, :20].mean() < 0.85  # corners dark
    plain = Imaging(light_ramp=(0.0, 0.0), vignetting=0.0, blur=0.0, noise=3.0,
                    jpeg_quality=None)
    n1 = SyntheticCamera(sheet, camera=model, imaging=plain, seed=1).read().astype(float)
    n2 = SyntheticCamera(sheet, camera=model, imaging=plain, seed=2).read().astype(float)
    sd = (n1 - n2).std(axis=(0, 1)) / math.sqrt(2)
    assert np.all((sd > 1.5) & (sd < 4.2))  # every channel: read + shot noise of 3 at grey
    a = SyntheticCamera(sheet, camera=model, seed=5).read()
    b = SyntheticCamera(sheet, camera=model, seed=5).read()
    c = SyntheticCamera(sheet, camera=model, seed=6).read()
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)
    assert 0.5 < np.abs(a.astype(float) - c.astype(float)).mean() < 6.0


def test_same_interface_as_the_real_camera(sheet):
    cam = SyntheticCamera(sheet, resolution=(320, 240))
    assert cam.resolution == (320, 240) and cam.truth is None
    with cam:
        cam.read()
        assert cam.truth.index == 0
        cam.read()
        assert cam.truth.index == 1
    with pytest.raises(RuntimeError, match="closed"):
        cam.read()
    with pytest.raises(ValueError, match="needs a fabric sheet or a board"):
        SyntheticCamera()
    with pytest.raises(ValueError, match="resolution"):
        CameraModel.default((9000, 100))


def test_simulate_camera_command(tmp_path):
    frame, truth = tmp_path / "f.png", tmp_path / "t.json"
    assert station(["simulate-camera", "--group", "p4g", "--repeat", "35", "--rotation", "12",
                    "--shift", "30", "20", "--resolution", "320", "240", "--seed", "2",
                    "-o", str(frame), "--truth", str(truth)]) == 0
    d = json.loads(truth.read_text())
    wp = Wallpaper.load(truth)  # top-level FABRIC.json fields, in table mm
    assert wp.group == "p4g"
    assert np.hypot(*wp.w1) == pytest.approx(35.0)
    assert cv2.imread(str(frame)).shape == (240, 320, 3)
    assert np.array(d["camera_matrix"]).shape == (3, 3) and len(d["dist_coeffs"]) == 5

    out = tmp_path / "cal.png"
    assert station(["simulate-camera", "--charuco", "--views", "2", "--resolution", "320",
                    "240", "-o", str(out), "--truth", str(truth)]) == 0
    d = json.loads(truth.read_text())
    assert len(d["frames"]) == 2 and (tmp_path / "cal_001.png").exists()
    assert len(d["frames"][0]["charuco"]["ids"]) > 10
    assert station(["simulate-camera", "--views", "3", "-o", str(out)]) == 2


def test_each_pixel_is_filtered_for_its_own_footprint():
    """A tilted view sees the fabric at several scales: near pixels get the fine texture,
    far ones the coarse, so neither side is blurred or aliased by a single filter."""
    from simulators.camera.render import _sample_print

    p = random_print("p2", 10.0, seed=1)
    y, x = np.mgrid[0:40, 0:80].astype(np.float32) * np.float32(0.7)
    foot = np.where(np.arange(80) < 40, 0.4, 3.0).astype(np.float32)[None, :].repeat(40, 0)
    out = _sample_print(p, x, y, foot)
    assert np.allclose(out[:, :40], p.colour_at(x, y, 0.4)[:, :40], atol=1e-5)
    assert np.allclose(out[:, 40:], p.colour_at(x, y, 3.0)[:, 40:], atol=1e-5)
    # the coarse filter really is coarser: less contrast left in the texture
    assert p.colour_at(x, y, 3.0).std() < 0.8 * p.colour_at(x, y, 0.4).std()


def _sample(frame: np.ndarray, truth, table_xy: np.ndarray) -> np.ndarray:
    """Frame colours at table points, through the true camera."""
    px = truth.table_to_image(table_xy).astype(np.float32)
    return cv2.remap(frame, px[:, :1], px[:, 1:], cv2.INTER_LINEAR)[:, 0].astype(float)


def test_truth_lattice_holds_in_the_camera_frame():
    """Every operation of the truth's group, applied in table mm, maps the photographed
    print onto itself; an isometry outside the group does not."""
    sheet = Sheet(random_print("p4", 40.0, seed=2), size=(520.0, 400.0), rotation=-14.0,
                  shift=(60.0, 40.0))
    cam = SyntheticCamera(sheet, camera=CameraModel.default((640, 480)),
                          poses=[Pose.overhead((300, 230), 620, tilt_deg=15, yaw_deg=5)],
                          seed=3)
    frame = cam.read()
    wp = cam.truth.wallpaper
    rng = np.random.default_rng(0)
    pts = rng.uniform([180, 140], [420, 330], (3000, 2))
    base = _sample(frame, cam.truth, pts)
    for op in wp.cartesian_ops():
        moved = pts @ op[:2, :2].T + op[:2, 2]
        moved -= (moved - pts) - wp.lattice_residual(moved - pts)  # stay near pts
        assert _corr(base, _sample(frame, cam.truth, moved)) > 0.9
    mirror = Wallpaper("p4m", wp.w1, wp.w2, wp.origin).cartesian_ops()[-1]
    moved = pts @ mirror[:2, :2].T + mirror[:2, 2]
    moved -= (moved - pts) - wp.lattice_residual(moved - pts)
    assert _corr(base, _sample(frame, cam.truth, moved)) < 0.6


def test_skewed_sheet_follows_the_affine_lattice():
    """With weft skew the print's true repeat on the table is ``lattice_affine``; the
    rigid lattice is off by the skew over the sheet."""
    sheet = Sheet(classic_print("gingham", 30.0), size=(700.0, 500.0), rotation=6.0,
                  shift=(20.0, 10.0), skew=5.0)
    cam = SyntheticCamera(sheet, camera=CameraModel.default((640, 480)), seed=1)
    frame = cam.read()
    aff = cam.truth.lattice_affine
    assert cam.truth.sheet["rigid"] is False
    pts = np.random.default_rng(1).uniform([150, 120], [450, 330], (3000, 2))
    base = _sample(frame, cam.truth, pts)
    step = 4 * np.asarray(aff["w1"])  # four repeats along the weft
    assert _corr(base, _sample(frame, cam.truth, pts + step)) > 0.9
    rigid = 4 * cam.truth.wallpaper.w1  # 10 mm off after 120 mm
    assert _corr(base, _sample(frame, cam.truth, pts + rigid)) < 0.5


def test_endless_sheet_fills_the_view_and_reports_no_size():
    """The module documents size=None as a sheet with no edge; its truth must say so."""
    endless = Sheet(random_print("p4", 30.0, seed=5), size=None)
    with SyntheticCamera(endless, camera=CameraModel.default(SMALL), seed=4) as cam:
        frame = cam.read()
        truth = cam.truth
    assert truth.sheet["size"] is None
    # No table shows: every part of the frame carries the print's contrast.
    grey = frame.mean(axis=2)
    h, w = grey.shape
    tiles = grey[: h // 4 * 4, : w // 4 * 4].reshape(4, h // 4, 4, w // 4).std(axis=(1, 3))
    assert tiles.min() > 5.0
