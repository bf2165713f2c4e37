"""Camera calibration to the table: intrinsics and lens distortion from ChArUco views,
and the table plane's homography to machine millimetres from a board lying on it.

ChArUco (a chessboard with ArUco markers in the white squares) gives identified
corners even when the board is partly out of view, so views that reach the frame's
corners (where distortion is largest) still count. OpenCV 4.7+/5 API: ``CharucoBoard``,
``CharucoDetector.detectBoard`` and ``Board.matchImagePoints``, then
``cv2.calibrateCamera`` on the matched object/image points.

Machine coordinates: the board defines them up to a placement the operator knows
(``board_origin`` = machine mm of the board's corner (0, 0), ``board_rotation`` degrees);
everything downstream (rectified images, lattices, origins) is in those millimetres.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

import untrusted
from untrusted.limits import MAX_IMAGE_PIXELS

__all__ = ["BoardSpec", "Calibration", "calibrate_intrinsics", "check_view", "detect_board",
           "rectified_size", "table_homography", "visible_region"]

_UNDISTORT = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-10)


@dataclass(frozen=True)
class BoardSpec:
    """A ChArUco board: (columns, rows) of squares, sizes in mm, ArUco dictionary."""

    squares: tuple[int, int] = (7, 5)
    square_mm: float = 30.0
    marker_mm: float = 22.0
    dictionary: str = "DICT_5X5_100"

    def __post_init__(self) -> None:
        if not hasattr(cv2.aruco, self.dictionary):
            raise ValueError(f"unknown ArUco dictionary {self.dictionary!r} "
                             "(e.g. DICT_5X5_100, DICT_4X4_50)")
        if not 0 < self.marker_mm < self.square_mm:
            raise ValueError(f"marker size {self.marker_mm} mm must be positive and below "
                             f"the square size {self.square_mm} mm")
        if min(self.squares) < 2:
            raise ValueError(f"a board needs at least 2x2 squares, got {self.squares}")

    def cv_board(self) -> cv2.aruco.CharucoBoard:
        dic = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        return cv2.aruco.CharucoBoard(tuple(int(v) for v in self.squares),
                                      float(self.square_mm), float(self.marker_mm), dic)

    def to_dict(self) -> dict[str, Any]:
        return {"squares": list(self.squares), "square_mm": self.square_mm,
                "marker_mm": self.marker_mm, "dictionary": self.dictionary}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> BoardSpec:
        return cls(tuple(d.get("squares", (7, 5))), float(d.get("square_mm", 30.0)),
                   float(d.get("marker_mm", 22.0)), str(d.get("dictionary", "DICT_5X5_100")))


def detect_board(image: np.ndarray, board: BoardSpec, *, min_corners: int = 6
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ChArUco corners in ``image``: (ids (N,), image px (N, 2), board mm (N, 2)).

    Fewer than ``min_corners`` corners give empty arrays (a view too poor to use).
    """
    gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    cvb = board.cv_board()
    det = cv2.aruco.CharucoDetector(cvb)
    corners, ids, _, _ = det.detectBoard(gray)
    empty = (np.zeros(0, int), np.zeros((0, 2)), np.zeros((0, 2)))
    if ids is None or len(ids) < min_corners:
        return empty
    obj, img = cvb.matchImagePoints(corners, ids)
    if obj is None or len(obj) < min_corners:
        return empty
    return (np.asarray(ids).ravel().astype(int), np.asarray(img, float).reshape(-1, 2),
            np.asarray(obj, float).reshape(-1, 3)[:, :2])


def calibrate_intrinsics(images: list[np.ndarray], board: BoardSpec, *,
                         min_views: int = 4) -> tuple[np.ndarray, np.ndarray, float, int]:
    """Camera matrix K, distortion (k1, k2, p1, p2, k3), RMS reprojection error (px) and
    the number of views used, from several views of the board."""
    if not images:
        raise ValueError("no calibration images given")
    size = (images[0].shape[1], images[0].shape[0])
    objs, imgs = [], []
    for im in images:
        if (im.shape[1], im.shape[0]) != size:
            raise ValueError(f"calibration images differ in size: {size} and "
                             f"{(im.shape[1], im.shape[0])}")
        ids, px, mm = detect_board(im, board)
        if len(ids) >= 6:
            objs.append(np.column_stack([mm, np.zeros(len(mm))]).astype(np.float32))
            imgs.append(px.astype(np.float32).reshape(-1, 1, 2))
    if len(objs) < min_views:
        raise ValueError(f"the board was found in {len(objs)} of {len(images)} images; "
                         f"calibration needs at least {min_views} views")
    rms, k, dist, _, _ = cv2.calibrateCamera(objs, imgs, size, None, None)
    return np.asarray(k, float), np.asarray(dist, float).ravel()[:5], float(rms), len(objs)


