"""Translational alignment, paper Sec. 4.2: Eq. (9) with the rotations fixed.

Driver ``optimise_translations``, state ``TranslationState``, one sweep
``translation_step``, batched over random starts.

Eq. (9) moves piece c against the weighted mean mismatch of its seam edges,
``t_c <- t_c + (1/w_c) sum w_S l_e d(v_e)``, with ``d`` pointing away from c. Our ``d`` is
measured in wallpaper space (``Wallpaper.mismatch``, from piece c's point to the closest
equivalent of the twin's point); since ``p_wp = R_c^T (p2D - t_c)``, moving c's point by
``+d`` in wallpaper space means ``t_c <- t_c - R_c d``. The update is a sum over the
piece's edges, so evaluating it for all edges at once *is* the paper's update; pieces
sharing no seam are updated together (same as visiting them in sequence).

Eq. (9) is exact block-coordinate descent on ``E2 = sum_e w_S l_e |d_e|^2`` (each block
is one piece's translation): for a fixed choice of closest equivalent point per edge,
E2 is a convex quadratic and Eq. (9) converges linearly to its minimiser. Once the
iteration has settled (``sum_c |t_c - t_c'|^2 < eps``), ``polish`` jumps to that limit by
solving the quadratic's normal equations, and the sweeps resume if the choice of
equivalent points changed. That is the converged Eq. (9), reached in fewer sweeps.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from solver.align.kernels import translation_normal_equations
from solver.align.problem import AlignProblem
from solver.geometry import rotate

EPS_TRANS = 1e-4  # mm^2; the polish then jumps to the exact limit


@dataclass
class TranslationState:
    """Batch of translations ``t`` (B,P,2) with the rotations ``angles`` (B,P) fixed."""

    angles: np.ndarray
    t: np.ndarray
    iterations: np.ndarray
    converged: np.ndarray
    plan: list = field(default_factory=list, repr=False)


def init_translations(problem: AlignProblem, angles, t) -> TranslationState:
    angles = np.atleast_2d(np.asarray(angles, float))
    t = np.asarray(t, float).reshape(len(angles), problem.n_pieces, 2).copy()
    b = len(angles)
    plan = problem.sweep_plan(problem.fix_trans, normalise=True)
    return TranslationState(angles=angles, t=t, iterations=np.zeros(b, int),
                            converged=np.zeros(b, bool), plan=plan)


def translation_step(problem: AlignProblem, state: TranslationState,
                     eps: float = EPS_TRANS) -> bool:
    """One Gauss-Seidel sweep of Eq. (9) for the unconverged starts; True when all are."""
    active = ~state.converged
    if not active.any() or not state.plan:
        state.converged[:] = True
        return True
    ang, t = state.angles[active], state.t[active]
    before = t.copy()
    for pieces, rec, mean in state.plan:
        d, _ = problem.seam_mismatch(ang, t, rec)
        step = mean @ d  # (B,k,2) mean mismatch of each piece, wallpaper space
        t[:, pieces] -= rotate(ang[:, pieces], step)
    change = np.sum((t - before) ** 2, axis=(1, 2))
    state.t[active] = t
    state.iterations[active] += 1
    done = np.zeros_like(state.converged)
    done[active] = change < eps
    state.converged |= done
    return bool(state.converged.all())


def energy2(problem: AlignProblem, angles: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(B,) E2 = sum over live twin pairs of w_S l_e |d_e|^2, the quantity Eq. (9) lowers."""
    rec = problem.live_records()
    rec = rec[rec < problem.frames.n_edges]
    d, _ = problem.seam_mismatch(angles, t, rec)
    return (d[..., 0] ** 2 + d[..., 1] ** 2) @ problem.record_weight[rec]


def polish(problem: AlignProblem, angles: np.ndarray, t: np.ndarray,
           weight: np.ndarray | None = None) -> np.ndarray:
    """Minimiser of E2 over the movable translations, closest points held fixed.

    ``weight`` (B,n) optionally replaces w_S l_e per live twin pair (IRLS uses this to
    minimise E_fit itself). Returns new translations (B,P,2).
    """
    fr, p = problem.frames, problem.n_pieces
    rec = problem.live_records()
    rec = rec[rec < fr.n_edges]
    if len(rec) == 0:
        return t.copy()
    d, op = problem.seam_mismatch(angles, t, rec)
    w = np.broadcast_to(problem.record_weight[rec][None, :] if weight is None else weight,
                        (len(t), len(rec)))
    w = np.require(w, float, ["C", "W"])  # numba warns on broadcasting's read-only views
    h = np.zeros((len(t), 2 * p, 2 * p))
    g = np.zeros((len(t), 2 * p))
    translation_normal_equations(np.cos(angles), np.sin(angles), rec, fr.piece, fr.other, d,
                                 op, problem.wp.cartesian_tables[0], w, h, g)
    fixed = np.repeat(problem.fix_trans, 2)
    scale = float(np.mean(np.abs(np.diagonal(h, axis1=1, axis2=2)))) or 1.0
    h = h + 1e-10 * scale * np.eye(2 * p)  # the pattern may slide freely (p1): pick the
    h[:, fixed, :] = 0.0  # least move
    h[:, :, fixed] = 0.0
    h[:, fixed, fixed] = 1.0
    g[:, fixed] = 0.0
    step = np.linalg.solve(h, -g[..., None])[..., 0]
    return t + step.reshape(len(t), p, 2)


def optimise_translations(problem: AlignProblem, angles: np.ndarray, t0: np.ndarray, *,
                          max_iter: int = 300, eps: float = EPS_TRANS,
                          polish_rounds: int = 8, polish_every: int = 5) -> TranslationState:
    """Eq. (9) to convergence from ``t0`` (B,P,2) with ``angles`` (B,P) fixed.

    Every ``polish_every`` sweeps (and at convergence) the iteration jumps to the limit
    for the current choice of closest points (``polish``); the jump is kept only where
    it lowers E2, and the sweeps go on until they no longer move anything.
    """
    state = init_translations(problem, angles, t0)
    rounds = 0
    for it in range(max_iter):
        done = translation_step(problem, state, eps)
        if (done or (it + 1) % polish_every == 0) and rounds < polish_rounds:
            rounds += 1
            e_before = energy2(problem, state.angles, state.t)
            cand = polish(problem, state.angles, state.t)
            better = energy2(problem, state.angles, cand) < e_before * (1 - 1e-12)
            state.t[better] = cand[better]
            state.converged[better] = False
            done = done and not better.any()
        if done:
            break
    return state
