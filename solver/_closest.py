"""The compiled closest-equivalent-point kernel behind :class:`solver.wallpaper.Wallpaper`.

Why compiled, and why this algorithm. Per pair the query must look at every operation of
the group (12 for p6m); for each it needs the lattice translation that brings the image
closest. With a Gauss-reduced basis ``u1, u2`` the cell they span splits along its shorter
diagonal into two non-obtuse (Delaunay) triangles, and a non-obtuse triangle is covered by
the Voronoi cells of its own corners; so the closest lattice point to any point is one of
the four corners of the reduced cell holding it (flooring the reduced fractional
coordinates), not one of the 3x3 block around a rounding. That is 4 candidates per
operation, ~40 flops, all in registers. NumPy cannot run this without materialising
(N, n_ops, 4, 2) temporaries, which made the query memory-bound at 2-24 µs per pair; one
compiled loop over the pairs keeps everything in registers and runs in tens of
nanoseconds (``python -m bench wallpaper``). Numba is the compiler: it installs from PyPI
as a wheel, needs no C toolchain on the station, and ``cache=True`` keeps the one-off
compile (~1 s) out of every later process.

This module is imported lazily by :mod:`solver.wallpaper` (measured: importing numba
costs ~0.35 s, which ``station --help`` must not pay).
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True, nogil=True, inline="always")
def _reduce(ox: float, oy: float, r00: float, r01: float, r10: float, r11: float,
            i00: float, i01: float, i10: float, i11: float) -> tuple[float, float]:
    """The offset moved into the reduced cell [0, 1)^2 spanned by u1, u2 (by flooring)."""
    f1 = math.floor(i00 * ox + i01 * oy)
    f2 = math.floor(i10 * ox + i11 * oy)
    return ox - f1 * r00 - f2 * r01, oy - f1 * r10 - f2 * r11


@numba.njit(cache=True, nogil=True, inline="always")
def closest_pair(px: float, py: float, qx: float, qy: float, lin: np.ndarray,
                 shift: np.ndarray, red: np.ndarray,
                 red_inv: np.ndarray) -> tuple[float, float, int]:  # pragma: no cover
    """One pair: the shortest ``g_k(q) + L - p`` over the operations
    ``g_k(x) = lin[k] x + shift[k]`` and lattice vectors L, and its k (the first on ties).
    ``red`` holds the reduced basis as columns, ``red_inv`` its inverse.

    The loop over the operations only keeps squared distances, taken branch-free with
    ``min`` from ``|x - c|^2 = |x|^2 - 2 x.c + |c|^2`` (random data mispredicts every
    compare-and-copy); the winner's vector is then rebuilt once.
    """
    r00, r01, r10, r11 = red[0, 0], red[0, 1], red[1, 0], red[1, 1]
    i00, i01, i10, i11 = red_inv[0, 0], red_inv[0, 1], red_inv[1, 0], red_inv[1, 1]
    s0, s1 = r00 + r01, r10 + r11  # u1 + u2
    g1, g2, g3 = r00 * r00 + r10 * r10, r01 * r01 + r11 * r11, s0 * s0 + s1 * s1
    best, bk = math.inf, 0
    for k in range(lin.shape[0]):
        ox = lin[k, 0, 0] * qx + lin[k, 0, 1] * qy + shift[k, 0] - px
        oy = lin[k, 1, 0] * qx + lin[k, 1, 1] * qy + shift[k, 1] - py
        x, y = _reduce(ox, oy, r00, r01, r10, r11, i00, i01, i10, i11)
        n = x * x + y * y
        b1 = 2.0 * (x * r00 + y * r10)
        b2 = 2.0 * (x * r01 + y * r11)
        m = min(min(n, n - b1 + g1), min(n - b2 + g2, n - b1 - b2 + g3))
        if m < best:
            best, bk = m, k
    ox = lin[bk, 0, 0] * qx + lin[bk, 0, 1] * qy + shift[bk, 0] - px
    oy = lin[bk, 1, 0] * qx + lin[bk, 1, 1] * qy + shift[bk, 1] - py
    x, y = _reduce(ox, oy, r00, r01, r10, r11, i00, i01, i10, i11)
    # the four corners of the cell: 0, u1, u2, u1 + u2
    cx, cy, dd = x, y, x * x + y * y
    for ax, ay in ((x - r00, y - r10), (x - r01, y - r11), (x - s0, y - s1)):
        e = ax * ax + ay * ay
        if e < dd:
            cx, cy, dd = ax, ay, e
    return cx, cy, bk


@numba.njit(cache=True, nogil=True)
def closest_equivalent(p: np.ndarray, q: np.ndarray, lin: np.ndarray, shift: np.ndarray,
                       red: np.ndarray, red_inv: np.ndarray, d_out: np.ndarray,
                       op_out: np.ndarray) -> None:  # pragma: no cover - compiled
    """`closest_pair` for every row of ``p, q`` (N, 2) into ``d_out`` (N, 2), ``op_out``."""
    for i in range(p.shape[0]):
        dx, dy, k = closest_pair(p[i, 0], p[i, 1], q[i, 0], q[i, 1], lin, shift, red,
                                 red_inv)
        d_out[i, 0] = dx
        d_out[i, 1] = dy
        op_out[i] = k
