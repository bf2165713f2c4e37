"""Compiled loops of the alignment's inner steps, over a batch of placements.

Each step of the optimiser (Eq. 9 sweeps, the polish's normal equations, E_fit of many
candidates) maps every seam record's two midpoints into wallpaper space and asks for the
closest equivalent point. In NumPy the mapping alone is a dozen (B, n, 2) temporaries per
call, which cost more than the query; here one loop does it, and the query is
`Wallpaper.closest`. No kernel here calls the closest-point kernel itself: numba's cache
is keyed by each function's own file, so a compiled caller in another file would keep a
stale copy of it after a change.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def seam_points(cos: np.ndarray, sin: np.ndarray, t: np.ndarray, rec: np.ndarray,
                piece: np.ndarray, other: np.ndarray, mid: np.ndarray, mid_other: np.ndarray,
                qc_out: np.ndarray, qo_out: np.ndarray) -> None:  # pragma: no cover
    """Per placement b and record j, both midpoints in wallpaper space:
    ``q_c = R_c^T (mid - t_c)`` and ``q_o = R_o^T (mid_other - t_o)``, (B, n, 2) each.
    ``cos, sin`` (B, P) hold the pieces' angles."""
    for b in range(t.shape[0]):
        for j in range(rec.shape[0]):
            r = rec[j]
            a, o = piece[r], other[r]
            xa, ya = mid[r, 0] - t[b, a, 0], mid[r, 1] - t[b, a, 1]
            xo, yo = mid_other[r, 0] - t[b, o, 0], mid_other[r, 1] - t[b, o, 1]
            ca, sa, co, so = cos[b, a], sin[b, a], cos[b, o], sin[b, o]
            qc_out[b, j, 0] = ca * xa + sa * ya
            qc_out[b, j, 1] = ca * ya - sa * xa
            qo_out[b, j, 0] = co * xo + so * yo
            qo_out[b, j, 1] = co * yo - so * xo


@numba.njit(cache=True, nogil=True)
def translation_normal_equations(cos: np.ndarray, sin: np.ndarray, rec: np.ndarray,
                                 piece: np.ndarray, other: np.ndarray, d: np.ndarray,
                                 op: np.ndarray, lin: np.ndarray, w: np.ndarray,
                                 h: np.ndarray, g: np.ndarray) -> None:  # pragma: no cover
    """Gauss-Newton system of ``sum_j w_j |d_j|^2`` in the translations, added into
    ``h`` (B, 2P, 2P) and ``g`` (B, 2P): ``d(d)/d(t_a) = R_a^T``,
    ``d(d)/d(t_o) = -M R_o^T`` with M the linear part of the record's operation."""
    for b in range(d.shape[0]):
        for j in range(rec.shape[0]):
            r = rec[j]
            a, o = piece[r], other[r]
            wj = w[b, j]
            ca, sa, co, so = cos[b, a], sin[b, a], cos[b, o], sin[b, o]
            m = lin[op[b, j]]
            # ja = R_a^T, jb = -M R_o^T (2x2 each)
            ja00, ja01, ja10, ja11 = ca, sa, -sa, ca
            jb00 = -(m[0, 0] * co + m[0, 1] * -so)
            jb01 = -(m[0, 0] * so + m[0, 1] * co)
            jb10 = -(m[1, 0] * co + m[1, 1] * -so)
            jb11 = -(m[1, 0] * so + m[1, 1] * co)
            dx, dy = d[b, j, 0], d[b, j, 1]
            ia, io = 2 * a, 2 * o
            jas = ((ja00, ja01), (ja10, ja11))
            jbs = ((jb00, jb01), (jb10, jb11))
            for u in range(2):
                g[b, ia + u] += wj * (jas[0][u] * dx + jas[1][u] * dy)
                g[b, io + u] += wj * (jbs[0][u] * dx + jbs[1][u] * dy)
                for v in range(2):
                    aa = jas[0][u] * jas[0][v] + jas[1][u] * jas[1][v]
                    bb = jbs[0][u] * jbs[0][v] + jbs[1][u] * jbs[1][v]
                    ab = jas[0][u] * jbs[0][v] + jas[1][u] * jbs[1][v]
                    h[b, ia + u, ia + v] += wj * aa
                    h[b, io + u, io + v] += wj * bb
                    h[b, ia + u, io + v] += wj * ab
                    h[b, io + v, ia + u] += wj * ab


