"""A synthetic camera over the cutting table, with exact ground truth for every frame.

The scene is the table plane (z = 0, millimetres) with a fabric sheet lying on it and,
optionally, a ChArUco board for calibration. Frames are rendered by *inverse mapping*:
each image pixel is undistorted with OpenCV's own model (``cv2.undistortPoints``, iterated
to convergence, so the simulator and calibration share one definition of k1, k2, p1, p2,
k3), cast as
a ray, intersected with the table, carried into fabric or board coordinates and looked
up in the band-limited print texture. The pixel -> table map is computed on a coarse
grid and interpolated (it is smooth), so a 4000x3000 frame takes about a second.

Frames: the table frame has x and y on the table and z pointing *into* the table, so a
camera straight above it with ``rvec = 0`` sees table x to the right and table y down
(OpenCV's calibration-board convention). Poses are table -> camera (``X_cam = R X + t``),
exactly what ``cv2.solvePnP`` and ``cv2.calibrateCamera`` return for a board lying at
z = 0.

The sheet: a W x H mm rectangle lying on the table turned by ``rotation`` degrees with
its corner at ``shift`` (sheet coordinates ``[0, W] x [0, H]``). Fabric coordinates are
the print's own millimetres; for a well spread sheet they equal the sheet coordinates.
Badly spread fabric is modelled as a map sheet -> fabric inside the same rectangle: weft
skew (a shear, degrees), weft bow (a parabola across the width, mm at the centre) and a
fold (a smooth step of ``depth`` mm of hidden fabric across a line, its crease shaded).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from simulators.fabric import Frieze, Print, to_uint8
from solver.wallpaper import Wallpaper

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

_TABLE_BGR = np.array([0.30, 0.34, 0.27], np.float32)  # a grey-green cutting mat
_PAPER_BGR = np.array([0.97, 0.97, 0.96], np.float32)
_COARSE_STEP = 8  # pixels between exactly mapped grid nodes
# undistortPoints stops after 5 iterations by default: too few near the frame corners
_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-10)


def _rot2(deg: float) -> np.ndarray:
    r = math.radians(deg)
    return np.array([[math.cos(r), -math.sin(r)], [math.sin(r), math.cos(r)]])


# ------------------------------------------------------------------ camera and pose
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


# ------------------------------------------------------------------ scene objects
@dataclass(frozen=True)
class Sheet:
    """A fabric sheet lying on the table (see the module docstring for the model)."""

    print: Print
    size: tuple[float, float] | None = (900.0, 600.0)  # fabric mm covered; None: endless
    rotation: float = 0.0  # degrees, fabric axes -> table axes
    shift: tuple[float, float] = (0.0, 0.0)  # table position of fabric (0, 0)
    skew: float = 0.0  # degrees: weft lines tilt by this angle
    bow: float = 0.0  # mm: weft lines sag by this much at mid-width
    fold: tuple[float, float, float] | None = None  # (x position, depth, width) mm

    @property
    def distorted(self) -> bool:
        return bool(self.skew or self.bow or (self.fold and self.fold[1]))

    def table_to_local(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Sheet coordinates (mm, the rigidly placed W x H rectangle) of table points."""
        f = np.float32 if np.asarray(x).dtype == np.float32 else np.float64
        c, s = f(math.cos(math.radians(self.rotation))), f(math.sin(math.radians(self.rotation)))
        dx, dy = x - f(self.shift[0]), y - f(self.shift[1])
        return c * dx + s * dy, -s * dx + c * dy

    def local_to_fabric(self, lx: np.ndarray, ly: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Fabric (print) coordinates of sheet points: the spreading faults live here."""
        f = np.float32 if np.asarray(lx).dtype == np.float32 else np.float64
        fx, fy = lx, ly
        if self.skew:
            fy = ly - f(math.tan(math.radians(self.skew))) * lx
        if self.bow and self.size is not None:
            q = f(2.0 / self.size[0]) * lx - f(1.0)
            fy = fy - f(self.bow) * (f(1.0) - q * q)
        if self.fold is not None:
            pos, depth, width = self.fold
            step = np.tanh((lx - f(pos)) * f(1.0 / max(width, 1e-6)))
            fx = fx + f(0.5 * depth) * (f(1.0) + step)
        return fx, fy

    def table_to_fabric(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Fabric coordinates (mm) of table points (vectorised, any shape)."""
        return self.local_to_fabric(*self.table_to_local(x, y))

    def shading(self, lx: np.ndarray) -> np.ndarray | float:
        """Brightness factor at sheet x ``lx`` (the crease of a fold is in shadow)."""
        if self.fold is None:
            return 1.0
        f = np.float32
        pos, depth, width = self.fold
        depth_ratio = f(0.35 * min(1.0, abs(depth) / max(width, 1e-6)))
        z = np.clip((lx - f(pos)) * f(1.0 / max(width, 1e-6)), -30.0, 30.0)
        return f(1.0) - depth_ratio / np.cosh(z) ** 2

    def fabric_to_table_affine(self) -> np.ndarray:
        """3x3 map fabric -> table for rotation, shift and skew (exact without bow/fold)."""
        lin = _rot2(self.rotation) @ np.array([[1.0, 0.0],
                                               [math.tan(math.radians(self.skew)), 1.0]])
        out = np.eye(3)
        out[:2, :2], out[:2, 2] = lin, self.shift
        return out

    def truth_on_table(self) -> Wallpaper | Frieze:
        """The print's symmetry in table mm: exact where the sheet is rigidly placed."""
        truth = self.print.truth
        r = _rot2(self.rotation)
        shift = np.asarray(self.shift, float)
        if isinstance(truth, Wallpaper):
            return truth.moved(math.radians(self.rotation), shift)
        return Frieze(truth.group, r @ truth.w1, r @ truth.origin + shift)


@dataclass(frozen=True)
class Board:
    """A ChArUco calibration board printed on paper, lying on the table.

    ``squares`` is (columns, rows); board coordinates are mm from the corner of the
    squares grid, as OpenCV's ``CharucoBoard.getChessboardCorners()`` gives them.
    """

    squares: tuple[int, int] = (7, 5)
    square_mm: float = 30.0
    marker_mm: float = 22.0
    dictionary: str = "DICT_5X5_100"
    rotation: float = 0.0
    shift: tuple[float, float] = (0.0, 0.0)  # table position of the board's (0, 0)
    margin_mm: float = 12.0  # white paper around the squares

    def __post_init__(self) -> None:
        if not hasattr(cv2.aruco, self.dictionary):
            raise ValueError(f"unknown ArUco dictionary {self.dictionary!r}")
        if not 0 < self.marker_mm < self.square_mm:
            raise ValueError(f"marker size {self.marker_mm} mm must be below the square "
                             f"size {self.square_mm} mm")

    def cv_board(self) -> cv2.aruco.CharucoBoard:
        """The same board as an OpenCV object (for detection and calibration)."""
        dic = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        return cv2.aruco.CharucoBoard(tuple(self.squares), float(self.square_mm),
                                      float(self.marker_mm), dic)

    @property
    def extent_mm(self) -> tuple[float, float]:
        return self.squares[0] * self.square_mm, self.squares[1] * self.square_mm

    def corners(self) -> tuple[np.ndarray, np.ndarray]:
        """(ids (N,), table xy (N, 2)) of the inner chessboard corners."""
        pts = np.asarray(self.cv_board().getChessboardCorners(), float)[:, :2]
        table = pts @ _rot2(self.rotation).T + np.asarray(self.shift, float)
        return np.arange(len(pts)), table

    def table_to_board(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        f = np.float32 if np.asarray(x).dtype == np.float32 else np.float64
        c, s = f(math.cos(math.radians(self.rotation))), f(math.sin(math.radians(self.rotation)))
        dx, dy = x - f(self.shift[0]), y - f(self.shift[1])
        return c * dx + s * dy, -s * dx + c * dy

    def image(self, px_per_mm: float) -> tuple[np.ndarray, float]:
        """The board's squares area as a float32 grey image in [0, 1], and its exact
        pixels per mm (a whole number of pixels per square, or OpenCV's layout rounds)."""
        sq = max(8, int(round(self.square_mm * px_per_mm)))
        size = (self.squares[0] * sq, self.squares[1] * sq)
        img = self.cv_board().generateImage(size, marginSize=0, borderBits=1)
        return img.astype(np.float32) / 255.0, sq / self.square_mm

    def to_dict(self) -> dict[str, Any]:
        return {"squares": list(self.squares), "square_mm": self.square_mm,
                "marker_mm": self.marker_mm, "dictionary": self.dictionary,
                "rotation": self.rotation, "shift": list(self.shift),
                "margin_mm": self.margin_mm}


@dataclass(frozen=True)
class Imaging:
    """What the light, lens and sensor do to the ideal image."""

    exposure: float = 1.0
    light_ramp: tuple[float, float] = (0.12, -0.08)  # gain change edge-to-centre in x, y
    vignetting: float = 0.22  # relative fall-off in the image corners
    blur: float = 0.6  # Gaussian sigma, px (optics and demosaicing)
    noise: float = 2.0  # sd in grey levels at mid grey (shot + read noise)
    jpeg_quality: int | None = 92  # None: no compression

    @classmethod
    def ideal(cls) -> Imaging:
        return cls(light_ramp=(0.0, 0.0), vignetting=0.0, blur=0.0, noise=0.0,
                   jpeg_quality=None)


# ------------------------------------------------------------------ rendering
def _sample_print(p: Print, fx: np.ndarray, fy: np.ndarray,
                  footprint: float | np.ndarray) -> np.ndarray:
    """Print colours filtered for each pixel's own footprint.

    A tilted view sees the fabric at different scales across the frame; one filter
    would blur the near side or alias the far side. Two band-limited textures (finest
    and coarsest footprint) are blended per pixel by log footprint, like mip-mapping.
    """
    if np.ndim(footprint) == 0:
        return p.colour_at(fx, fy, float(footprint))
    lo, hi = float(footprint.min()), float(footprint.max())
    if hi <= 1.2 * lo:
        return p.colour_at(fx, fy, 0.5 * (lo + hi))
    near, far = p.colour_at(fx, fy, lo), p.colour_at(fx, fy, hi)
    t = np.clip(np.log(footprint / np.float32(lo)) / np.float32(math.log(hi / lo)), 0, 1)
    return cv2.blendLinear(far, near, t.astype(np.float32), (1.0 - t).astype(np.float32))


def _render_table(x: np.ndarray, y: np.ndarray, footprint: float | np.ndarray,
                  sheet: Sheet | None, board: Board | None) -> np.ndarray:
    """Float32 BGR colours of table points (mm), anti-aliased for ``footprint`` mm per
    pixel (a number, or one per pixel)."""
    out = np.empty(x.shape + (3,), np.float32)
    out[:] = _TABLE_BGR
    fp = np.maximum(footprint, 1e-6)
    if sheet is not None:
        lx, ly = sheet.table_to_local(x, y)
        cover = np.float32(1.0)
        if sheet.size is not None:  # the sheet is a rectangle; the print inside may not be
            w, h = sheet.size
            inside = np.minimum(np.minimum(lx, w - lx), np.minimum(ly, h - ly))
            cover = np.clip(inside / fp + 0.5, 0.0, 1.0).astype(np.float32)[..., None]
        fx, fy = sheet.local_to_fabric(lx, ly)
        colour = _sample_print(sheet.print, fx, fy, fp)
        shade = sheet.shading(lx)
        if not np.isscalar(shade):
            colour *= np.asarray(shade, np.float32)[..., None]
        out = _blend(colour, out, cover)
    if board is not None:
        bx, by = board.table_to_board(x, y)
        bw, bh = board.extent_mm
        m = board.margin_mm
        paper = np.minimum(np.minimum(bx + m, bw + m - bx), np.minimum(by + m, bh + m - by))
        cover = np.clip(paper / fp + 0.5, 0.0, 1.0).astype(np.float32)[..., None]
        fine = float(np.min(fp))
        img, ppm = board.image(float(np.clip(4.0 / fine, 4.0, 16.0)))
        sigma = 0.5 * fine * ppm
        if sigma > 0.3:
            img = cv2.GaussianBlur(img, (0, 0), sigma)
        grey = cv2.remap(img, (bx * ppm - 0.5).astype(np.float32),
                         (by * ppm - 0.5).astype(np.float32), cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_CONSTANT, borderValue=1.0)
        colour = grey[..., None] * _PAPER_BGR
        out = _blend(colour, out, cover)
    return out


def _blend(top: np.ndarray, below: np.ndarray, cover) -> np.ndarray:
    """``cover * top + (1 - cover) * below`` with a per-pixel (H, W, 1) or scalar cover."""
    if np.isscalar(cover) or np.ndim(cover) == 0:
        return top if float(cover) >= 1.0 else below + float(cover) * (top - below)
    c = np.ascontiguousarray(cover[..., 0], np.float32)
    return cv2.blendLinear(top, below, c, 1.0 - c)


def render_rectified(sheet: Sheet | Print | None, region: tuple[float, float, float, float],
                     mm_per_px: float, *, board: Board | None = None) -> np.ndarray:
    """A distortion-free top-down image of the table region ``(x0, y0, x1, y1)`` mm.

    Pixel ``(col, row)`` is centred on table point ``(x0 + col * s, y0 + row * s)``.
    A bare :class:`Print` is laid on the table as an endless sheet at the origin.
    Returns (H, W, 3) BGR uint8.
    """
    if mm_per_px <= 0:
        raise ValueError(f"mm per pixel must be positive, got {mm_per_px}")
    x0, y0, x1, y1 = (float(v) for v in region)
    w, h = int(round((x1 - x0) / mm_per_px)), int(round((y1 - y0) / mm_per_px))
    if not (1 <= w <= 20000 and 1 <= h <= 20000):
        raise ValueError(f"region {region} at {mm_per_px} mm/px gives {w}x{h} px")
    if isinstance(sheet, Print):
        sheet = Sheet(sheet, size=None)
    xs = x0 + np.arange(w) * mm_per_px
    ys = y0 + np.arange(h) * mm_per_px
    x, y = np.meshgrid(xs.astype(np.float32), ys.astype(np.float32))
    return to_uint8(_render_table(x, y, mm_per_px, sheet, board))


# ------------------------------------------------------------------ truth
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


# ------------------------------------------------------------------ the camera
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
    centre = _rot2(board.rotation) @ np.array([bw / 2, bh / 2]) + np.asarray(board.shift)
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
            table = corners @ _rot2(self.board.rotation).T + np.asarray(self.board.shift)
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
        w, h = self.camera.resolution
        x, y, foot, foot_px = self._table_maps(pose)
        img = _render_table(x, y, foot_px, self.sheet, self.board)
        im = self.imaging
        # light: a gain ramp across the frame and vignetting (cos^4-like fall-off)
        nx = np.linspace(-1.0, 1.0, w, dtype=np.float32)[None, :]
        ny = np.linspace(-1.0, 1.0, h, dtype=np.float32)[:, None]
        gain = im.exposure * (1.0 + im.light_ramp[0] * nx + im.light_ramp[1] * ny)
        gain = (gain * (1.0 - im.vignetting * 0.5 * (nx * nx + ny * ny))).astype(np.float32)
        # (OpenCV's element-wise functions below are several times faster than NumPy's
        # on 12-megapixel float images, which matters for 4000 x 3000 frames.)
        img = cv2.multiply(img, cv2.merge([gain, gain, gain]), scale=255.0)
        if im.blur > 0:
            img = cv2.GaussianBlur(img, (0, 0), im.blur)
        if im.noise > 0:
            read = 0.5 * im.noise
            shot = (im.noise**2 - read**2) / 128.0
            var = cv2.add(cv2.multiply(cv2.max(img, 0.0), shot), read**2)
            # cv2.randn is ~5x faster than NumPy's normals; seeding OpenCV's generator
            # from the camera's own keeps every frame repeatable.
            cv2.setRNGSeed(int(self._rng.integers(2**31 - 1)))
            noise = cv2.randn(np.empty_like(img), (0.0,) * 3, (1.0,) * 3)  # per channel
            img = cv2.add(img, cv2.multiply(cv2.sqrt(var), noise))
        frame = cv2.convertScaleAbs(cv2.max(img, 0.0))  # rounds and saturates to uint8
        if im.jpeg_quality is not None:
            ok, buf = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, im.jpeg_quality])
            frame = cv2.imdecode(buf, cv2.IMREAD_COLOR)
        return frame, self._truth(pose, foot)

    def _truth(self, pose: Pose, foot: np.ndarray) -> FrameTruth:
        r = pose.R
        hom = self.camera.K @ np.column_stack([r[:, 0], r[:, 1], np.asarray(pose.tvec, float)])
        hom /= hom[2, 2]
        truth = FrameTruth(index=self._count, camera=self.camera, pose=pose, homography=hom,
                           mm_per_px=float(foot[foot.shape[0] // 2, foot.shape[1] // 2]))
        if self.sheet is not None:
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
        if self.board is not None:
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
        return truth
