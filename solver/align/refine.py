"""Continuous refinement of E_fit itself (not the squared proxy of Eq. 9).

``irls_translations``: iteratively reweighted least squares, ``w_S l_e / |d_e|`` as the
weights of the Eq. (9) quadratic, whose fixed points are the stationary points of E_fit
in the translations (Weiszfeld's scheme). ``bfgs_refine``: quasi-Newton (BFGS) over all
movable angles and translations with the analytic gradient, grain limits built into
the parametrisation.
Both only ever return a placement that is at least as good as the one given.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.optimize import minimize

from solver.align.problem import AlignProblem
from solver.align.translation import polish
from solver.geometry import rotation_matrices


def irls_translations(problem: AlignProblem, angles: np.ndarray, t: np.ndarray,
                      iterations: int = 15) -> np.ndarray:
    """(B,P,2) translations lowering E_fit, batched; never worse than ``t``."""
    fr = problem.frames
    rec = problem.live_records()
    rec = rec[rec < fr.n_edges]
    best_t, best_e = t.copy(), problem.energy(angles, t)
    cur = t.copy()
    for _ in range(iterations):
        d, _ = problem.seam_mismatch(angles, cur, rec)
        dist = np.hypot(d[..., 0], d[..., 1])
        floor = 1e-9 * max(float(np.abs(problem.wp.basis).max()), 1.0)
        w = problem.record_weight[rec][None, :] / np.maximum(dist, floor)
        cur = polish(problem, angles, cur, weight=w)
        e = problem.energy(angles, cur)
        better = e < best_e
        gain = np.max((best_e - e) / np.maximum(best_e, 1e-300))
        best_t[better], best_e[better] = cur[better], e[better]
        if not better.any() or gain < 1e-7:
            break
    return best_t


def _energy_grad(problem: AlignProblem, angles, t, rec, w):
    """E_fit over records ``rec`` (side a) and its gradient in angles (P,) and t (P,2)."""
    fr = problem.frames
    a, b = fr.piece[rec], fr.other[rec]
    ra, rb = rotation_matrices(angles[a]), rotation_matrices(angles[b])
    xa, xb = fr.mid[rec] - t[a], fr.mid_other[rec] - t[b]
    d, op = problem.seam_mismatch(angles[None], t[None], rec)
    d, op = d[0], op[0]
    m = problem.wp.cartesian_ops()[:, :2, :2][op]
    dist = np.hypot(d[:, 0], d[:, 1])
    e = float(np.sum(w * dist))
    unit = w[:, None] * d / np.where(dist > 1e-12, dist, np.inf)[:, None]
    # d = M q_o + c - q_c;  q = R^T x;  dR^T/dtheta x = R^T J^T x with J = [[0,-1],[1,0]]
    perp = np.array([[0.0, 1.0], [-1.0, 0.0]])
    dqa_dth = np.einsum("nji,nj->ni", ra, xa @ perp.T)
    dqb_dth = np.einsum("nji,nj->ni", rb, xb @ perp.T)
    g_ang = np.zeros(problem.n_pieces)
    np.add.at(g_ang, a, -np.sum(unit * dqa_dth, 1))
    np.add.at(g_ang, b, np.sum(unit * np.einsum("nij,nj->ni", m, dqb_dth), 1))
    g_t = np.zeros((problem.n_pieces, 2))
    np.add.at(g_t, a, np.einsum("nij,nj->ni", ra, unit))  # d(-q_a)/dt_a = R_a^T
    np.add.at(g_t, b, -np.einsum("nij,nj->ni", rb, np.einsum("nji,nj->ni", m, unit)))
    return e, g_ang, g_t


def bfgs_refine(problem: AlignProblem, angles: np.ndarray, t: np.ndarray, *,
                 rotations: bool = True, max_iter: int = 200,
                 objective: Callable[[np.ndarray, np.ndarray], tuple] | None = None):
    """Joint local descent on E_fit of one placement; returns (angles, t, energy).

    ``objective(angles, t) -> (e, g_angles, g_t)`` replaces the problem's own E_fit (the
    problem still gives the unknowns, their grain limits and fixed pieces): symmetric
    placement descends on the E_fit of the whole garment over the quotient's unknowns.
    """
    fr = problem.frames
    rec = np.arange(fr.n_edges)
    w = problem.weight * fr.length[rec]
    rec, w = rec[w > 0], w[w > 0]
    if objective is None:
        def objective(a, tt):
            return _energy_grad(problem, a, tt, rec, w)
    free_a = ~problem.fix_rot if rotations else np.zeros(problem.n_pieces, bool)
    free_t = ~problem.fix_trans
    ia, it = np.flatnonzero(free_a), np.flatnonzero(free_t)
    e0 = objective(angles, t)[0]
    if len(rec) == 0 or (len(ia) == 0 and len(it) == 0):
        return angles, t, e0
    # grain limits: theta = c + tol sin(phi) keeps every angle inside its interval
    centre, tol = np.zeros(len(ia)), 1.0
    grain = problem.grain is not None and len(ia) > 0
    if grain:
        cen = problem.grain.centres[ia]
        k = np.argmin(np.abs((angles[ia, None] - cen + np.pi) % (2 * np.pi) - np.pi), axis=1)
        c = cen[np.arange(len(ia)), k]
        centre = angles[ia] + ((c - angles[ia] + np.pi) % (2 * np.pi) - np.pi)
        tol = max(problem.grain.tol, 1e-12)
        phi0 = np.arcsin(np.clip((angles[ia] - centre) / tol, -1, 1))
        x0 = np.concatenate([phi0, t[it].ravel()])
    else:
        x0 = np.concatenate([angles[ia], t[it].ravel()])

    def unpack(x):
        a, tt = angles.copy(), t.copy()
        a[ia] = centre + tol * np.sin(x[: len(ia)]) if grain else x[: len(ia)]
        tt[it] = x[len(ia):].reshape(-1, 2)
        return a, tt

    def fun(x):
        a, tt = unpack(x)
        e, ga, gt = objective(a, tt)
        if grain:
            ga[ia] *= tol * np.cos(x[: len(ia)])
        return e, np.concatenate([ga[ia], gt[it].ravel()])

    # BFGS (NumPy only): L-BFGS-B's Fortran core stalls on BLAS threads on a busy machine
    res = minimize(fun, x0, jac=True, method="BFGS", options={"maxiter": max_iter})
    a, tt = unpack(res.x)
    e = objective(a, tt)[0]
    if e < e0:
        return a, tt, e
    return angles, t, e0
