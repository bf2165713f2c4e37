"""Closest-equivalent-point query (`Wallpaper.closest`): ns per pair, all 17 groups.

Every E_fit evaluation, alignment step, ideal seam and lattice snap rests on this query.
Measured in the same run, on the same pairs:

- **kernel**: `Wallpaper.closest` (the compiled kernel of :mod:`solver._closest`);
- **bound**: a compiled loop over the classic candidates, every operation x the 3x3
  block of lattice translations around a rounding in the reduced basis (the issue's
  "lower bound"); the kernel needs only the 4 corners of the reduced cell, so it may
  beat it;
- **floor**: a compiled loop that only applies every operation and takes the shortest
  image (no lattice reduction at all): no exact query can do less work per pair;
- **old**: the NumPy kernel that alignment used before (4 corners, batched arrays);
- **brute**: NumPy enumeration of every operation and a 7x7 block of translations around
  a naive rounding, on the first `N_BRUTE` pairs, for the agreement check.

    python -m bench wallpaper
"""

from __future__ import annotations

import math
import os
import platform
import time
from datetime import datetime, timezone

import numba
import numpy as np

from solver.wallpaper import GROUP_NAMES, GROUPS, Wallpaper, gauss_reduce

N = 200_000
N_BRUTE = 20_000


def lattice_for(group: str) -> tuple[np.ndarray, np.ndarray]:
    lattice = GROUPS[group].lattice
    a = np.array([40.0, 0.0])
    b = {"oblique": [12.0, 35.0], "rectangular": [0.0, 55.0], "rhombic": [14.0, 37.4833],
         "square": [0.0, 40.0], "hexagonal": [-20.0, 34.641016]}[lattice]
    if lattice == "rhombic":
        b = np.array(b) / np.hypot(*b) * 40.0
    return a, np.asarray(b, float)


