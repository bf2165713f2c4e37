"""Alignment benchmark (issue 3): the paper's method against the global method.

For every Berkeley garment with an isotropic or draped mesh and two GarmentCode
patterns (2D-only), under prints of groups p1, pmm, pgg, cmm, p4m, p6m with repeats
from 30 to 100 mm: E_fit of the random starts (mean), after the paper's method and
after the global method (mm² and cm²), the ratio aligned/random (paper Table 1:
0.41-0.69), the time for 15 restarts, and where at most four pieces move the gap to a
brute-force optimum (joint grid over all translations, rotations of the global result).

    python -m bench align            # full table (about 10-20 minutes on 2 cores)
    BENCH_ALIGN_QUICK=1 python -m bench align   # two garments, for a smoke run
    BENCH_ALIGN_ONLY=vest,pants python -m bench align   # only garments whose path matches
    BENCH_ALIGN_TIMING=1 python -m bench align   # only the timings on the 10k-face dress
"""

from __future__ import annotations

import os
import platform
import time
from datetime import date
from pathlib import Path

import numpy as np

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "garments"
BERKELEY = [
    "tshirt/isotropic/tshirt-iso.obj", "shirt/isotropic/shirt-iso.obj",
    "vest/isotropic/vest-iso.obj", "tank-male/isotropic/tank-male-iso.obj",
    "pants/isotropic/pants-iso.obj", "shorts/isotropic/shorts-iso.obj",
    "skirt/isotropic/skirt-iso.obj", "dress2/isotropic/dress2-iso.obj",
    "dress/draped/dress-draped-iso.obj", "dress3/draped/dress3-iso-draped.obj",
    "dress-victor/draped/dress-victor-iso-draped.obj",
]
GARMENTCODE = ["tshirt", "pants"]
# group -> repeat in mm (30 to 100 mm across the groups)
PRINTS = {"p1": 30.0, "pmm": 45.0, "pgg": 60.0, "cmm": 75.0, "p4m": 90.0, "p6m": 100.0}
RESTARTS = 15
#: brute-force reference: grid points per cell axis by number of moving pieces (denser
#: than the global method's own joint grid, solver.align.global_.GLOBAL_GRID)
BRUTE_GRID = {1: 128, 2: 32, 3: 24, 4: 24}


def fabric(group: str, a: float):
    from solver.wallpaper import GROUPS, Wallpaper

    lattice = GROUPS[group].lattice
    w = {"oblique": ((a, 0.0), (0.3 * a, 0.9 * a)),
         "rectangular": ((a, 0.0), (0.0, 0.7 * a)),
         "rhombic": ((0.8 * a, 0.6 * a), (0.8 * a, -0.6 * a)),
         "square": ((a, 0.0), (0.0, a)),
         "hexagonal": ((a, 0.0), (-a / 2, a * np.sqrt(3) / 2))}[lattice]
    return Wallpaper(group, *w, origin=(0.0, 0.0))


def pairs_run_start() -> tuple[Path | None, list[str]]:
    """The Berkeley library's root (None, said, when ../shared is absent), the garments
    BENCH_ALIGN_ONLY keeps, and the run's header line: shared by the pair benchmarks."""
    root = SHARED / "berkeley_garment_library" / "Garments"
    if not root.is_dir():
        print(f"skipped: {root} is absent")
        return None, []
    print(f"# {date.today()}  {platform.processor() or platform.machine()}  "
          f"load {os.getloadavg()[0]:.1f}  global method, grain 1 deg, 15 restarts, seed 0")
    return root, [w for w in os.environ.get("BENCH_ALIGN_ONLY", "").split(",") if w]


def garments():
    from solver.garment import load_garment

    quick = bool(os.environ.get("BENCH_ALIGN_QUICK"))
    only = [w for w in os.environ.get("BENCH_ALIGN_ONLY", "").split(",") if w]
    items = BERKELEY[4:6] if quick else BERKELEY
    if only:
        items = [rel for rel in items if any(w in rel for w in only)]
    for rel in items:
        path = SHARED / "berkeley_garment_library" / "Garments" / rel
        if path.is_file():
            yield Path(rel).stem, load_garment(path, units="m")
    for name in GARMENTCODE[: 1 if quick else 2]:
        if only and not any(w in f"gc-{name}" for w in only):
            continue
        path = SHARED / "garmentcode" / "generated" / name / f"{name}_specification.json"
        if path.is_file():
            yield f"gc-{name} (2D)", load_garment(path)