@numba.njit(cache=True, nogil=True)
def rotation_class_update(r: np.ndarray, pieces: np.ndarray, rec: np.ndarray,
                          piece: np.ndarray, other: np.ndarray, a_mat: np.ndarray,
                          c_mat: np.ndarray, a_inv: np.ndarray, w: np.ndarray, rosy: int,
                          reflect: bool) -> None:  # pragma: no cover - compiled
    """Eqs. (4)-(6) (and (8) with ``reflect``) for one colour class of pieces, in place on
    ``r`` (B, P, 2): every record j pulls its piece by ``w_j A_inv target_j``, with
    ``target_j`` the r-RoSy turn of ``v = C r_o`` closest to ``u = A r_c``; then each
    piece's sum is normalised (a zero sum keeps the old field)."""
    step = 2.0 * np.pi / rosy
    acc = np.zeros((r.shape[1], 2))
    for b in range(r.shape[0]):
        for k in range(pieces.shape[0]):
            acc[pieces[k], 0] = 0.0
            acc[pieces[k], 1] = 0.0
        for j in range(rec.shape[0]):
            e = rec[j]
            c, o = piece[e], other[e]
            ux = a_mat[e, 0, 0] * r[b, c, 0] + a_mat[e, 0, 1] * r[b, c, 1]
            uy = a_mat[e, 1, 0] * r[b, c, 0] + a_mat[e, 1, 1] * r[b, c, 1]
            vx = c_mat[e, 0, 0] * r[b, o, 0] + c_mat[e, 0, 1] * r[b, o, 1]
            vy = c_mat[e, 1, 0] * r[b, o, 0] + c_mat[e, 1, 1] * r[b, o, 1]
            tx, ty = 0.0, 0.0
            for side in range(2 if reflect else 1):
                sy = vy if side == 0 else -vy  # the mirror about the seam edge, Eq. (8)
                phi = np.arctan2(ux * sy - uy * vx, ux * vx + uy * sy)
                turn = step * np.round(-phi / step)
                ct, st = np.cos(turn), np.sin(turn)
                tx += ct * vx - st * sy
                ty += st * vx + ct * sy
            wj = w[e]
            acc[c, 0] += wj * (a_inv[e, 0, 0] * tx + a_inv[e, 0, 1] * ty)
            acc[c, 1] += wj * (a_inv[e, 1, 0] * tx + a_inv[e, 1, 1] * ty)
        for k in range(pieces.shape[0]):
            pc = pieces[k]
            nx, ny = r[b, pc, 0] + acc[pc, 0], r[b, pc, 1] + acc[pc, 1]
            norm = np.hypot(nx, ny)
            if norm > 1e-300:
                r[b, pc, 0] = nx / norm
                r[b, pc, 1] = ny / norm


@numba.njit(cache=True, nogil=True)
def joint_grid_best(unary: np.ndarray, pair: np.ndarray, sizes: np.ndarray,
                    top: int) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover
    """The ``top`` lowest sums ``sum_i unary[i, x_i] + sum_{i<j} pair[i, j, x_i, x_j]`` over
    every combination of up to four pieces' candidates ``x_i < sizes[i]`` (unused pieces:
    size 1, zero tables). Exact: branch and bound on the last piece with the row minima
    of its tables, so most of the ``prod(sizes)`` combinations are never summed.
    Returns values (top,) ascending and the combinations (top, 4)."""
    vals = np.full(top, np.inf)
    idx = np.zeros((top, 4), np.int64)
    n0, n1, n2, n3 = sizes[0], sizes[1], sizes[2], sizes[3]
    u3min = np.min(unary[3, :n3])
    row03 = np.empty(n0)
    row13 = np.empty(n1)
    row23 = np.empty(n2)
    for i in range(n0):
        row03[i] = np.min(pair[0, 3, i, :n3])
    for i in range(n1):
        row13[i] = np.min(pair[1, 3, i, :n3])
    for i in range(n2):
        row23[i] = np.min(pair[2, 3, i, :n3])
    for i0 in range(n0):
        a0 = unary[0, i0]
        for i1 in range(n1):
            a1 = a0 + unary[1, i1] + pair[0, 1, i0, i1]
            for i2 in range(n2):
                a2 = a1 + unary[2, i2] + pair[0, 2, i0, i2] + pair[1, 2, i1, i2]
                if a2 + u3min + row03[i0] + row13[i1] + row23[i2] >= vals[top - 1]:
                    continue
                for i3 in range(n3):
                    v = (a2 + unary[3, i3] + pair[0, 3, i0, i3] + pair[1, 3, i1, i3]
                         + pair[2, 3, i2, i3])
                    if v < vals[top - 1]:
                        k = top - 1
                        while k > 0 and vals[k - 1] > v:
                            vals[k] = vals[k - 1]
                            idx[k] = idx[k - 1]
                            k -= 1
                        vals[k] = v
                        idx[k, 0], idx[k, 1], idx[k, 2], idx[k, 3] = i0, i1, i2, i3
    return vals, idx


