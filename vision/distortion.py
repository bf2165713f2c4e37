"""How badly the fabric lies: local lattices on a coarse grid, skew and bow.

Woven checks and plaids are often spread skewed (weft lines tilted against the warp)
or bowed (weft lines sagging across the width). Cutting a matched garment from such
cloth puts the print off the seams however well the pieces are placed, so the operator
is warned above a tolerance. The local lattice of each tile is the global one refined
on the tile's own autocorrelation (the same least-squares fit on many peaks as the
global detection), so a tile needs only about three repeats across.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from vision.autocorrelation import autocorrelation
from vision.basis import refine_basis
from vision.lattice import LatticeResult
from vision.prepare import prepare_image

__all__ = ["Distortion", "angle_between", "local_lattices", "measure_distortion"]


@dataclass
class Distortion:
    """Local lattices and the spreading faults they reveal (mm, degrees)."""

    centres: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  # (K,2) mm
    w1: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  # (K,2) local w1 mm
    w2: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    skew_deg: float = 0.0
    bow_mm: float = 0.0
    max_strain: float = 0.0
    warning: str | None = None
    perspective: dict | None = None  # vision.perspective.View.to_dict(), when one was found

    def to_dict(self) -> dict:
        return {"skew_deg": round(self.skew_deg, 3), "bow_mm": round(self.bow_mm, 3),
                "max_strain": round(self.max_strain, 5), "warning": self.warning,
                "perspective": self.perspective,
                "grid": [{"centre": c.round(3).tolist(), "w1": a.round(4).tolist(),
                          "w2": b.round(4).tolist()}
                         for c, a, b in zip(self.centres, self.w1, self.w2, strict=True)]}


def angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle between the rows of a and b, degrees."""
    cos = np.sum(a * b, axis=-1) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
    return np.degrees(np.arccos(np.clip(cos, -1, 1)))


def local_lattices(flat: np.ndarray, basis: np.ndarray, *, grid: int = 3
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The lattice of each square tile of a ``grid x grid`` array over the working
    image ``flat``, refined from the global ``basis`` (columns w1, w2, working (x, y) px).
    Returns tile centres (K, 2) and bases (K, 2, 2) in working px, each vector's sign
    that of the global one; tiles under about three repeats across are left out."""
    h, w = flat.shape
    longest = float(np.linalg.norm(basis, axis=0).max())
    # Tiles of at least three repeats, overlapping where the image is too small for a
    # grid of separate ones (a view's change shows only between distinct centres).
    side = int(min(min(h, w), max(min(h, w) / grid, 3.0 * longest)))
    ys = np.unique(np.linspace(0, h - side, grid).astype(int))
    xs = np.unique(np.linspace(0, w - side, grid).astype(int))
    centres, bases = [], []
    rc_basis = basis[::-1]  # (row, col) rows for the peak fit
    for y0 in ys:
        for x0 in xs:
            tile = flat[y0:y0 + side, x0:x0 + side]
            if side < 2.5 * longest:
                continue
            acf, wacf = autocorrelation(cv2.GaussianBlur(tile, (0, 0), 1.0))
            b, _, used = refine_basis(acf, wacf > 0.25, rc_basis.copy(), rounds=2)
            if used < 3:
                continue
            loc = b[::-1]  # back to (x, y)
            loc = loc * np.sign(np.sum(loc * basis, axis=0))[None, :]
            centres.append([x0 + (side - 1) / 2, y0 + (side - 1) / 2])
            bases.append(loc)
    return np.array(centres).reshape(-1, 2), np.array(bases).reshape(-1, 2, 2)


def measure_distortion(image: np.ndarray, lattice: LatticeResult, *, grid: int = 3,
                       ideal_angle: float | None = None, skew_tol_deg: float = 1.0,
                       bow_tol_mm: float = 3.0, work_side: int = 1024,
                       prepared: tuple[np.ndarray, float] | None = None,
                       local: tuple[np.ndarray, np.ndarray] | None = None) -> Distortion:
    """Local lattice on a ``grid x grid`` array of tiles; skew, bow and a warning.

    Parameters
    ----------
    lattice : LatticeResult
        The global lattice of the same image.
    ideal_angle : float, optional
        The angle w1-w2 the print should have (90 for checks); skew is the departure
        from it. Default: the global angle (skew then measures only its variation).
    skew_tol_deg, bow_tol_mm : float
        The operator's tolerances; above either, ``warning`` says what is wrong.
    local : (centres, bases), optional
        :func:`local_lattices` of the same working image, when already measured.
    """
    if not lattice.found:
        return Distortion()
    flat, scale = prepared or prepare_image(image, work_side=work_side)
    mm = lattice.mm_per_px
    px_mm = mm / scale
    if local is None:
        local = local_lattices(flat, lattice.basis / px_mm, grid=grid)
    centres, bases = local
    if not len(centres):
        return Distortion(warning=None)
    c = ((np.asarray(centres) + 0.5) / scale - 0.5) * mm
    l1, l2 = bases[:, :, 0] * px_mm, bases[:, :, 1] * px_mm
    g1, g2 = lattice.w1, lattice.w2
    angles = angle_between(l1, l2)
    ideal = angle_between(g1[None], g2[None])[0] if ideal_angle is None else float(ideal_angle)
    skew = float(np.median(angles) - ideal)
    strain = max(float(np.max(np.linalg.norm(l1 - g1, axis=1) / np.linalg.norm(g1))),
                 float(np.max(np.linalg.norm(l2 - g2, axis=1) / np.linalg.norm(g2))))
    bow = _bow(c, l1, l2, g1, g2, np.array([image.shape[1], image.shape[0]], float) * mm)
    warning = None
    faults = []
    if abs(skew) > skew_tol_deg:
        faults.append(f"skew {skew:.2f} deg exceeds {skew_tol_deg:g} deg")
    if abs(bow) > bow_tol_mm:
        faults.append(f"bow {bow:.1f} mm exceeds {bow_tol_mm:g} mm")
    if faults:
        warning = "fabric lies distorted: " + "; ".join(faults) + " (straighten the cloth)"
    return Distortion(c, l1, l2, skew, bow, strain, warning)


def _bow(c: np.ndarray, l1: np.ndarray, l2: np.ndarray, g1: np.ndarray, g2: np.ndarray,
         ext: np.ndarray) -> float:
    """The larger sag (mm) of the lines along w1 and along w2, from the local lattices
    (l1, l2 at centres ``c``) against the global (g1, g2), over the image extent ``ext``
    (mm): lines along w_k turn as one moves along w_k (a parabola's slope changes
    linearly); the sag at mid-width is d(slope)/ds * L^2 / 8."""
    bow = 0.0
    for loc, glob in ((l1, g1), (l2, g2)):
        if len(loc) < 3:
            break
        u = glob / np.linalg.norm(glob)
        nrm = np.array([-u[1], u[0]])
        slope = (loc @ nrm) / (loc @ u)  # tan of the local turn against the global
        s = c @ u
        if np.ptp(s) < 1e-9:
            continue
        k = np.polyfit(s, slope, 1)[0]
        length = float(abs(ext @ np.abs(u)))
        sag = k * length**2 / 8.0
        if abs(sag) > abs(bow):
            bow = float(sag)
    return bow