def _placement(origin: tuple[float, float], rotation: float) -> np.ndarray:
    r = math.radians(rotation)
    out = np.eye(3)
    out[:2, :2] = [[math.cos(r), -math.sin(r)], [math.sin(r), math.cos(r)]]
    out[:2, 2] = origin
    return out


def table_homography(image: np.ndarray, board: BoardSpec, k: np.ndarray, dist: np.ndarray,
                     *, board_origin: tuple[float, float] = (0.0, 0.0),
                     board_rotation: float = 0.0) -> tuple[np.ndarray, float, int]:
    """Homography from *undistorted* image pixels to machine mm for a board lying on the
    table, its RMS residual in mm and the number of corners used."""
    ids, px, mm = detect_board(image, board)
    if len(ids) < 8:
        raise ValueError(f"the board was not found on the table image ({len(ids)} corners)")
    und = cv2.undistortPoints(px.reshape(-1, 1, 2), k, dist, P=k,
                              criteria=_UNDISTORT).reshape(-1, 2)
    table = mm @ _placement(board_origin, board_rotation)[:2, :2].T + np.asarray(board_origin)
    h, _ = cv2.findHomography(und, table, 0)
    if h is None:
        raise ValueError("the table homography is degenerate (board corners collinear?)")
    pred = cv2.perspectiveTransform(und.reshape(-1, 1, 2), h).reshape(-1, 2)
    rms = float(np.sqrt(np.mean(np.sum((pred - table) ** 2, axis=1))))
    return h / h[2, 2], rms, len(ids)


