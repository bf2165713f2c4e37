"""Closest-equivalent-point query (`Wallpaper.mismatch`) against brute force, all 17 groups.

Every E_fit evaluation, alignment step and ideal seam rests on this query. The baseline,
in the same run, enumerates every operation and a 7x7 block of lattice translations
around a naive rounding (exact only near the cell; it is here for the speed ratio and the
agreement check, not as a reference for far points).
"""

from __future__ import annotations

import time

import numpy as np

from solver.wallpaper import GROUP_NAMES, GROUPS, Wallpaper

N = 100_000


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


def best_of(f, repeat: int = 3) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    rng = np.random.default_rng(0)
    print(f"| group | n ops | mismatch ms per {N // 1000}k pairs | brute force ms | ratio | "
          "max |difference| mm |")
    print("|---|---|---|---|---|---|")
    for group in GROUP_NAMES:
        wp = Wallpaper(group, *lattice_for(group), origin=(3.0, -2.0))
        p, q = rng.uniform(-500, 500, (2, N, 2))
        fast = best_of(lambda wp=wp, p=p, q=q: wp.mismatch_distance(p, q))
        slow = best_of(lambda wp=wp, p=p, q=q: brute_force(wp, p, q), repeat=1)
        diff = np.max(np.abs(wp.mismatch_distance(p, q) - brute_force(wp, p, q)))
        print(f"| {group} | {wp.n_equivalent} | {1e3 * fast:.1f} | {1e3 * slow:.1f} | "
              f"{slow / fast:.1f}x | {diff:.1e} |", flush=True)


if __name__ == "__main__":
    main()
