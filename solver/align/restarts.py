"""The paper's alignment (Sec. 4.3): rotations, then translations, from N random starts,
keeping the start with the lowest E_fit.

All starts run side by side (a batch axis), seeded, so the result is reproducible.
Pieces fixed by the user keep their given rotation and/or translation exactly.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from solver.align.problem import AlignProblem
from solver.align.rotation import optimise_rotations
from solver.align.translation import optimise_translations

#: Rotation stop criterion. The paper stops at 1e-7 (rotation.EPS_ROT); that leaves angle
#: errors of ~3e-4 rad, a tenth of a millimetre across a 300 mm piece, which shows in
#: E_fit. A few more sweeps (typically 3 to 30 in all) reach 1e-14.
ROTATION_EPS = 1e-14


@dataclass
class AlignResult:
    """Best placement of a run and what it took."""

    angles: np.ndarray  # (P,) radians
    translations: np.ndarray  # (P,2) mm
    energy: float  # objective E_fit (user weights) of the best start, mm^2
    energies: np.ndarray  # (N,) E_fit of every start after alignment
    random_energies: np.ndarray  # (N,) E_fit of every random start
    rotation_iterations: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    translation_iterations: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    all_angles: np.ndarray | None = None  # (N,P) every start's result (for the global method)
    all_translations: np.ndarray | None = None  # (N,P,2)
    info: dict = field(default_factory=dict)


def enforce_fixed(problem: AlignProblem, angles: np.ndarray, t: np.ndarray):
    """Put the fixed pieces back bit for bit (guards against rounding in any step)."""
    angles = np.where(problem.fix_rot, problem.init_angles, angles)
    t = np.where(problem.fix_trans[:, None], problem.init_translations, t)
    return angles, t


def align_paper(problem: AlignProblem, *, restarts: int = 15, seed: int = 0,
                rotation: bool = True, translation: bool = True,
                rotation_eps: float = ROTATION_EPS, progress=None) -> AlignResult:
    """The paper's optimiser from ``restarts`` random starts (seeded).

    ``rotation``/``translation`` False keep that part at the problem's ``init`` values
    (the user sets it by hand). ``progress(k, n, e_random, e_aligned)`` is called once per
    start when it finishes.
    """
    if restarts < 1:
        raise ValueError(f"restarts must be at least 1, got {restarts}")
    rng = np.random.default_rng(seed)
    ang0, t0 = problem.random_starts(rng, restarts)
    if not rotation:
        ang0 = np.broadcast_to(problem.init_angles, ang0.shape).copy()
    if not translation:
        t0 = np.broadcast_to(problem.init_translations, t0.shape).copy()
    e_random = problem.energy(ang0, t0)
    rot_iter = np.zeros(restarts, int)
    ang = ang0
    if rotation:
        rs = optimise_rotations(problem, ang0, eps=rotation_eps)
        ang, rot_iter = rs.angles, rs.iterations
        ang = np.where(problem.fix_rot, problem.init_angles, ang)
    t, trans_iter = t0, np.zeros(restarts, int)
    if translation:
        ts = optimise_translations(problem, ang, t0)
        t, trans_iter = ts.t, ts.iterations
    ang, t = enforce_fixed(problem, ang, t)
    energies = problem.energy(ang, t)
    if progress is not None:
        for k in range(restarts):
            progress(k + 1, restarts, float(e_random[k]), float(energies[k]))
    best = int(np.argmin(energies))
    return AlignResult(
        angles=ang[best].copy(), translations=t[best].copy(), energy=float(energies[best]),
        energies=energies, random_energies=e_random, rotation_iterations=rot_iter,
        translation_iterations=trans_iter, all_angles=ang, all_translations=t,
        info={"best_start": best, "random_angles": ang0, "random_translations": t0},
    )
