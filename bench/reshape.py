"""Benchmark of pattern reshaping (paper Sec. 5, Table 1 bottom rows) and its scaling.

Per Berkeley garment and print group: E_fit for a random placement (median of the
alignment's random starts), after the global alignment (solver.align, 15 starts as the
paper) and after reshaping; L initial/final; time. Then one garment refined by midpoint
subdivision from about 3k to about 200k faces.

    python -m bench reshape            # writes nothing; paste the tables into BENCHMARKS.md
"""

from __future__ import annotations

import os
import platform
import time
from pathlib import Path

import numpy as np

GARMENTS = Path(__file__).resolve().parents[2] / "shared" / "data" / "garments" / \
    "berkeley_garment_library" / "Garments"
BUNDLED = Path(__file__).resolve().parents[1] / "tests" / "data" / "garments" / "berkeley"
CASES = ["shorts/isotropic/shorts-iso.obj", "pants/isotropic/pants-iso.obj",
         "skirt/isotropic/skirt-iso.obj", "tshirt/isotropic/tshirt-iso.obj",
         "shirt/isotropic/shirt-iso.obj", "dress3/draped/dress3-iso-draped.obj"]
GROUPS = {"p4m": ((50.0, 0.0), (0.0, 50.0)), "pmm": ((50.0, 0.0), (0.0, 30.0)),
          "p6m": ((50.0, 0.0), (-25.0, 25.0 * 3**0.5))}


def subdivide(g):
    """Midpoint (1 -> 4) subdivision keeping seams: a new vertex per pattern edge, sewn
    to its twin through the pair of 3D points it lies between."""
    from solver.garment import build_garment

    f = g.faces
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    lo, hi = np.minimum(e[:, 0], e[:, 1]), np.maximum(e[:, 0], e[:, 1])
    key, inv = np.unique(lo * g.n_vertices + hi, return_inverse=True)
    a, b = key // g.n_vertices, key % g.n_vertices
    n = g.n_vertices
    mid = n + inv.reshape(3, -1).T  # (F,3): midpoints of edges 01, 12, 20
    uv = np.concatenate([g.uv, 0.5 * (g.uv[a] + g.uv[b])])
    pa, pb = g.point_of_vertex[a], g.point_of_vertex[b]
    n_pts = int(g.point_of_vertex.max()) + 1
    pkey = np.minimum(pa, pb) * n_pts + np.maximum(pa, pb)
    _, pnew = np.unique(pkey, return_inverse=True)
    point = np.concatenate([g.point_of_vertex, n_pts + pnew.ravel()])
    xyz = None
    if g.xyz is not None:
        xyz = np.concatenate([g.xyz, 0.5 * (g.xyz[a] + g.xyz[b])])
    faces = np.concatenate([
        np.column_stack([f[:, 0], mid[:, 0], mid[:, 2]]),
        np.column_stack([f[:, 1], mid[:, 1], mid[:, 0]]),
        np.column_stack([f[:, 2], mid[:, 2], mid[:, 1]]),
        mid,
    ])
    return build_garment(uv, faces, point, xyz=xyz, source=g.source + " (subdivided)",
                         kind=g.kind)


def _align(g, wp, restarts=15):
    from solver.align.problem import AlignProblem
    from solver.align.restarts import align_paper
    from solver.placement import Placement

    res = align_paper(AlignProblem.build(g, wp), restarts=restarts, seed=0)
    return Placement(res.angles, res.translations, wp), float(np.median(res.random_energies))


def main() -> None:
    """Both tables; RESHAPE_BENCH=scaling or =garments runs one of them;
    RESHAPE_BENCH_LEVELS=3 stops the scaling run at ~48k faces."""
    which = os.environ.get("RESHAPE_BENCH", "all")
    if which in ("all", "garments"):
        garments_table()
    if which in ("all", "scaling"):
        scaling_table()


def garments_table() -> None:
    from solver.garment import load_garment
    from solver.reshape import reshape
    from solver.wallpaper import Wallpaper

    print(f"# bench/reshape.py  {time.strftime('%Y-%m-%d %H:%M')}  "
          f"{platform.processor() or platform.machine()}  {os.cpu_count()} cores, "
          f"load average {os.getloadavg()[0]:.1f} (wall time inflates with load; CPU time "
          "is the process's own)")
    cases = [GARMENTS / c for c in CASES] if GARMENTS.is_dir() else [BUNDLED / "shorts-iso.obj"]
    print("| garment | faces | group | E_fit random cm² | aligned cm² | reshaped cm² | "
          "reshaped/random | L init cm | L final cm | eps cm | γ rounds | iterations | "
          "max move mm | flips | reshape wall s | reshape CPU s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for path in cases:
        g = load_garment(path, units="m")
        for group, (w1, w2) in GROUPS.items():
            wp = Wallpaper(group, w1, w2)
            placement, e_random = _align(g, wp)
            cpu = time.process_time()
            _, r = reshape(g, placement)
            cpu = time.process_time() - cpu
            print(f"| {path.stem} | {len(g.faces)} | {group} | {e_random / 100:.1f} | "
                  f"{r.e_fit_before_mm2 / 100:.1f} | {r.e_fit_after_mm2 / 100:.1f} | "
                  f"{r.e_fit_after_mm2 / e_random:.3f} | "
                  f"{r.length_mismatch_initial_mm / 10:.2f} | "
                  f"{r.length_mismatch_final_mm / 10:.2f} | {r.epsilon_mm / 10:.2f} | "
                  f"{r.gamma_rounds} | {r.iterations} | {r.max_displacement_mm:.1f} | "
                  f"{r.flipped_triangles} | {r.seconds:.2f} | {cpu:.2f} |", flush=True)


def scaling_table() -> None:
    """One garment, p4m, refined by midpoint subdivision from ~3k to ~200k faces."""
    from solver.garment import load_garment
    from solver.reshape import reshape
    from solver.wallpaper import Wallpaper

    print("\n| faces | vertices | E_fit aligned cm² | reshaped cm² | γ rounds | iterations | "
          "factorisations | flips | reshape wall s | reshape CPU s | CPU s per 1k faces |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    base = GARMENTS / CASES[0] if GARMENTS.is_dir() else BUNDLED / "shorts-iso.obj"
    g = load_garment(base, units="m")
    wp = Wallpaper("p4m", *GROUPS["p4m"])
    placement, _ = _align(g, wp, restarts=5)
    for level in range(int(os.environ.get("RESHAPE_BENCH_LEVELS", "4"))):
        if level:
            g = subdivide(g)
        cpu = time.process_time()
        _, r = reshape(g, placement)
        cpu = time.process_time() - cpu
        print(f"| {len(g.faces)} | {g.n_vertices} | {r.e_fit_before_mm2 / 100:.1f} | "
              f"{r.e_fit_after_mm2 / 100:.1f} | {r.gamma_rounds} | {r.iterations} | "
              f"{r.factorisations} | {r.flipped_triangles} | {r.seconds:.2f} | {cpu:.2f} | "
              f"{1000 * cpu / len(g.faces):.3f} |", flush=True)


if __name__ == "__main__":
    main()