def brute_force(wp: Wallpaper, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    k = np.arange(-3, 4)
    shifts = np.stack(np.meshgrid(k, k), -1).reshape(-1, 2) @ wp.basis.T
    eq = wp.equivalent_points(q)
    eq = eq - np.round(wp.to_fractional(eq) - wp.to_fractional(p)[:, None]) @ wp.basis.T
    d = (eq[:, :, None, :] + shifts[None, None] - p[:, None, None, :]).reshape(len(p), -1, 2)
    return np.sqrt(np.min(np.einsum("pki,pki->pk", d, d), axis=1))


@numba.njit(cache=True)
def _bound_3x3(p, q, lin, shift, red, red_inv, out):  # pragma: no cover - compiled
    """Every operation x the 3x3 lattice block around the rounding: shortest distance."""
    for i in range(p.shape[0]):
        best = math.inf
        for k in range(lin.shape[0]):
            ox = lin[k, 0, 0] * q[i, 0] + lin[k, 0, 1] * q[i, 1] + shift[k, 0] - p[i, 0]
            oy = lin[k, 1, 0] * q[i, 0] + lin[k, 1, 1] * q[i, 1] + shift[k, 1] - p[i, 1]
            f1 = math.floor(red_inv[0, 0] * ox + red_inv[0, 1] * oy + 0.5)
            f2 = math.floor(red_inv[1, 0] * ox + red_inv[1, 1] * oy + 0.5)
            for a in range(-1, 2):
                for b in range(-1, 2):
                    x = ox - (f1 + a) * red[0, 0] - (f2 + b) * red[0, 1]
                    y = oy - (f1 + a) * red[1, 0] - (f2 + b) * red[1, 1]
                    best = min(best, x * x + y * y)
        out[i] = math.sqrt(best)


@numba.njit(cache=True)
def _floor_ops_only(p, q, lin, shift, out):  # pragma: no cover - compiled
    """Apply every operation, keep the shortest offset: the work no exact query avoids."""
    for i in range(p.shape[0]):
        best = math.inf
        for k in range(lin.shape[0]):
            ox = lin[k, 0, 0] * q[i, 0] + lin[k, 0, 1] * q[i, 1] + shift[k, 0] - p[i, 0]
            oy = lin[k, 1, 0] * q[i, 0] + lin[k, 1, 1] * q[i, 1] + shift[k, 1] - p[i, 1]
            best = min(best, ox * ox + oy * oy)
        out[i] = math.sqrt(best)


def old_numpy_kernel(wp: Wallpaper, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The alignment's former NumPy query (4 corners of the reduced cell, batched)."""
    ops = wp.cartesian_ops()
    lin, sh = ops[:, :2, :2], ops[:, :2, 2]
    r1, r2, _ = gauss_reduce(wp.w1, wp.w2)
    r = np.column_stack([r1, r2])
    ri = np.linalg.inv(r).T
    corners = np.array([[0, 0], [1, 0], [0, 1], [1, 1]], float) @ r.T
    px, py, qx, qy = p[:, :1], p[:, 1:], q[:, :1], q[:, 1:]
    dx = qx * lin[:, 0, 0] + qy * lin[:, 0, 1] + sh[:, 0] - px
    dy = qx * lin[:, 1, 0] + qy * lin[:, 1, 1] + sh[:, 1] - py
    f1 = np.floor(dx * ri[0, 0] + dy * ri[1, 0])
    f2 = np.floor(dx * ri[0, 1] + dy * ri[1, 1])
    bx = dx - f1 * r[0, 0] - f2 * r[0, 1]
    by = dy - f1 * r[1, 0] - f2 * r[1, 1]
    cx, cy = bx[..., None] - corners[:, 0], by[..., None] - corners[:, 1]
    return np.sqrt((cx * cx + cy * cy).reshape(len(p), -1).min(axis=1))


def best_of(f, *args, repeat: int = 7) -> float:
    """Least CPU time of ``repeat`` calls: on a shared machine the wall clock also counts
    the time other jobs hold the core, CPU time only this process's work."""
    times = []
    for _ in range(repeat):
        t0 = time.process_time()
        f(*args)
        times.append(time.process_time() - t0)
    return min(times)


def main() -> None:
    rng = np.random.default_rng(0)
    print(f"bench/wallpaper.py, {datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC, "
          f"{platform.machine()} {os.cpu_count()} cores, load {os.getloadavg()[0]:.2f}, "
          f"Python {platform.python_version()}, numba {numba.__version__}; "
          f"{N // 1000}k pairs in [-500, 500]² mm, least CPU time of 7 runs")
    print("| group | ops | kernel ns/pair | bound ns/pair (ops x 3x3) | floor ns/pair (ops only) "
          "| kernel/bound | kernel/floor | old NumPy ns/pair | old/kernel | brute ns/pair "
          "| brute/kernel | max abs diff mm |")
    print("|" + "---|" * 12)
    worst_bound, worst_floor = 0.0, 0.0
    for group in GROUP_NAMES:
        wp = Wallpaper(group, *lattice_for(group), origin=(3.0, -2.0))
        p, q = rng.uniform(-500, 500, (2, N, 2))
        ops = wp.cartesian_ops()
        lin = np.ascontiguousarray(ops[:, :2, :2])
        shift = np.ascontiguousarray(ops[:, :2, 2])
        r1, r2, _ = gauss_reduce(wp.w1, wp.w2)
        red = np.column_stack([r1, r2])
        red_inv = np.linalg.inv(red)
        out = np.empty(N)
        wp.closest(p[:10], q[:10])  # compile / load the caches outside the clock
        _bound_3x3(p[:10], q[:10], lin, shift, red, red_inv, out[:10])
        _floor_ops_only(p[:10], q[:10], lin, shift, out[:10])
        t_kernel = best_of(wp.closest, p, q)
        t_bound = best_of(_bound_3x3, p, q, lin, shift, red, red_inv, out)
        bound_dist = out.copy()
        t_floor = best_of(_floor_ops_only, p, q, lin, shift, out)
        t_old = best_of(old_numpy_kernel, wp, p, q, repeat=3)
        pb, qb = p[:N_BRUTE], q[:N_BRUTE]
        t_brute = best_of(brute_force, wp, pb, qb, repeat=1) * N / N_BRUTE
        d, _ = wp.closest(p, q)
        dist = np.hypot(d[:, 0], d[:, 1])
        diff = max(np.max(np.abs(dist[:N_BRUTE] - brute_force(wp, pb, qb))),
                   np.max(np.abs(dist - bound_dist)),
                   np.max(np.abs(dist - old_numpy_kernel(wp, p, q))))
        ns = 1e9 / N
        worst_bound = max(worst_bound, t_kernel / t_bound)
        worst_floor = max(worst_floor, t_kernel / t_floor)
        print(f"| {group} | {wp.n_equivalent} | {ns * t_kernel:.0f} | {ns * t_bound:.0f} "
              f"| {ns * t_floor:.0f} | {t_kernel / t_bound:.2f} | {t_kernel / t_floor:.2f} "
              f"| {ns * t_old:.0f} | {t_old / t_kernel:.0f}x | {ns * t_brute:.0f} "
              f"| {t_brute / t_kernel:.0f}x | {diff:.1e} |", flush=True)
    print(f"\nworst kernel/bound {worst_bound:.2f}, worst kernel/floor {worst_floor:.2f}")


if __name__ == "__main__":
    main()
