"""The camera's lens and where it stands: pinhole intrinsics with OpenCV's distortion, poses,
and the varied views of a calibration session.

Frames: the table frame has x and y on the table and z pointing *into* the table, so a
camera straight above it with ``rvec = 0`` sees table x to the right and table y down
(OpenCV's calibration-board convention). Poses are table -> camera (``X_cam = R X + t``),
exactly what ``cv2.solvePnP`` and ``cv2.calibrateCamera`` return for a board lying at
z = 0.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from simulators.camera.scene import Board, rot2


@dataclass(frozen=True)
class CameraModel:
    """Pinhole intrinsics and OpenCV distortion ``(k1, k2, p1, p2, k3)``."""

    K: np.ndarray
    dist: np.ndarray
    resolution: tuple[int, int]  # (width, height) px

    @classmethod
    def default(cls, resolution: tuple[int, int] = (1280, 960), *, hfov_deg: float = 62.0,
                dist: Sequence[float] = (-0.11, 0.045, 4e-4, -3e-4, -0.008)) -> CameraModel:
        """A typical machine-vision lens: mild barrel distortion, principal point a few
        pixels off centre (as real calibrations find)."""
        w, h = (int(v) for v in resolution)
        if not (16 <= w <= 8000 and 16 <= h <= 6000):
            raise ValueError(f"resolution {w}x{h} out of range (16..8000 x 16..6000)")
        f = (w / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
        k = np.array([[f, 0.0, (w - 1) / 2.0 + 0.004 * w],
                      [0.0, f * 1.0005, (h - 1) / 2.0 - 0.003 * h],
                      [0.0, 0.0, 1.0]])
        return cls(k, np.asarray(dist, float).reshape(5), (w, h))

    def to_dict(self) -> dict[str, Any]:
        return {"camera_matrix": self.K.tolist(), "dist_coeffs": self.dist.tolist(),
                "resolution": list(self.resolution)}


@dataclass(frozen=True)
class Pose:
    """Table -> camera: ``X_cam = R(rvec) X_table + tvec`` (mm)."""

    rvec: np.ndarray
    tvec: np.ndarray

    @property
    def R(self) -> np.ndarray:  # noqa: N802 (the usual name)
        return cv2.Rodrigues(np.asarray(self.rvec, float).reshape(3, 1))[0]

    @property
    def centre(self) -> np.ndarray:
        """Camera centre in table coordinates (z < 0: above the table)."""
        return -self.R.T @ np.asarray(self.tvec, float)

    @classmethod
    def look_at(cls, eye: Sequence[float], target: Sequence[float],
                yaw_deg: float = 0.0) -> Pose:
        """Camera at ``eye`` (table frame, z < 0 is above) looking at ``target``; image
        x runs along table direction ``yaw_deg`` as far as the view allows."""
        eye, target = np.asarray(eye, float), np.asarray(target, float)
        z = target - eye
        z /= np.linalg.norm(z)
        hint = np.array([math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg)), 0])
        x = hint - (hint @ z) * z
        if np.linalg.norm(x) < 1e-6:
            raise ValueError("look_at: the yaw direction is parallel to the view direction")
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        r = np.stack([x, y, z])
        return cls(cv2.Rodrigues(r)[0].ravel(), -r @ eye)

    @classmethod
    def overhead(cls, centre: Sequence[float], height: float, *, yaw_deg: float = 0.0,
                 tilt_deg: float = 0.0, tilt_azimuth_deg: float = 0.0) -> Pose:
        """Looking at table point ``centre`` from ``height`` mm, tilted ``tilt_deg`` off
        the vertical towards table direction ``tilt_azimuth_deg``."""
        if not height > 0:
            raise ValueError(f"camera height must be positive, got {height}")
        t, a = math.radians(tilt_deg), math.radians(tilt_azimuth_deg)
        c = np.array([centre[0], centre[1], 0.0])
        eye = c + height * np.array([-math.sin(t) * math.cos(a), -math.sin(t) * math.sin(a),
                                     -math.cos(t)])
        return cls.look_at(eye, c, yaw_deg)

    def to_dict(self) -> dict[str, Any]:
        return {"rvec": np.asarray(self.rvec, float).ravel().tolist(),
                "tvec": np.asarray(self.tvec, float).ravel().tolist()}



def calibration_poses(board: Board, n: int = 10, *, camera: CameraModel | None = None,
                      seed: int = 0, max_tilt_deg: float = 35.0) -> list[Pose]:
    """``n`` varied views of ``board`` (tilts, turns, distances) for calibration.

    The board fills about half the frame and is seen from different sides and in
    different parts of the frame (corners included, as calibration guides recommend,
    so the distortion is measured where it is largest); the first view is straight
    down and centred.
    """
    camera = camera or CameraModel.default()
    rng = np.random.default_rng(seed)
    bw, bh = board.extent_mm
    centre = rot2(board.rotation) @ np.array([bw / 2, bh / 2]) + np.asarray(board.shift)
    f = camera.K[0, 0]
    w, h = camera.resolution
    base = f * max(bw / w, bh / h) / 0.6
    view = base * np.array([w, h]) / f  # table mm seen at the base height
    quadrants = np.array([(-1, -1), (1, -1), (1, 1), (-1, 1)], float)
    poses = []
    for k in range(n):
        tilt = 0.0 if k == 0 else rng.uniform(12.0, max_tilt_deg)
        # move the board towards a frame corner (quadrants in turn), by about a quarter
        # of the view, so the board's corners reach the frame's corners
        offset = quadrants[k % 4] * rng.uniform(0.2, 0.28, 2) * view * (k > 0)
        aim = centre - offset
        poses.append(Pose.overhead(aim, base * rng.uniform(0.95, 1.15), tilt_deg=tilt,
                                   tilt_azimuth_deg=rng.uniform(0, 360),
                                   yaw_deg=board.rotation + rng.uniform(-25, 25) * (k > 0)))
    return poses


