"""A roll longer than the table, on a conveyor that slips, seen only through the table window.

Truth for the bite-by-bite cut (issue 35): the print on a real roll is not the perfect
lattice of its design. It bows across the width, skews and stretches, slowly, along the
roll; :class:`RollPrint` maps a point of the cloth (u along the roll, v across it, mm)
to the design's coordinates where that cloth shows the print. The :class:`Conveyor`
advances the roll by the commanded length plus a slip (up to ±3 mm) and turns it by a
small skew; :class:`RollCamera` photographs only the table window, rectified to table
mm (the calibration's own simulation is `simulators.camera`). Every pose is kept, so a
test or report can say where any table point of any bite lay on the cloth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from simulators.fabric import Print, to_uint8


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

    def __post_init__(self) -> None:
        self._rng = np.random.default_rng(self.seed)

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
        img = img + self._rng.normal(0.0, self.noise, img.shape).astype(np.float32)
        return to_uint8(img)
