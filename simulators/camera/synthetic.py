"""The synthetic camera: renders frames of the sheet and board through the lens from each pose,
by inverse mapping (see the package's docstring), with the frame's exact truth."""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from simulators.camera.lens import CameraModel, Pose
from simulators.camera.render import render_table
from simulators.camera.scene import Board, Sheet, rot2
from simulators.camera.sensor import Imaging, expose
from simulators.camera.truth import FrameTruth
from simulators.fabric import Frieze

_COARSE_STEP = 8  # pixels between exactly mapped grid nodes
# undistortPoints stops after 5 iterations by default: too few near the frame corners
_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-10)


class SyntheticCamera:
    """A camera over the table that photographs a fabric sheet and/or a ChArUco board.

    Same interface as the station's real camera: :meth:`read` returns the next BGR
    uint8 frame, :meth:`close` releases it, it is a context manager, ``resolution`` is
    (width, height) (give ``resolution`` for the default lens, or a full ``camera``
    model). ``truth`` describes the last frame. With several ``poses`` the
    frames cycle through them (a calibration session); ``seed`` makes the noise, and
    so every frame, repeatable.
    """

    def __init__(self, sheet: Sheet | None = None, *, board: Board | None = None,
                 camera: CameraModel | None = None, resolution: tuple[int, int] | None = None,
                 poses: Sequence[Pose] | None = None, imaging: Imaging | None = None,
                 seed: int = 0) -> None:
        if sheet is None and board is None:
            raise ValueError("a synthetic camera needs a fabric sheet or a board to look at")
        if camera is not None and resolution is not None:
            raise ValueError("give either a camera model or a resolution, not both")
        self.sheet, self.board = sheet, board
        self.camera = camera or CameraModel.default(resolution or (1280, 960))
        self.imaging = imaging or Imaging()
        self.poses = list(poses) if poses else [self._default_pose()]
        self._rng = np.random.default_rng(seed)
        self._count = 0
        self._open = True
        self.truth: FrameTruth | None = None

    @property
    def resolution(self) -> tuple[int, int]:
        return self.camera.resolution

    @property
    def is_open(self) -> bool:
        return self._open

    def __enter__(self) -> SyntheticCamera:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._open = False

    def _default_pose(self) -> Pose:
        """Straight down on the sheet (or board), everything in view with a margin."""
        if self.sheet is not None:
            # An endless sheet (size None) is framed like a default-sized one.
            w, h = self.sheet.size or Sheet.__dataclass_fields__["size"].default
            corners = np.array([[0, 0], [w, 0], [w, h], [0, h]], float)
            table = corners @ self.sheet.fabric_to_table_affine()[:2, :2].T + self.sheet.shift
        else:
            bw, bh = self.board.extent_mm
            m = self.board.margin_mm
            corners = np.array([[-m, -m], [bw + m, -m], [bw + m, bh + m], [-m, bh + m]])
            table = corners @ rot2(self.board.rotation).T + np.asarray(self.board.shift)
        lo, hi = table.min(0), table.max(0)
        f = self.camera.K[0, 0]
        w, h = self.camera.resolution
        height = 1.08 * f * max((hi[0] - lo[0]) / w, (hi[1] - lo[1]) / h)
        return Pose.overhead((lo + hi) / 2, height)

    def read(self) -> np.ndarray:
        """The next frame, (H, W, 3) BGR uint8; ``self.truth`` then describes it."""
        if not self._open:
            raise RuntimeError("synthetic camera is closed")
        pose = self.poses[self._count % len(self.poses)]
        frame, truth = self._render(pose)
        self.truth = truth
        self._count += 1
        return frame

    # -------------------------------------------------------------- internals
    def _table_maps(self, pose: Pose) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Table coordinates of every pixel (float32 (H, W) each) and the footprint
        (mm per px) at the coarse-grid nodes and at every pixel."""
        w, h = self.camera.resolution
        st = _COARSE_STEP
        gx = np.arange(0, w - 1 + st, st, dtype=float)
        gy = np.arange(0, h - 1 + st, st, dtype=float)
        px, py = np.meshgrid(gx, gy)
        pts = np.stack([px, py], -1).reshape(-1, 1, 2)
        norm = cv2.undistortPoints(pts, self.camera.K, self.camera.dist, R=None, P=None,
                                   criteria=_UNDISTORT_CRITERIA).reshape(-1, 2)
        r = pose.R
        rays = np.column_stack([norm, np.ones(len(norm))]) @ r  # rows: R^T d
        c = pose.centre
        if np.any(rays[:, 2] * -c[2] <= 0):
            raise ValueError("part of the view does not see the table (camera looks "
                             "above the horizon or from below the table)")
        s = -c[2] / rays[:, 2]
        tx = (c[0] + s * rays[:, 0]).reshape(px.shape)
        ty = (c[1] + s * rays[:, 1]).reshape(px.shape)
        # footprint: sqrt |det J| of pixel -> table, per node
        jx = np.gradient(tx, st, axis=1), np.gradient(tx, st, axis=0)
        jy = np.gradient(ty, st, axis=1), np.gradient(ty, st, axis=0)
        foot = np.sqrt(np.abs(jx[0] * jy[1] - jx[1] * jy[0]))
        # interpolate the smooth map to every pixel (exact node alignment via remap)
        mx = (np.arange(w, dtype=np.float32) / st)[None, :].repeat(h, 0)
        my = (np.arange(h, dtype=np.float32) / st)[:, None].repeat(w, 1)
        ref = np.array([tx.mean(), ty.mean()])
        fx = cv2.remap((tx - ref[0]).astype(np.float32), mx, my, cv2.INTER_LINEAR)
        fy = cv2.remap((ty - ref[1]).astype(np.float32), mx, my, cv2.INTER_LINEAR)
        foot_px = cv2.remap(foot.astype(np.float32), mx, my, cv2.INTER_LINEAR)
        return fx + np.float32(ref[0]), fy + np.float32(ref[1]), foot, foot_px

    def _render(self, pose: Pose) -> tuple[np.ndarray, FrameTruth]:
        x, y, foot, foot_px = self._table_maps(pose)
        img = render_table(x, y, foot_px, self.sheet, self.board)
        frame = expose(img, self.imaging, self._rng)
        return frame, self._truth(pose, foot)

    def _truth(self, pose: Pose, foot: np.ndarray) -> FrameTruth:
        r = pose.R
        hom = self.camera.K @ np.column_stack([r[:, 0], r[:, 1], np.asarray(pose.tvec, float)])
        hom /= hom[2, 2]
        truth = FrameTruth(index=self._count, camera=self.camera, pose=pose, homography=hom,
                           mm_per_px=float(foot[foot.shape[0] // 2, foot.shape[1] // 2]))
        if self.sheet is not None:
            self._sheet_truth(truth)
        if self.board is not None:
            self._board_truth(truth, pose)
        return truth

    def _sheet_truth(self, truth: FrameTruth) -> None:
        """The print's symmetry and lattice in table mm, and how the sheet lies."""
        sh = self.sheet
        aff = sh.fabric_to_table_affine()
        pt = sh.print.truth
        w2 = pt.w1 if isinstance(pt, Frieze) else pt.w2
        truth.print_truth = sh.truth_on_table()
        truth.print_name = sh.print.name
        truth.lattice_affine = {"w1": (aff[:2, :2] @ pt.w1).tolist(),
                                "w2": (aff[:2, :2] @ w2).tolist(),
                                "origin": (aff[:2, :2] @ pt.origin + aff[:2, 2]).tolist()}
        truth.sheet = {"size": None if sh.size is None else list(sh.size),
                       "rotation": sh.rotation,
                       "shift": list(sh.shift), "skew": sh.skew, "bow": sh.bow,
                       "fold": list(sh.fold) if sh.fold else None,
                       "rigid": not sh.distorted}

    def _board_truth(self, truth: FrameTruth, pose: Pose) -> None:
        """The ChArUco corners in view: their ids, table and image positions."""
        ids, table = self.board.corners()
        image = truth.table_to_image(table)
        w, h = self.camera.resolution
        seen = np.all((image >= 0) & (image <= [w - 1, h - 1]), axis=1)
        # far outside the field of view the distortion polynomial folds back into
        # the frame: keep only corners whose pixel undistorts to their own ray
        cam_pts = np.column_stack([table, np.zeros(len(table))]) @ pose.R.T + np.asarray(
            pose.tvec, float)
        ray = cam_pts[:, :2] / cam_pts[:, 2:]
        back = cv2.undistortPoints(image.reshape(-1, 1, 2), self.camera.K,
                                   self.camera.dist, R=None, P=None,
                                   criteria=_UNDISTORT_CRITERIA).reshape(-1, 2)
        seen &= (cam_pts[:, 2] > 0) & (np.hypot(*(back - ray).T) < 1e-3)
        truth.board = self.board.to_dict()
        truth.charuco_ids, truth.charuco_table = ids[seen], table[seen]
        truth.charuco_image = image[seen]
