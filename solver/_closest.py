"""The compiled closest-equivalent-point kernel behind :class:`solver.wallpaper.Wallpaper`.

Why compiled, and why this algorithm. Per pair the query must look at every operation of
the group (12 for p6m); for each it needs the lattice translation that brings the image
closest. With a Gauss-reduced basis ``u1, u2`` the cell they span splits along its shorter
diagonal into two non-obtuse (Delaunay) triangles, and a non-obtuse triangle is covered by
the Voronoi cells of its own corners; so the closest lattice point to any point is one of
the four corners of the reduced cell holding it (flooring the reduced fractional
coordinates), not one of the 3x3 block around a rounding. Working in those fractional
coordinates (the operations converted once per print), that is 4 candidates and ~30
flops per operation, all in registers. NumPy cannot run this without materialising
(N, n_ops, 4, 2) temporaries, which made the query memory-bound at 2-24 µs per pair; one
compiled loop over the pairs runs in 27-102 ns (``python -m bench wallpaper``). Numba is
the compiler: it installs from PyPI as a wheel, needs no C toolchain on the station, and
``cache=True`` keeps the one-off compile (~1 s) out of every later process. Compiled
callers live in this file only: numba's cache is keyed by each function's own file.

This module is imported lazily by :mod:`solver.wallpaper` (measured: importing numba
costs ~0.35 s, which ``station --help`` must not pay).
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True, nogil=True, inline="always")
def closest_pair(px: float, py: float, qx: float, qy: float, flin: np.ndarray,
                 fshift: np.ndarray, red: np.ndarray,
                 red_inv: np.ndarray) -> tuple[float, float, int]:  # pragma: no cover
    """One pair: the shortest ``g_k(q) + L - p`` (mm) over the operations and lattice
    vectors L, and its k (the first on ties). ``red`` holds the reduced basis as columns,
    ``red_inv`` its inverse; ``flin`` (n, 2, 2), ``fshift`` (n, 2) are the operations in
    the reduced basis' fractional coordinates (`Wallpaper.kernel_tables`).

    Per operation: the offset's fractional part in the reduced cell, then the squared
    distance to the cell's 4 corners in the basis' metric G, ``|a - c|_G^2 =
    |a|_G^2 - 2 c.Ga + |c|_G^2``, taken branch-free with ``min`` (random data mispredicts
    every compare-and-copy); the winner's vector is rebuilt in mm once.
    """
    r00, r01, r10, r11 = red[0, 0], red[0, 1], red[1, 0], red[1, 1]
    i00, i01, i10, i11 = red_inv[0, 0], red_inv[0, 1], red_inv[1, 0], red_inv[1, 1]
    g11, g22, g12 = r00 * r00 + r10 * r10, r01 * r01 + r11 * r11, r00 * r01 + r10 * r11
    g3 = g11 + 2.0 * g12 + g22  # |u1 + u2|^2
    fpx, fpy = i00 * px + i01 * py, i10 * px + i11 * py
    fqx, fqy = i00 * qx + i01 * qy, i10 * qx + i11 * qy
    best, bk = math.inf, 0
    for k in range(flin.shape[0]):
        fx = flin[k, 0, 0] * fqx + flin[k, 0, 1] * fqy + fshift[k, 0] - fpx
        fy = flin[k, 1, 0] * fqx + flin[k, 1, 1] * fqy + fshift[k, 1] - fpy
        ax, ay = fx - math.floor(fx), fy - math.floor(fy)
        gx, gy = g11 * ax + g12 * ay, g12 * ax + g22 * ay
        n = ax * gx + ay * gy
        m = min(min(n, n - 2.0 * gx + g11), min(n - 2.0 * gy + g22, n - 2.0 * (gx + gy) + g3))
        if m < best:
            best, bk = m, k
    fx = flin[bk, 0, 0] * fqx + flin[bk, 0, 1] * fqy + fshift[bk, 0] - fpx
    fy = flin[bk, 1, 0] * fqx + flin[bk, 1, 1] * fqy + fshift[bk, 1] - fpy
    ax, ay = fx - math.floor(fx), fy - math.floor(fy)
    # the four corners of the cell: 0, u1, u2, u1 + u2
    x, y = r00 * ax + r01 * ay, r10 * ax + r11 * ay
    cx, cy, dd = x, y, x * x + y * y
    for bx, by in ((x - r00, y - r10), (x - r01, y - r11), (x - r00 - r01, y - r10 - r11)):
        e = bx * bx + by * by
        if e < dd:
            cx, cy, dd = bx, by, e
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
