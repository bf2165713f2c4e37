"""Compiled loops of the alignment's inner steps, over a batch of placements.

Each step of the optimiser (Eq. 9 sweeps, the polish's normal equations, E_fit of many
candidates) maps every seam record's two midpoints into wallpaper space and asks for the
closest equivalent point. In NumPy that is a dozen (B, n, 2) temporaries per call, and
their allocation cost more than the query itself; here one loop does the mapping and calls
the single closest-point kernel (:func:`solver._closest.closest_pair`) per record.
"""

from __future__ import annotations

import numba
import numpy as np

from solver._closest import closest_pair


@numba.njit(cache=True, nogil=True)
def seam_closest(cos: np.ndarray, sin: np.ndarray, t: np.ndarray, rec: np.ndarray,
                 piece: np.ndarray, other: np.ndarray, mid: np.ndarray,
                 mid_other: np.ndarray, lin: np.ndarray, shift: np.ndarray, red: np.ndarray,
                 red_inv: np.ndarray, d_out: np.ndarray,
                 op_out: np.ndarray) -> None:  # pragma: no cover - compiled
    """Per placement b and record j: ``q_c = R_c^T (mid - t_c)``, ``q_o`` likewise on the
    twin side, then ``d_out[b, j]`` from q_c to the closest equivalent of q_o and
    ``op_out[b, j]`` its operation. ``cos, sin`` (B, P) hold the pieces' angles."""
    for b in range(t.shape[0]):
        for j in range(rec.shape[0]):
            r = rec[j]
            a, o = piece[r], other[r]
            xa, ya = mid[r, 0] - t[b, a, 0], mid[r, 1] - t[b, a, 1]
            xo, yo = mid_other[r, 0] - t[b, o, 0], mid_other[r, 1] - t[b, o, 1]
            ca, sa, co, so = cos[b, a], sin[b, a], cos[b, o], sin[b, o]
            dx, dy, k = closest_pair(ca * xa + sa * ya, ca * ya - sa * xa,
                                     co * xo + so * yo, co * yo - so * xo,
                                     lin, shift, red, red_inv)
            d_out[b, j, 0] = dx
            d_out[b, j, 1] = dy
            op_out[b, j] = k


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
