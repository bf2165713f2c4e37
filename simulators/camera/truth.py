"""Everything known exactly about one synthetic frame: camera, pose, homography, the print's
symmetry in table mm and the ChArUco corners seen."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from simulators.camera.lens import CameraModel, Pose
from simulators.fabric import Frieze
from solver.wallpaper import Wallpaper


@dataclass
class FrameTruth:
    """Everything that is known exactly about one synthetic frame."""

    index: int
    camera: CameraModel
    pose: Pose
    homography: np.ndarray  # table mm -> undistorted image px
    mm_per_px: float  # footprint of a pixel at the image centre
    print_truth: Wallpaper | Frieze | None = None  # the print's symmetry in table mm
    print_name: str | None = None
    lattice_affine: dict[str, list[float]] | None = None  # incl. skew (w1, w2, origin)
    sheet: dict[str, Any] | None = None
    board: dict[str, Any] | None = None
    charuco_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    charuco_table: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    charuco_image: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))

    @property
    def wallpaper(self) -> Wallpaper | None:
        return self.print_truth if isinstance(self.print_truth, Wallpaper) else None

    def table_to_image(self, xy: np.ndarray) -> np.ndarray:
        """(N, 2) table mm -> (N, 2) pixel positions in the (distorted) frame."""
        xy = np.asarray(xy, float).reshape(-1, 2)
        obj = np.column_stack([xy, np.zeros(len(xy))])
        img, _ = cv2.projectPoints(obj, np.asarray(self.pose.rvec, float),
                                   np.asarray(self.pose.tvec, float), self.camera.K,
                                   self.camera.dist)
        return img.reshape(-1, 2)

    def rectify(self, frame: np.ndarray, region: tuple[float, float, float, float],
                mm_per_px: float) -> np.ndarray:
        """Resample ``frame`` onto the table grid of :func:`render_rectified` using the
        true camera (through ``cv2.projectPoints``, independent of the renderer)."""
        x0, y0, x1, y1 = (float(v) for v in region)
        xs = x0 + np.arange(round((x1 - x0) / mm_per_px)) * mm_per_px
        ys = y0 + np.arange(round((y1 - y0) / mm_per_px)) * mm_per_px
        gx, gy = np.meshgrid(xs, ys)
        img = self.table_to_image(np.column_stack([gx.ravel(), gy.ravel()]))
        mx = img[:, 0].reshape(gx.shape).astype(np.float32)
        my = img[:, 1].reshape(gx.shape).astype(np.float32)
        return cv2.remap(frame, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"frame": self.index, **self.camera.to_dict(),
                             **self.pose.to_dict(),
                             "homography_table_to_undistorted": self.homography.tolist(),
                             "mm_per_px_at_centre": self.mm_per_px, "units": "mm"}
        if self.print_truth is not None:
            d["fabric"] = self.print_truth.to_dict()
            d["fabric"]["print"] = self.print_name
            d["lattice_affine"] = self.lattice_affine
            d["sheet"] = self.sheet
        if self.board is not None:
            d["board"] = self.board
            d["charuco"] = {"ids": self.charuco_ids.tolist(),
                            "table_xy": self.charuco_table.tolist(),
                            "image_xy": self.charuco_image.tolist()}
        return d