@dataclass
class Calibration:
    """Camera model plus the table plane: everything to turn pixels into machine mm."""

    camera_matrix: np.ndarray
    dist_coeffs: np.ndarray
    resolution: tuple[int, int]
    reprojection_rms_px: float = float("nan")
    homography: np.ndarray = field(default_factory=lambda: np.eye(3))  # undistorted px -> mm
    table_rms_mm: float = float("nan")
    board: BoardSpec = field(default_factory=BoardSpec)
    views: int = 0

    # ------------------------------------------------------------ maps
    def image_to_table(self, px: np.ndarray) -> np.ndarray:
        """(N, 2) frame pixels -> (N, 2) machine mm on the table plane."""
        px = np.asarray(px, float).reshape(-1, 1, 2)
        und = cv2.undistortPoints(px, self.camera_matrix, self.dist_coeffs,
                                  P=self.camera_matrix, criteria=_UNDISTORT)
        return cv2.perspectiveTransform(und, self.homography).reshape(-1, 2)

    def table_to_image(self, mm: np.ndarray) -> np.ndarray:
        """(N, 2) machine mm -> (N, 2) frame pixels (with the lens distortion)."""
        mm = np.asarray(mm, float).reshape(-1, 1, 2)
        und = cv2.perspectiveTransform(mm, np.linalg.inv(self.homography)).reshape(-1, 2)
        kinv = np.linalg.inv(self.camera_matrix)
        norm = np.column_stack([und, np.ones(len(und))]) @ kinv.T
        pts, _ = cv2.projectPoints(norm.reshape(-1, 1, 3), np.zeros(3), np.zeros(3),
                                   self.camera_matrix, self.dist_coeffs)
        return pts.reshape(-1, 2)

    def mm_per_px(self) -> float:
        """Footprint of one pixel at the frame centre (mm)."""
        w, h = self.resolution
        c = np.array([[w / 2, h / 2], [w / 2 + 1, h / 2], [w / 2, h / 2 + 1]])
        t = self.image_to_table(c)
        a, b = t[1] - t[0], t[2] - t[0]
        return float(math.sqrt(abs(a[0] * b[1] - a[1] * b[0])))

    @property
    def focal_px(self) -> float:
        return float(self.camera_matrix[0, 0])

    # ------------------------------------------------------------ files
    def to_dict(self) -> dict[str, Any]:
        return {"camera_matrix": self.camera_matrix.tolist(),
                "dist_coeffs": self.dist_coeffs.tolist(),
                "resolution": list(self.resolution),
                "reprojection_rms_px": self.reprojection_rms_px,
                "homography_undistorted_px_to_mm": self.homography.tolist(),
                "table_rms_mm": self.table_rms_mm, "views": self.views,
                "board": self.board.to_dict(), "units": "mm"}

    def save(self, path: str | Path) -> None:
        Path(path).write_text(json.dumps(self.to_dict(), indent=2) + "\n")

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Calibration:
        try:
            k = np.asarray(d["camera_matrix"], float)
            dist = np.asarray(d["dist_coeffs"], float).ravel()
            hom = np.asarray(d.get("homography_undistorted_px_to_mm", np.eye(3)), float)
            res = tuple(int(v) for v in d["resolution"])
        except KeyError as exc:
            raise ValueError(f"calibration lacks {exc.args[0]!r}") from None
        if k.shape != (3, 3) or hom.shape != (3, 3) or len(res) != 2:
            raise ValueError("calibration: camera_matrix and homography must be 3x3 and "
                             "resolution [width, height]")
        if not np.all(np.isfinite(k)) or not np.all(np.isfinite(hom)):
            raise ValueError("calibration contains non-finite numbers")
        return cls(k, dist, res, float(d.get("reprojection_rms_px", float("nan"))), hom,
                   float(d.get("table_rms_mm", float("nan"))),
                   BoardSpec.from_dict(d.get("board", {})), int(d.get("views", 0)))

    @classmethod
    def load(cls, path: str | Path) -> Calibration:
        src = str(path)
        d = untrusted.mapping(untrusted.read_json(path, what="calibration file"), src)
        for key in ("camera_matrix", "homography_undistorted_px_to_mm"):
            if key in d:
                untrusted.matrix(d[key], src, key, (3, 3), max_abs=1e12)
        if "dist_coeffs" in d:  # OpenCV's models have at most 14 coefficients
            dist = untrusted.sequence(d["dist_coeffs"], src, "dist_coeffs", max_len=14)
            if len(dist) == 1 and isinstance(dist[0], list):  # OpenCV's (1, n) row
                dist = untrusted.sequence(dist[0], src, "dist_coeffs", max_len=14)
            untrusted.points([[v] for v in dist] or [[0.0]], src, "dist_coeffs", dim=1)
        if "resolution" in d:
            res = untrusted.sequence(d["resolution"], src, "resolution", min_len=2, max_len=2)
            for v in res:
                untrusted.integer(v, src, "resolution", lo=1, hi=100_000)
        try:
            cal = cls.from_dict(d)
        except (ValueError, TypeError) as exc:
            raise untrusted.InputError(src, str(exc)) from None
        cal.check(src)
        return cal

    def check(self, source: str) -> None:
        """Err (naming ``source``) unless the maps are a camera's: OpenCV's distortion
        model, positive focal lengths, and a table view that rectifies into a sane image.
        A singular or wild homography otherwise surfaces later as an OpenCV assertion, a
        fault blamed on the photo, or a rectified image of hundreds of megapixels."""
        k = self.camera_matrix
        if len(self.dist_coeffs) not in (0, 4, 5, 8, 12, 14):
            raise untrusted.InputError(source, f"dist_coeffs has {len(self.dist_coeffs)} "
                                       "numbers; OpenCV's models take 4, 5, 8, 12 or 14")
        if not (k[0, 0] > 0 and k[1, 1] > 0 and np.array_equal(k[2], [0.0, 0.0, 1.0])):
            raise untrusted.InputError(source, "camera_matrix must be [[fx, 0, cx], [0, fy, "
                                       "cy], [0, 0, 1]] with fx, fy > 0")
        try:
            check_view(self)
        except (ValueError, cv2.error) as exc:  # LinAlgError is a ValueError
            fault = str(exc).removeprefix("calibration: ").splitlines()[0]
            raise untrusted.InputError(source, f"the table map does not fit the camera "
                                       f"({fault})") from None

    # ------------------------------------------------------------ building
    @classmethod
    def from_views(cls, views: list[np.ndarray], table_view: np.ndarray,
                   board: BoardSpec, *, board_origin: tuple[float, float] = (0.0, 0.0),
                   board_rotation: float = 0.0) -> Calibration:
        """Intrinsics from ``views`` (board in varied poses), table plane from
        ``table_view`` (board lying flat where the fabric goes)."""
        k, dist, rms, used = calibrate_intrinsics(views, board)
        hom, trms, _ = table_homography(table_view, board, k, dist,
                                        board_origin=board_origin,
                                        board_rotation=board_rotation)
        res = (table_view.shape[1], table_view.shape[0])
        return cls(k, dist, res, rms, hom, trms, board, used)


