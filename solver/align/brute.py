"""Brute-force reference for small garments: a dense grid over every movable piece's
translation (one primitive cell each), rotations fixed, then local refinement of the
best grid points.

E_fit is a sum over seam edges, and each edge involves at most two pieces, so the
energy of every grid combination is a sum of per-piece and per-pair tables; the
combinations are summed by one compiled branch-and-bound loop, never edge by edge. Used by
the global method (few pieces), and by the tests and the benchmark to measure how far
the optimisers are from the global optimum.
"""

from __future__ import annotations

import numpy as np

from solver.align.kernels import grid_pair_sum, grid_step_offsets, joint_grid_best
from solver.align.problem import AlignProblem
from solver.align.refine import bfgs_refine, irls_translations
from solver.geometry import rotate_back

GRID = {1: 48, 2: 20, 3: 12, 4: 8}  # points per cell axis for 1..4 movable pieces


def cell_grid(problem: AlignProblem, angles, t_ref, c: int, k: int) -> np.ndarray:
    """(k*k,2) translations of piece c that shift its print by a k x k grid over a cell."""
    f = np.arange(k) / k
    cell = np.stack(np.meshgrid(f, f, indexing="ij"), -1).reshape(-1, 2) @ problem.wp.basis.T
    c_, s_ = np.cos(angles[c]), np.sin(angles[c])
    return t_ref[c] - cell @ np.array([[c_, -s_], [s_, c_]]).T


def grid_tables(problem: AlignProblem, angles: np.ndarray, t_ref: np.ndarray,
                movable: np.ndarray, k: int, pairs: set[tuple[int, int]] | None = None):
    """E_fit over the k x k cell grids of the ``movable`` pieces (the others at ``t_ref``)
    as ``unary`` (m, k*k) per piece and ``pair[(i, j)]`` (k*k, k*k), i < j indices into
    ``movable``: E_fit(x) = sum_i unary[i, x_i] + sum_(i,j) pair[i, j][x_i, x_j].
    ``pairs`` (index pairs i < j) limits the pair tables built (the others' seams are
    left out); the candidates (m, k*k, 2) are returned as the third value."""
    fr = problem.frames
    slot = {int(c): i for i, c in enumerate(movable)}
    cands = [cell_grid(problem, angles, t_ref, int(c), k) for c in movable]
    kk = k * k
    rec = np.arange(fr.n_edges)
    w = problem.weight * fr.length[rec]
    rec, w = rec[w > 0], w[w > 0]
    a, b = fr.piece[rec], fr.other[rec]
    unary = np.zeros((len(movable), kk))
    pair: dict[tuple[int, int], np.ndarray] = {}
    frac_lin = np.rint(problem.wp.info.ops[:, :, :2]).astype(np.int64)

    def q(piece, mids, tt):  # wallpaper points for translations tt (K,2) -> (K,n,2)
        return rotate_back(angles[piece], mids[None, :, :] - tt[:, None, :])

    for pa, pb in sorted({(int(x), int(y)) for x, y in zip(a, b)}):
        sel = (a == pa) & (b == pb)
        ma, mb, ws = fr.mid[rec[sel]], fr.mid_other[rec[sel]], w[sel]
        ia, ib = slot.get(pa), slot.get(pb)
        if ia is None and ib is None:
            continue
        if pa == pb or ia is None or ib is None:
            i = ia if ia is not None else ib
            ta = cands[i] if ia is not None else t_ref[pa][None]
            tb = cands[i] if ib is not None else t_ref[pb][None]
            d, _ = problem.mismatch(q(pa, ma, ta), q(pb, mb, tb))  # broadcast there
            unary[i] += np.hypot(d[..., 0], d[..., 1]) @ ws
            continue
        key = (min(ia, ib), max(ia, ib))
        if pairs is not None and key not in pairs:
            continue
        # grid offsets enter the wallpaper points as + W f (see cell_grid)
        offsets = np.empty((len(ws), len(frac_lin), kk, 2))
        grid_step_offsets(q(pa, ma, t_ref[pa][None])[0], q(pb, mb, t_ref[pb][None])[0],
                          *problem.wp.cartesian_tables, problem.wp.basis, k, offsets)
        reduced = problem.wp.lattice_residual(offsets)
        table = np.empty((kk, kk))
        grid_pair_sum(np.hypot(reduced[..., 0], reduced[..., 1]), ws, frac_lin, k, table)
        table = table if ia < ib else table.T
        pair[key] = pair.get(key, 0.0) + table
    return unary, pair, cands


def brute_force(problem: AlignProblem, angles: np.ndarray, t_ref: np.ndarray, *,
                grid: int | None = None, top: int = 8, polish: bool = True):
    """(translations (P,2), E_fit) of the best grid point after refinement (IRLS on the
    ``top`` grid points, then BFGS on the best two unless ``polish`` is False: a caller
    that polishes its own best candidates needs no second BFGS)."""
    movable = np.flatnonzero(~problem.fix_trans)
    m = len(movable)
    if m == 0:
        return t_ref.copy(), float(problem.energy(angles[None], t_ref[None])[0])
    if m > 4:
        raise ValueError(f"brute force needs at most 4 movable pieces, got {m}")
    k = grid or GRID[m]
    kk = k * k
    unary, pair, cands = grid_tables(problem, angles, t_ref, movable, k)
    # every combination, summed and bounded in one compiled loop (dummy pieces pad to 4)
    sizes = np.array([kk] * m + [1] * (4 - m), np.int64)
    u4 = np.zeros((4, kk))
    u4[:m] = unary
    p4 = np.zeros((4, 4, kk, kk if m > 1 else 1))
    for (i, j), table in pair.items():
        p4[i, j] = table
    vals, best_idx = joint_grid_best(u4, p4, sizes, top)
    best_idx = best_idx[np.isfinite(vals), :m]
    starts = np.repeat(t_ref[None], len(best_idx), axis=0)
    for i, c in enumerate(movable):
        starts[:, c] = cands[i][best_idx[:, i]]
    ang = np.repeat(angles[None], len(starts), axis=0)
    refined = irls_translations(problem, ang, starts)
    e = problem.energy(ang, refined)
    order = np.argsort(e)[:2 if polish else 0]
    best_t, best_e = refined[np.argmin(e)], float(e.min())
    for i in order:
        _, tt, ei = bfgs_refine(problem, angles, refined[i], rotations=False, max_iter=60)
        if ei < best_e:
            best_t, best_e = tt, ei
    return best_t, best_e
