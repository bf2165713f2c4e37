"""What lies on the cutting table: a fabric sheet and a ChArUco calibration board.

The sheet: a W x H mm rectangle lying on the table turned by ``rotation`` degrees with
its corner at ``shift`` (sheet coordinates ``[0, W] x [0, H]``). Fabric coordinates are
the print's own millimetres; for a well spread sheet they equal the sheet coordinates.
Badly spread fabric is modelled as a map sheet -> fabric inside the same rectangle: weft
skew (a shear, degrees), weft bow (a parabola across the width, mm at the centre) and a
fold (a smooth step of ``depth`` mm of hidden fabric across a line, its crease shaded).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from simulators.fabric import Frieze, Print
from solver.wallpaper import Wallpaper


def rot2(deg: float) -> np.ndarray:
    r = math.radians(deg)
    return np.array([[math.cos(r), -math.sin(r)], [math.sin(r), math.cos(r)]])



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
        lin = rot2(self.rotation) @ np.array([[1.0, 0.0],
                                               [math.tan(math.radians(self.skew)), 1.0]])
        out = np.eye(3)
        out[:2, :2], out[:2, 2] = lin, self.shift
        return out

    def truth_on_table(self) -> Wallpaper | Frieze:
        """The print's symmetry in table mm: exact where the sheet is rigidly placed."""
        truth = self.print.truth
        r = rot2(self.rotation)
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
        table = pts @ rot2(self.rotation).T + np.asarray(self.shift, float)
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


