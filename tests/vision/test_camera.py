"""Camera interface: OpenCV VideoCapture over a real video file, and the synthetic one."""

from __future__ import annotations

import ast
from pathlib import Path

import cv2
import numpy as np
import pytest

import vision
from simulators.camera import Sheet, SyntheticCamera
from simulators.fabric import random_print
from vision.camera import CameraError, SimulatedCamera, VideoCaptureCamera, open_camera


@pytest.fixture
def video(tmp_path):
    """A short MJPG video whose frames are a fixed picture plus frame-to-frame noise."""
    path = tmp_path / "table.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10, (160, 120))
    if not writer.isOpened():
        pytest.skip("this OpenCV build cannot write MJPG video")
    rng = np.random.default_rng(0)
    base = np.zeros((120, 160, 3), np.uint8)
    base[:, 80:] = 200
    for _ in range(8):
        noisy = np.clip(base + rng.normal(0, 30, base.shape), 0, 255).astype(np.uint8)
        writer.write(noisy)
    writer.release()
    return path, base


def test_video_file_frames_and_resolution(video):
    path, base = video
    with VideoCaptureCamera(str(path)) as cam:
        assert cam.resolution == (160, 120)
        frame = cam.read()
        assert frame.shape == (120, 160, 3) and frame.dtype == np.uint8


def test_averaging_cuts_the_noise(video):
    path, base = video
    with VideoCaptureCamera(str(path)) as one:
        err1 = np.abs(one.read().astype(float) - base).mean()
    with VideoCaptureCamera(str(path), average=4) as four:
        err4 = np.abs(four.read().astype(float) - base).mean()
    assert err4 < 0.75 * err1


def test_end_of_video_and_closed_camera_raise(video):
    path, _ = video
    cam = VideoCaptureCamera(str(path), average=8)
    cam.read()
    with pytest.raises(CameraError, match="no frame"):
        cam.read()
    cam.close()
    cam.close()  # idempotent
    with pytest.raises(CameraError, match="closed"):
        cam.read()


def test_missing_source_is_a_clear_error(tmp_path):
    with pytest.raises(CameraError, match="cannot open"):
        VideoCaptureCamera(str(tmp_path / "nope.avi"))
    with pytest.raises(ValueError, match="--simulate"):
        open_camera(None)


def test_synthetic_camera_behind_the_same_interface():
    def factory():
        return SyntheticCamera(Sheet(random_print("p4m", 40.0, seed=1)), resolution=(320, 240))

    with pytest.raises(ValueError, match="sim_factory"):
        open_camera(simulate=True)
    with open_camera(simulate=True, sim_factory=factory, average=2) as cam:
        assert isinstance(cam, SimulatedCamera)
        assert cam.resolution == (320, 240)
        frame = cam.read()
        assert frame.shape == (240, 320, 3)
        assert cam.truth.wallpaper is not None and cam.truth.wallpaper.group == "p4m"


def test_vision_never_imports_the_simulators():
    """The design's arrows run one way: the station hands vision its simulated camera.
    Checked on the source, so an import inside a function counts too."""
    for path in Path(vision.__file__).parent.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            assert not any(n.split(".")[0] == "simulators" for n in names), path.name
