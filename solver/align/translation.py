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

from solver.align.problem import AlignProblem, apply_r, rot

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
        q_c, q_o = problem.wallpaper_points(ang, t, rec)
        d, _ = problem.mismatch(q_c, q_o)
        step = mean @ d  # (B,k,2) mean mismatch of each piece, wallpaper space
        t[:, pieces] -= apply_r(ang[:, pieces], step)
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
    q_c, q_o = problem.wallpaper_points(angles, t, rec)
    d, _ = problem.mismatch(q_c, q_o)
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
    q_c, q_o = problem.wallpaper_points(angles, t, rec)
    d, op = problem.mismatch(q_c, q_o)
    m = problem.wp.cartesian_ops()[:, :2, :2][op]  # (B,n,2,2)
    a, b = fr.piece[rec], fr.other[rec]
    ja = np.swapaxes(rot(angles[:, a]), -1, -2)  # d(d)/d(t_a) = R_a^T
    jb = -m @ np.swapaxes(rot(angles[:, b]), -1, -2)  # d(d)/d(t_b) = -M R_b^T
    w = problem.record_weight[rec][None, :] if weight is None else weight
    nb, n = len(t), len(rec)
    jat, jbt = np.swapaxes(ja, -1, -2), np.swapaxes(jb, -1, -2)
    wv = w[..., None, None] * np.ones((nb, n, 1, 1))
    # blocks (B,n,2,2) scattered into the (P,P) block matrix by one sparse-like product
    blocks = np.stack([wv * (jat @ ja), wv * (jbt @ jb), wv * (jat @ jb), wv * (jbt @ ja)])
    slot = np.concatenate([a * p + a, b * p + b, a * p + b, b * p + a])
    flat = np.moveaxis(blocks, 0, 1).reshape(nb, 4 * n, 4)
    h = _scatter_sum(flat, slot, p * p).reshape(nb, p, p, 2, 2)  # (B,P,P,2,2)
    h = h.transpose(0, 1, 3, 2, 4).reshape(nb, 2 * p, 2 * p)
    ga = wv[..., 0] * np.einsum("bnji,bnj->bni", ja, d)
    gb = wv[..., 0] * np.einsum("bnji,bnj->bni", jb, d)
    g = _scatter_sum(np.concatenate([ga, gb], axis=1), np.concatenate([a, b]), p)
    g = g.reshape(nb, 2 * p)
    fixed = np.repeat(problem.fix_trans, 2)
    scale = float(np.mean(np.abs(np.diagonal(h, axis1=1, axis2=2)))) or 1.0
    h = h + 1e-10 * scale * np.eye(2 * p)  # the pattern may slide freely (p1): pick the
    h[:, fixed, :] = 0.0  # least move
    h[:, :, fixed] = 0.0
    h[:, fixed, fixed] = 1.0
    g[:, fixed] = 0.0
    step = np.linalg.solve(h, -g[..., None])[..., 0]
    return t + step.reshape(len(t), p, 2)


def _scatter_sum(values: np.ndarray, slot: np.ndarray, n_slots: int) -> np.ndarray:
    """(B,k,c) values summed into (B,n_slots,c) by ``slot`` (k,), with bincount."""
    nb, k, c = values.shape
    idx = (np.arange(nb)[:, None] * n_slots + slot[None, :]).ravel()
    out = np.stack([np.bincount(idx, weights=values[..., j].ravel(), minlength=nb * n_slots)
                    for j in range(c)], -1)
    return out.reshape(nb, n_slots, c)


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
