"""A synthetic camera over the cutting table, with exact ground truth for every frame.

The scene is the table plane (z = 0, millimetres) with a fabric sheet lying on it and,
optionally, a ChArUco board for calibration. Frames are rendered by *inverse mapping*:
each image pixel is undistorted with OpenCV's own model (``cv2.undistortPoints``, iterated
to convergence, so the simulator and calibration share one definition of k1, k2, p1, p2,
k3), cast as a ray, intersected with the table, carried into fabric or board coordinates
and looked up in the band-limited print texture. The pixel -> table map is computed on a
coarse grid and interpolated (it is smooth), so a 4000x3000 frame takes about a second.

Modules by job: `lens` (the camera model, poses and calibration views), `scene` (the sheet
and the board on the table), `render` (colours of table points, rectified views), `sensor`
(light, blur, noise and JPEG), `truth` (what is known exactly about a frame) and `synthetic`
(the camera that puts them together).
"""

from __future__ import annotations

from simulators.camera.lens import CameraModel, Pose, calibration_poses
from simulators.camera.render import render_rectified
from simulators.camera.scene import Board, Sheet
from simulators.camera.sensor import Imaging
from simulators.camera.synthetic import SyntheticCamera
from simulators.camera.truth import FrameTruth

__all__ = [
    "Board",
    "CameraModel",
    "FrameTruth",
    "Imaging",
    "Pose",
    "Sheet",
    "SyntheticCamera",
    "calibration_poses",
    "render_rectified",
]
