"""A roll longer than the table, on a conveyor that slips, seen only through the table window.

Truth for the bite-by-bite cut (issue 35): the print on a real roll is not the perfect
lattice of its design. It bows across the width, skews and stretches, slowly, along the
roll; :class:`RollPrint` maps a point of the cloth (u along the roll, v across it, mm)
to the design's coordinates where that cloth shows the print. The :class:`Conveyor`
advances the roll by the commanded length plus a slip (up to ±3 mm) and turns it by a
small skew; :class:`RollCamera` photographs only the table window, rectified to table
mm (the calibration's own simulation is `simulators.camera`). Every pose is kept, so a
test or report can say where any table point of any bite lay on the cloth.

What the cutter burns is kept too (:meth:`RollCamera.burn`), in cloth coordinates: the
kerfs travel with the cloth, and every later photograph shows those still in the window,
as thin dark lines (the cut and its charred edges, `KERF_MM` wide), anti-aliased.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from simulators.fabric import Print, to_uint8

#: a laser's kerf in cloth as the camera sees it: the cut and its charred edges (mm)
KERF_MM = 0.5
KERF_BGR = np.array([0.10, 0.09, 0.08], np.float32)  # charred cloth over the dark table
#: kerfs are drawn this many times finer than the photograph, then averaged down
KERF_SUPERSAMPLE = 4


@dataclass(frozen=True)
class RollPrint:
    """The print as it lies on a roll ``width`` mm wide: ``design`` distorted slowly.

    Along the roll, with a period of ``wave_mm``: the weft line bows by up to ``bow_mm``
    at mid-width, turns by up to ``skew_deg``, and the print stretches by up to
    ``stretch`` (a fraction) against its design."""

    design: Print
    width: float
    bow_mm: float = 4.0
    skew_deg: float = 0.5
    stretch: float = 0.003
    wave_mm: float = 6000.0

    def design_point(self, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Design coordinates (mm) of the print shown at cloth point ``(u, v)``."""
        phase = 2.0 * math.pi * np.asarray(u, float) / self.wave_mm
        across = np.asarray(v, float) / self.width - 0.5  # -0.5 .. 0.5 across the roll
        along = (u + self.stretch * self.wave_mm / (2 * math.pi) * (1.0 - np.cos(phase))
                 + self.bow_mm * np.sin(phase + 0.7) * (1.0 - 4.0 * across**2)
                 + math.tan(math.radians(self.skew_deg)) * np.sin(phase + 1.9)
                 * across * self.width)
        return along, np.asarray(v, float)


@dataclass(frozen=True)
class LaidPrint:
    """``roll``'s print as it lies on the table before the first advance (cloth point =
    table point of the window): what the station's camera photographs to plan the
    marker, bow, skew and stretch included. It stands for a `Print` in a
    `simulators.camera.Sheet`; its truth is the design's ideal lattice, which the vision
    should find as the best fit of the distorted print."""

    roll: RollPrint

    @property
    def name(self) -> str:
        return self.roll.design.name

    @property
    def truth(self):
        return self.roll.design.truth

    def colour_at(self, x: np.ndarray, y: np.ndarray, pixel_mm: float, *,
                  anti_alias: bool = True) -> np.ndarray:
        """`Print.colour_at` of the design at the design point each cloth point shows."""
        u, v = self.roll.design_point(np.asarray(x, float), np.asarray(y, float))
        return self.roll.design.colour_at(u, v, pixel_mm, anti_alias=anti_alias)