def main() -> None:
    from solver.align.brute import brute_force
    from solver.align.global_ import align_global
    from solver.align.problem import AlignProblem
    from solver.align.restarts import align_paper

    if not SHARED.is_dir():
        print(f"bench/align.py: {SHARED} is absent: nothing to measure")
        return
    if os.environ.get("BENCH_ALIGN_TIMING"):
        timing()
        return
    print(f"bench/align.py, {date.today()}, {platform.machine()} {os.cpu_count()} cores, "
          f"Python {platform.python_version()}; restarts {RESTARTS}, seed 0")
    print("| garment | pieces | faces | seam edges | group | repeat mm | E random mm² (cm²) "
          "| E paper mm² (cm²) | E global mm² (cm²) | paper/random | global/random "
          "| paper s (15 starts) | global s | global vs brute |")
    print("|" + "---|" * 14)
    ratios_p, ratios_g, gaps = [], [], []
    for name, g in garments():
        for group, a in PRINTS.items():
            problem = AlignProblem.build(g, fabric(group, a))
            align_paper(problem, restarts=2, seed=99)  # warm caches
            t0 = time.perf_counter()
            paper = align_paper(problem, restarts=RESTARTS, seed=0)
            t_paper = time.perf_counter() - t0
            t0 = time.perf_counter()
            glob = align_global(problem, restarts=RESTARTS, seed=0)
            t_glob = time.perf_counter() - t0
            e_rand = float(paper.random_energies.mean())
            gap = "-"
            if g.n_pieces <= 4:
                _, ref = brute_force(problem, glob.angles, glob.translations,
                                     grid=BRUTE_GRID[g.n_pieces])
                gaps.append(glob.energy / ref - 1.0)
                gap = f"{100 * (glob.energy / ref - 1.0):+.2f} %"
            ratios_p.append(paper.energy / e_rand)
            ratios_g.append(glob.energy / e_rand)
            print(f"| {name} | {g.n_pieces} | {len(g.faces)} | {len(g.seam_edges)} | {group} "
                  f"| {a:g} | {e_rand:.0f} ({e_rand / 100:.1f}) "
                  f"| {paper.energy:.0f} ({paper.energy / 100:.1f}) "
                  f"| {glob.energy:.0f} ({glob.energy / 100:.1f}) "
                  f"| {paper.energy / e_rand:.2f} | {glob.energy / e_rand:.2f} "
                  f"| {t_paper:.2f} | {t_glob:.1f} | {gap} |", flush=True)
    if ratios_p:
        print(f"\nmedian ratio aligned/random: paper {np.median(ratios_p):.2f} "
              f"(range {min(ratios_p):.2f}-{max(ratios_p):.2f}), global "
              f"{np.median(ratios_g):.2f} (range {min(ratios_g):.2f}-{max(ratios_g):.2f})")
    if gaps:
        print(f"global vs brute force over {len(gaps)} runs with <= 4 pieces: worst "
              f"{100 * max(gaps):+.2f} %, median {100 * np.median(gaps):+.2f} %")
    if not os.environ.get("BENCH_ALIGN_ONLY"):
        timing()


#: issue 18's aims on the dress, seconds for 15 restarts
AIM_PAPER_S, AIM_GLOBAL_S = 0.1, 1.0


def timing() -> None:
    """15 restarts on the 10k-face dress, every print of the benchmark, paper's and global
    method: best of 3, wall and CPU (the machine is shared: CPU time is the steadier)."""
    from solver.align.global_ import align_global
    from solver.align.problem import AlignProblem
    from solver.align.restarts import align_paper
    from solver.garment import load_garment

    path = SHARED / "berkeley_garment_library" / "Garments" / BERKELEY[8]
    if not path.is_file():
        return
    g = load_garment(path, units="m")
    print(f"\n15 restarts, seed 0, {path.name}: {len(g.faces)} faces, {g.n_pieces} pieces, "
          f"{len(g.seam_edges)} seam edges; load average {os.getloadavg()[0]:.1f} on "
          f"{os.cpu_count()} cores at the start")
    print("| print | paper wall s | paper CPU s | paper CPU / aim 0.1 s | global wall s "
          "| global CPU s | global CPU / aim 1 s | E paper mm² | E global mm² "
          "| rotation sweeps (mean) | Eq. 9 sweeps (mean) |")
    print("|" + "---|" * 11)
    for group, a in PRINTS.items():
        problem = AlignProblem.build(g, fabric(group, a))
        align_global(problem, restarts=2, seed=9)  # load the compiled kernels
        runs = {}
        for name, run in (("paper", align_paper), ("global", align_global)):
            walls, cpus = [], []
            for _ in range(3):
                c0, w0 = time.process_time(), time.perf_counter()
                res = run(problem, restarts=RESTARTS, seed=0)
                walls.append(time.perf_counter() - w0)
                cpus.append(time.process_time() - c0)
            runs[name] = (min(walls), min(cpus), res)
        (pw, pc, pr), (gw, gc, gr) = runs["paper"], runs["global"]
        print(f"| {group}, {a:g} mm | {pw:.3f} | {pc:.3f} | {pc / AIM_PAPER_S:.2f} "
              f"| {gw:.2f} | {gc:.2f} | {gc / AIM_GLOBAL_S:.2f} | {pr.energy:.0f} "
              f"| {gr.energy:.0f} | {pr.rotation_iterations.mean():.1f} "
              f"| {pr.translation_iterations.mean():.1f} |", flush=True)
    print(f"load average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
