"""Grain lines: woven fabric is cut on grain, so a piece may only take a few rotations
relative to the print.

The print's grain is the wallpaper's vertical axis ``(0, 1)``; on piece ``c`` it points
along ``R_c (0, 1)``, i.e. at angle ``theta_c + 90°`` in pattern space. The piece's grain
line points at ``gamma_c`` (from the input's grain line, else the pattern's vertical
axis, ``gamma_c = 90°``). The rotation of the piece relative to the print is
``theta_c + 90° - gamma_c`` and must lie within ``tol`` of one of ``allowed`` (default
0° and 180°).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


@dataclass(frozen=True)
class GrainRule:
    """Allowed placement angles per piece: ``centres`` (P,m) radians, half-width ``tol``;
    ``base`` (P,) is the placement angle at which the print runs along the grain line."""

    centres: np.ndarray
    tol: float
    base: np.ndarray

    @classmethod
    def from_garment(cls, garment, tol_deg: float = 2.0,
                     allowed_deg: tuple[float, ...] = (0.0, 180.0)) -> GrainRule:
        if not np.isfinite(tol_deg) or tol_deg < 0:
            raise ValueError(f"grain tolerance must be >= 0 degrees, got {tol_deg}")
        p = garment.n_pieces
        gamma = np.full(p, np.pi / 2)
        for piece, line in (getattr(garment, "grainlines", None) or {}).items():
            (x0, y0), (x1, y1) = line
            if 0 <= int(piece) < p and (x1 - x0, y1 - y0) != (0, 0):
                gamma[int(piece)] = np.arctan2(y1 - y0, x1 - x0)
        allowed = np.radians(np.asarray(allowed_deg, float))
        centres = gamma[:, None] - np.pi / 2 + allowed[None, :]
        return cls(centres=centres, tol=float(np.radians(tol_deg)), base=gamma - np.pi / 2)

    def relative_deg(self, angles: np.ndarray) -> np.ndarray:
        """(...,P) rotation of each piece relative to the print, degrees in (-180, 180]."""
        return np.degrees(_wrap(angles - self.base))

    def violation(self, angles: np.ndarray) -> np.ndarray:
        """(...,P) radians by which each angle lies outside its nearest allowed interval."""
        dist = np.abs(_wrap(angles[..., None] - self.centres))
        return np.maximum(dist.min(axis=-1) - self.tol, 0.0)

    def project(self, angles: np.ndarray, rosy: int, fixed: np.ndarray | None = None):
        """Nearest allowed angle among the r-RoSy equivalents ``angle + 2 pi k / r``.

        The rotational step only knows each angle up to the print's r-fold rotation, so
        any equivalent may be used; the translational step then absorbs the change of
        rotation centre. Fixed pieces are returned unchanged.
        """
        angles = np.asarray(angles, float)
        k = 2 * np.pi * np.arange(rosy) / rosy
        cand = angles[..., None] + k  # (...,P,r)
        diff = _wrap(cand[..., None] - self.centres[:, None, :])  # (...,P,r,m)
        clamped = np.clip(diff, -self.tol, self.tol)
        move = np.abs(diff - clamped)
        flat = move.reshape(*move.shape[:-2], -1)
        best = np.argmin(flat, axis=-1)
        km = best % self.centres.shape[1]
        centre = np.take_along_axis(
            np.broadcast_to(self.centres, move.shape[:-3] + self.centres.shape),
            km[..., None], -1)[..., 0]
        off = np.take_along_axis(
            clamped.reshape(*move.shape[:-2], -1), best[..., None], -1)[..., 0]
        out = centre + off
        if fixed is not None:
            out = np.where(fixed, angles, out)
        return out

    def project_subset(self, angles: np.ndarray, pieces: np.ndarray, rosy: int) -> np.ndarray:
        """``project`` for the angles (...,k) of the pieces ``pieces`` (k,) only."""
        sub = GrainRule(centres=self.centres[pieces], tol=self.tol, base=self.base[pieces])
        return sub.project(angles, rosy)
