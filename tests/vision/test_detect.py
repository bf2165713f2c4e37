"""End to end: the simulated camera photographs a print; rectify, detect, compare in mm."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from simulators.camera import CameraModel, Sheet, SyntheticCamera
from simulators.fabric import random_print
from station.cli import main
from vision.calibration import Calibration
from vision.pipeline import detect_fabric
from vision.rectify import rectify


def _true_calibration(sim: SyntheticCamera) -> Calibration:
    """The simulator's exact camera and table plane (calibration itself is tested in
    test_calibration; here the detection is under test)."""
    hom = np.linalg.inv(sim.truth.homography)
    return Calibration(sim.camera.K, sim.camera.dist, sim.camera.resolution,
                       homography=hom / hom[2, 2])


@pytest.mark.parametrize(("group", "seed", "rotation"),
                         [("p4g", 3, 20.0), ("pmg", 4, 57.0), ("p31m", 5, 8.0),
                          ("cm", 6, 71.0)])
def test_photographed_print_lattice_and_origin_in_mm(group, seed, rotation, vt):
    p = random_print(group, 40.0, rotation=rotation, seed=seed)
    sim = SyntheticCamera(Sheet(p, size=(700, 500)), camera=CameraModel.default((960, 720)),
                          seed=seed)
    frame = sim.read()
    img, region, s = rectify(frame, _true_calibration(sim), region=(60, 60, 640, 440))
    det = detect_fabric(img, mm_per_px=s, offset=region[:2])
    truth = sim.truth.wallpaper
    wp = det.wallpaper
    assert wp is not None and wp.group == group
    assert vt.lattice_error(wp.basis, truth.basis) < 0.005
    assert vt.symmetry_error(wp, truth) < 0.01
    assert det.distortion.warning is None


@pytest.fixture(scope="module")
def print_png(tmp_path_factory):
    from simulators.fabric import render_print
    path = tmp_path_factory.mktemp("detect") / "p6.png"
    p = random_print("p6", 30.0, rotation=15.0, seed=2)
    cv2.imwrite(str(path), render_print(p, (300, 240), 0.5))
    return path, p.wallpaper


def test_cli_json_fabric_file_and_picture(print_png, tmp_path, capsys, vt):
    path, truth = print_png
    out, png = tmp_path / "fabric.json", tmp_path / "overlay.png"
    rc = main(["detect", str(path), "--mm-per-px", "0.5", "-o", str(out), "--png", str(png),
               "--json"])
    assert rc == 0
    line = json.loads(capsys.readouterr().out)
    assert line["group"] == "p6" and line["confidence"] > 0.9 and line["seconds"] > 0
    fabric = json.loads(out.read_text())
    assert fabric["units"] == "mm" and "distortion" in fabric and "confidence" in fabric
    from solver.wallpaper import Wallpaper
    wp = Wallpaper.from_dict(fabric)
    assert vt.lattice_error(wp.basis, truth.basis) < 0.005
    assert vt.symmetry_error(wp, truth) < 0.01
    pic = cv2.imread(str(png))
    assert pic is not None and pic.shape[:2] == (480, 600)


def test_cli_no_lattice_prints_null_group(tmp_path, capsys):
    rng = np.random.default_rng(0)
    path = tmp_path / "noise.png"
    cv2.imwrite(str(path), rng.integers(0, 255, (200, 260, 3), dtype=np.uint8))
    assert main(["detect", str(path), "--mm-per-px", "1", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["group"] is None


def test_cli_errors_name_the_file(tmp_path, capsys):
    assert main(["detect", str(tmp_path / "none.png"), "--mm-per-px", "1"]) == 2
    assert "none.png: image not found" in capsys.readouterr().err
    bad = tmp_path / "bad.png"
    bad.write_text("not an image")
    assert main(["detect", str(bad), "--mm-per-px", "1"]) == 2
    assert "bad.png: not an image" in capsys.readouterr().err


@pytest.mark.parametrize(("option", "value", "fault"), [
    ("--mm-per-px", "nan", "--mm-per-px must be 0.001 to 100 mm per pixel, got nan"),
    ("--mm-per-px", "1e-300", "--mm-per-px must be 0.001 to 100 mm per pixel"),
    ("--mm-per-px", "inf", "--mm-per-px must be 0.001 to 100 mm per pixel, got inf"),
    ("--min-repeat", "1e300", "--min-repeat must be 0 to 2000 mm"),
])
def test_a_scale_or_repeat_beyond_any_table_is_one_line_before_any_work(tmp_path, capsys,
                                                                        option, value, fault):
    args = ["detect", str(tmp_path / "none.png"), "--mm-per-px", "1", option, value]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert fault in err and err.count("\n") == 1, err