# ---------------------------------------------------------------- the table in view
def visible_region(cal: Calibration, *, samples: int = 64) -> tuple[float, float, float,
                                                                     float]:
    """The largest axis-aligned table rectangle (x0, y0, x1, y1) mm inside the frame.

    Found from the frame's border mapped onto the table: each side of the box is pushed
    in to the innermost border point on that side, so no rectified pixel is black.
    """
    w, h = cal.resolution
    t = np.linspace(0, 1, samples)
    top = cal.image_to_table(np.column_stack([t * (w - 1), np.zeros(samples)]))
    bottom = cal.image_to_table(np.column_stack([t * (w - 1), np.full(samples, h - 1.0)]))
    left = cal.image_to_table(np.column_stack([np.zeros(samples), t * (h - 1)]))
    right = cal.image_to_table(np.column_stack([np.full(samples, w - 1.0), t * (h - 1)]))
    border = np.concatenate([top, right, bottom, left])
    centre = cal.image_to_table(np.array([[(w - 1) / 2, (h - 1) / 2]]))[0]
    # Which side of the centre each border segment lies on, in table axes.
    rel = border - centre
    x0 = rel[(rel[:, 0] < 0) & (np.abs(rel[:, 1]) <= np.abs(rel[:, 0]))][:, 0].max(initial=-np.inf)
    x1 = rel[(rel[:, 0] > 0) & (np.abs(rel[:, 1]) <= np.abs(rel[:, 0]))][:, 0].min(initial=np.inf)
    y0 = rel[(rel[:, 1] < 0) & (np.abs(rel[:, 0]) <= np.abs(rel[:, 1]))][:, 1].max(initial=-np.inf)
    y1 = rel[(rel[:, 1] > 0) & (np.abs(rel[:, 0]) <= np.abs(rel[:, 1]))][:, 1].min(initial=np.inf)
    box = np.array([x0, y0, x1, y1])
    if not np.all(np.isfinite(box)):
        raise ValueError("calibration: the frame does not enclose a table region")
    # Shrink until all four corners map inside the frame.
    for _ in range(20):
        corners = centre + np.array([[box[0], box[1]], [box[2], box[1]], [box[2], box[3]],
                                     [box[0], box[3]]])
        px = cal.table_to_image(corners)
        if np.all((px >= 0) & (px <= [w - 1, h - 1])):
            break
        box *= 0.97
    x0, y0, x1, y1 = box + np.concatenate([centre, centre])
    return float(x0), float(y0), float(x1), float(y1)


def rectified_size(region: tuple[float, float, float, float], mm_per_px: float
                   ) -> tuple[int, int]:
    """(width, height) px of ``region`` rectified at ``mm_per_px``; a ValueError if that is
    not a sane image (at most the image pixel limit), before anything is allocated."""
    x0, y0, x1, y1 = region
    if not 0 < mm_per_px < math.inf:
        raise ValueError(f"mm per pixel must be positive and finite, got {mm_per_px:g}")
    nx, ny = (x1 - x0) / mm_per_px, (y1 - y0) / mm_per_px
    if not (8 <= nx <= 20000 and 8 <= ny <= 20000 and nx * ny <= MAX_IMAGE_PIXELS):
        raise ValueError(f"the table region {x0:.4g}..{x1:.4g} x {y0:.4g}..{y1:.4g} mm at "
                         f"{mm_per_px:.4g} mm/px gives {nx:.4g} x {ny:.4g} px")
    return int(round(nx)), int(round(ny))


def check_view(cal: Calibration) -> None:
    """A ValueError unless ``cal`` maps its frame onto a table region that rectifies into
    a sane image, at most 4 times the frame's pixels (a camera's view of a flat table is
    within a few times that): a calibration file's maps, checked before any photo is read."""
    nx, ny = rectified_size(visible_region(cal), cal.mm_per_px())
    w, h = cal.resolution
    if nx * ny > 4 * w * h:
        raise ValueError(f"the frame of {w} x {h} px would rectify into {nx} x {ny} px")
