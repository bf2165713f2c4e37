"""Cutting on grain: each piece's grain line lies along the fabric's grain, so a piece may
take only a few rotations relative to the print.

The fabric's grain runs at ``fabric_grain_deg`` in fabric (= wallpaper) space, by default 0
(the roll's length, fabric x). With ``p2D = R(theta) p_wp + t`` it appears on piece ``c`` at
``theta_c + fabric_grain``; the piece's grain (``solver.garment.grain``) points at
``gamma_c``. The piece's turn relative to the fabric grain, ``theta_c + fabric_grain -
gamma_c``, must lie within ``tol`` of an allowed turn: 0 or 180 degrees, 0 only with a nap
(one-way prints, pile), and for a bias piece 45 degrees more (both diagonals; with a nap the
two whose grain still points along the roll).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

STRAIGHT = (0.0, 180.0)
NAP = (0.0,)
BIAS = (45.0, 135.0, 225.0, 315.0)
BIAS_NAP = (45.0, 315.0)


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


def allowed_turns(bias: bool, nap: bool) -> tuple[float, ...]:
    """Allowed turns (degrees) of a piece's grain relative to the fabric's grain."""
    if bias:
        return BIAS_NAP if nap else BIAS
    return NAP if nap else STRAIGHT


@dataclass(frozen=True)
class GrainRule:
    """Allowed placement angles per piece: ``centres`` (P,m) radians, half-width ``tol``;
    ``base`` (P,) is the placement angle at which the piece's grain runs along the
    fabric's grain (pieces with fewer allowed turns repeat their last centre)."""

    centres: np.ndarray
    tol: float
    base: np.ndarray

    @classmethod
    def from_garment(cls, garment, tol_deg: float = 1.0, *, nap: bool = False,
                     fabric_grain_deg: float = 0.0) -> GrainRule:
        """The rule for ``garment.grains()`` on a fabric whose grain is at
        ``fabric_grain_deg``."""
        if not np.isfinite(tol_deg) or tol_deg < 0:
            raise ValueError(f"grain tolerance must be >= 0 degrees, got {tol_deg}")
        if not np.isfinite(fabric_grain_deg):
            raise ValueError("the fabric's grain direction must be finite")
        grains = garment.grains()
        gamma = np.radians([g.deg for g in grains])
        base = gamma - np.radians(fabric_grain_deg)
        turns = [allowed_turns(g.bias, nap) for g in grains]
        m = max(len(t) for t in turns)
        table = np.radians([list(t) + [t[-1]] * (m - len(t)) for t in turns])
        # a hair inside the tolerance, so that angles written in degrees and checked
        # again after rounding still lie within it
        return cls(centres=base[:, None] + table, tol=float(np.radians(tol_deg)) * (1 - 1e-7),
                   base=base)

    def relative_deg(self, angles: np.ndarray) -> np.ndarray:
        """(...,P) turn of each piece's grain from the fabric's grain, degrees in (-180, 180]."""
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
