"""Brute-force reference for small garments: a dense grid over every movable piece's
translation (one primitive cell each), rotations fixed, then local refinement of the
best grid points.

E_fit is a sum over seam edges, and each edge involves at most two pieces, so the
energy of every grid combination is a sum of per-piece and per-pair tables; the
combinations are summed in chunks, never edge by edge. Used by the tests and the
benchmark to measure how far the optimisers are from the global optimum.
"""

from __future__ import annotations

import numpy as np

from solver.align.problem import AlignProblem, apply_rt
from solver.align.refine import bfgs_refine, irls_translations

GRID = {1: 48, 2: 20, 3: 12, 4: 8}  # points per cell axis for 1..4 movable pieces


def _grid(problem: AlignProblem, angles, t_ref, c: int, k: int) -> np.ndarray:
    """(k*k,2) translations of piece c that shift its print by a k x k grid over a cell."""
    f = np.arange(k) / k
    cell = np.stack(np.meshgrid(f, f, indexing="ij"), -1).reshape(-1, 2) @ problem.wp.basis.T
    c_, s_ = np.cos(angles[c]), np.sin(angles[c])
    return t_ref[c] - cell @ np.array([[c_, -s_], [s_, c_]]).T


def brute_force(problem: AlignProblem, angles: np.ndarray, t_ref: np.ndarray, *,
                grid: int | None = None, top: int = 8):
    """(translations (P,2), E_fit) of the best grid point after refinement."""
    fr = problem.frames
    movable = np.flatnonzero(~problem.fix_trans)
    m = len(movable)
    if m == 0:
        return t_ref.copy(), float(problem.energy(angles[None], t_ref[None])[0])
    if m > 4:
        raise ValueError(f"brute force needs at most 4 movable pieces, got {m}")
    k = grid or GRID[m]
    slot = {int(c): i for i, c in enumerate(movable)}
    cands = [_grid(problem, angles, t_ref, int(c), k) for c in movable]
    kk = k * k
    rec = np.arange(fr.n_edges)
    w = problem.weight * fr.length[rec]
    rec, w = rec[w > 0], w[w > 0]
    a, b = fr.piece[rec], fr.other[rec]
    unary = [np.zeros(kk) for _ in movable]
    pair: dict[tuple[int, int], np.ndarray] = {}

    def q(piece, mids, tt):  # wallpaper points for translations tt (K,2) -> (K,n,2)
        return apply_rt(angles[piece], mids[None, :, :] - tt[:, None, :])

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
            d, _ = problem.mismatch(*np.broadcast_arrays(q(pa, ma, ta), q(pb, mb, tb)))
            unary[i] += np.hypot(d[..., 0], d[..., 1]) @ ws
            continue
        qa_all, qb_all = q(pa, ma, cands[ia]), q(pb, mb, cands[ib])
        table = np.empty((kk, kk))
        rows = max(1, 200_000 // (kk * len(ws)))  # bound the memory of one chunk
        for r0 in range(0, kk, rows):
            qa = np.broadcast_to(qa_all[r0:r0 + rows, None], (len(qa_all[r0:r0 + rows]), kk,
                                                               len(ws), 2))
            qb = np.broadcast_to(qb_all[None, :], qa.shape)
            d, _ = problem.mismatch(qa, qb)
            table[r0:r0 + rows] = np.hypot(d[..., 0], d[..., 1]) @ ws
        key = (min(ia, ib), max(ia, ib))
        table = table if ia < ib else table.T
        pair[key] = pair.get(key, 0.0) + table
    # sum over all combinations, chunked over the first movable piece
    shape = (kk,) * m

    def expand(arr, axes):
        sh = [1] * m
        for ax, n in zip(axes, arr.shape):
            sh[ax] = n
        return arr.reshape(sh)

    best_vals, best_idx = np.zeros(0), np.zeros((0, m), int)
    for i0 in range(kk):
        total = np.zeros(shape[1:]) if m > 1 else np.zeros(())
        total = total + unary[0][i0]
        for i in range(1, m):
            total = total + expand(unary[i], [i])[0]
        for (i, j), table in pair.items():
            if i == 0:
                total = total + expand(table[i0], [j])[0]
            else:
                total = total + expand(table, [i, j])[0]
        flat = np.ravel(total)
        n_keep = min(top, flat.size)
        part = np.argpartition(flat, n_keep - 1)[:n_keep]
        idx = np.column_stack([np.full(n_keep, i0), *np.unravel_index(part, shape[1:])]) \
            if m > 1 else np.full((n_keep, 1), i0)
        best_vals = np.concatenate([best_vals, flat[part]])
        best_idx = np.concatenate([best_idx, idx])
        keep = np.argsort(best_vals, kind="stable")[:top]
        best_vals, best_idx = best_vals[keep], best_idx[keep]
    starts = np.repeat(t_ref[None], len(best_idx), axis=0)
    for i, c in enumerate(movable):
        starts[:, c] = cands[i][best_idx[:, i]]
    ang = np.repeat(angles[None], len(starts), axis=0)
    refined = irls_translations(problem, ang, starts)
    e = problem.energy(ang, refined)
    order = np.argsort(e)[:2]
    best_t, best_e = refined[order[0]], float(e[order[0]])
    for i in order:
        _, tt, ei = bfgs_refine(problem, angles, refined[i], rotations=False, max_iter=60)
        if ei < best_e:
            best_t, best_e = tt, ei
    return best_t, best_e