@dataclass
class Pose:
    """Where the roll lies on the table: table point p shows cloth point
    ``R(angle) (p - pivot) + pivot + (along, across)``."""

    along: float
    across: float
    angle_deg: float
    pivot: tuple[float, float]

    def cloth_point(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        c, s = math.cos(math.radians(self.angle_deg)), math.sin(math.radians(self.angle_deg))
        dx, dy = np.asarray(x, float) - self.pivot[0], np.asarray(y, float) - self.pivot[1]
        return (c * dx - s * dy + self.pivot[0] + self.along,
                s * dx + c * dy + self.pivot[1] + self.across)

    def table_point(self, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The table point that shows cloth point ``(u, v)`` (the inverse of
        :meth:`cloth_point`)."""
        c, s = math.cos(math.radians(self.angle_deg)), math.sin(math.radians(self.angle_deg))
        du = np.asarray(u, float) - self.pivot[0] - self.along
        dv = np.asarray(v, float) - self.pivot[1] - self.across
        return c * du + s * dv + self.pivot[0], -s * du + c * dv + self.pivot[1]


@dataclass
class Conveyor:
    """Advances the roll by the commanded length plus a slip, and turns it a little.

    ``slip_mm`` and ``skew_deg`` bound the uniform random error of one advance (a test
    may also force the next one with :meth:`advance`'s ``slip``/``skew``)."""

    pivot: tuple[float, float]
    slip_mm: float = 3.0
    skew_deg: float = 0.2
    drift_mm: float = 0.5  # sideways wander of one advance
    seed: int = 0
    poses: list[Pose] = field(default_factory=list)

    def __post_init__(self) -> None:
        self._rng = np.random.default_rng(self.seed)
        if not self.poses:
            self.poses.append(Pose(0.0, 0.0, 0.0, self.pivot))

    @property
    def pose(self) -> Pose:
        return self.poses[-1]

    def advance(self, commanded_mm: float, *, slip: float | None = None,
                skew: float | None = None) -> Pose:
        """Move the roll on by ``commanded_mm`` (plus the slip), returning the new pose."""
        rng = self._rng
        slip = rng.uniform(-self.slip_mm, self.slip_mm) if slip is None else slip
        skew = rng.uniform(-self.skew_deg, self.skew_deg) if skew is None else skew
        drift = rng.uniform(-self.drift_mm, self.drift_mm)
        last = self.pose
        self.poses.append(Pose(last.along + commanded_mm + slip, last.across + drift,
                               last.angle_deg + skew, self.pivot))
        return self.pose


@dataclass
class RollCamera:
    """The table window ``(x0, y0, x1, y1)`` mm, photographed at ``mm_per_px``, with
    sensor noise: what the station's rectified capture of a roll would give."""

    roll: RollPrint
    conveyor: Conveyor
    window: tuple[float, float, float, float]
    mm_per_px: float = 1.0
    noise: float = 0.02
    seed: int = 0
    #: what was cut so far: (n, 4) segments u0, v0, u1, v1 in cloth mm, per burn
    kerfs: list[np.ndarray] = field(default_factory=list)

    def __post_init__(self) -> None:
        self._rng = np.random.default_rng(self.seed)

    def burn(self, segments: np.ndarray) -> None:
        """Cut the (n, 4) ``segments`` (x0, y0, x1, y1, table mm) into the cloth where the
        roll lies now."""
        seg = np.asarray(segments, float).reshape(-1, 4)
        pose = self.conveyor.pose
        self.kerfs.append(np.column_stack([*pose.cloth_point(seg[:, 0], seg[:, 1]),
                                           *pose.cloth_point(seg[:, 2], seg[:, 3])]))

    def photograph(self) -> np.ndarray:
        """(H, W, 3) BGR uint8 of the window; pixel (col, row) centred on
        ``(x0, y0) + (col, row) * mm_per_px``."""
        x0, y0, x1, y1 = self.window
        xs = x0 + np.arange(int(round((x1 - x0) / self.mm_per_px))) * self.mm_per_px
        ys = y0 + np.arange(int(round((y1 - y0) / self.mm_per_px))) * self.mm_per_px
        x, y = np.meshgrid(xs, ys)
        u, v = self.conveyor.pose.cloth_point(x, y)
        px, py = self.roll.design_point(u, v)
        img = self.roll.design.colour_at(px, py, self.mm_per_px)
        if self.kerfs:
            cloth = np.concatenate(self.kerfs)
            pose = self.conveyor.pose
            table = np.column_stack([*pose.table_point(cloth[:, 0], cloth[:, 1]),
                                     *pose.table_point(cloth[:, 2], cloth[:, 3])])
            cover = kerf_cover((table - np.tile([x0, y0], 2)) / self.mm_per_px,
                               img.shape[:2], KERF_MM / self.mm_per_px)[..., None]
            img = img * (1.0 - cover) + KERF_BGR * cover
        img = img + self._rng.normal(0.0, self.noise, img.shape).astype(np.float32)
        return to_uint8(img)


def kerf_cover(segments_px: np.ndarray, shape: tuple[int, int], width_px: float
               ) -> np.ndarray:
    """(H, W) float32 in [0, 1]: the share of each pixel that the (n, 4) ``segments_px``
    (x0, y0, x1, y1, pixel centres at whole numbers), ``width_px`` wide, cover: drawn
    `KERF_SUPERSAMPLE` times finer, only where they cross the photograph, and averaged."""
    h, w = shape
    cover = np.zeros((h, w), np.float32)
    seg = np.asarray(segments_px, float).reshape(-1, 4)
    lo, hi = np.minimum(seg[:, :2], seg[:, 2:]), np.maximum(seg[:, :2], seg[:, 2:])
    seg = seg[np.all(hi >= -width_px - 1, axis=1) & (lo[:, 0] <= w + width_px)
              & (lo[:, 1] <= h + width_px)]
    if not len(seg):
        return cover
    k = KERF_SUPERSAMPLE
    c0, r0 = (max(0, int(np.floor(v - width_px)) - 1) for v in seg.reshape(-1, 2).min(axis=0))
    c1, r1 = (min(n, int(np.ceil(v + width_px)) + 2)
              for v, n in zip(seg.reshape(-1, 2).max(axis=0), (w, h)))
    if c1 <= c0 or r1 <= r0:
        return cover
    fine = np.zeros(((r1 - r0) * k, (c1 - c0) * k), np.uint8)
    ends = (seg - np.tile([c0, r0], 2)) * k + (k - 1) / 2  # the fine grid's pixel centres
    ends = np.round(np.clip(ends, -1e6, 1e6) * 16).astype(np.int32).reshape(-1, 2, 1, 2)
    cv2.polylines(fine, list(ends), False, 255, max(1, round(width_px * k)), cv2.LINE_8,
                  shift=4)
    cover[r0:r1, c0:c1] = cv2.resize(fine, (c1 - c0, r1 - r0),
                                     interpolation=cv2.INTER_AREA).astype(np.float32) / 255
    return cover