@numba.njit(cache=True, nogil=True)
def grid_step_offsets(qa: np.ndarray, qb: np.ndarray, lin: np.ndarray, shift: np.ndarray,
                      basis: np.ndarray, k: int, out: np.ndarray) -> None:  # pragma: no cover
    """``out[j, m, s]`` = ``g_m(qb_j) - qa_j + W f_s`` (mm) for every record j, operation m
    (``lin``, ``shift`` in mm) and grid step ``f_s = (s // k, s % k) / k``, W = ``basis``.

    Operation m maps ``qb + W f_b`` to ``g_m(qb) + W F_m f_b`` (F_m integer: the point group
    keeps the lattice), so its offset from ``qa + W f_a`` depends on the step
    ``F_m f_b - f_a`` modulo the lattice alone: k^2 offsets per record and operation stand
    for all (k^2)^2 pairs of grid points (`grid_pair_sum`)."""
    for j in range(qa.shape[0]):
        for m in range(lin.shape[0]):
            gx = lin[m, 0, 0] * qb[j, 0] + lin[m, 0, 1] * qb[j, 1] + shift[m, 0] - qa[j, 0]
            gy = lin[m, 1, 0] * qb[j, 0] + lin[m, 1, 1] * qb[j, 1] + shift[m, 1] - qa[j, 1]
            for s in range(k * k):
                fx, fy = (s // k) / k, (s % k) / k
                out[j, m, s, 0] = gx + basis[0, 0] * fx + basis[0, 1] * fy
                out[j, m, s, 1] = gy + basis[1, 0] * fx + basis[1, 1] * fy


@numba.njit(cache=True, nogil=True)
def grid_pair_sum(dist: np.ndarray, ws: np.ndarray, frac_lin: np.ndarray, k: int,
                  out: np.ndarray) -> None:  # pragma: no cover - compiled
    """``out[x_a, x_b]`` = sum_j ws_j min_m dist[j, m, step_m(x_a, x_b)] over the k x k grids
    of two pieces (index i k + j), ``step_m = F_m f_b - f_a`` modulo 1 (``frac_lin`` = F_m):
    E_fit of their seams for every pair of grid points, from `grid_step_offsets`' table of
    lattice-reduced distances."""
    n, n_ops, kk = dist.shape[0], dist.shape[1], k * k
    step = np.empty(n_ops, np.int64)
    for xa in range(kk):
        ai, aj = xa // k, xa % k
        for xb in range(kk):
            bi, bj = xb // k, xb % k
            for m in range(n_ops):
                si = (frac_lin[m, 0, 0] * bi + frac_lin[m, 0, 1] * bj - ai) % k
                sj = (frac_lin[m, 1, 0] * bi + frac_lin[m, 1, 1] * bj - aj) % k
                step[m] = si * k + sj
            total = 0.0
            for j in range(n):
                best = dist[j, 0, step[0]]
                for m in range(1, n_ops):
                    best = min(best, dist[j, m, step[m]])
                total += ws[j] * best
            out[xa, xb] = total
