"""Nesting benchmark: ESICUP instances, shirts under square prints, Berkeley garments on a roll.

    python -m bench.nest [--time SECONDS] [--only esicup,shirts,garments,density] [--seed S]
                         [--garments tshirt,pants] [--method auto]

``make bench`` runs it with the time from $BENCH_NEST_TIME (default 30 s per run, the
issue's setting). Every layout is verified with ``verify_layout`` before it is counted.
Needs ../shared/data (skips, saying so, when absent).
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"
RECORDS = {"shirts": 90.92, "trousers": 92.62, "swim": 79.83, "albano": 89.82, "dagli": 90.17,
           "marques": 92.02, "jakobs1": 89.25, "jakobs2": 87.72}  # sparrow 2025, % density
GARMENTS = ("tshirt/isotropic/tshirt-iso.obj", "pants/isotropic/pants-iso.obj",
            "skirt/isotropic/skirt-iso.obj")


def _run(problem, method: str, t: float, seed: int):
    from solver.nest import verify_layout
    from solver.nest.solve import nest

    t0 = time.monotonic()
    layout = nest(problem, time_limit=t, seed=seed, method=method)
    sec = time.monotonic() - t0
    faults = verify_layout(layout, problem)
    if faults:
        raise RuntimeError(f"invalid layout ({method}): {faults[0]}")
    return layout, sec


def esicup(t: float, seed: int) -> None:
    from solver.nest import load_esicup
    from solver.nest.plain import spyrrow_pack

    print(f"\n### ESICUP instances, {t:g} s per run, gap 0\n")
    print("| instance | pieces | station nest (sparrow adapter, verified) | spyrrow direct | "
          "record (sparrow 2025) | seconds |")
    print("|---|---|---|---|---|---|")
    for name, record in RECORDS.items():
        problem = load_esicup(SHARED / "nesting" / f"{name}.json")
        layout, sec = _run(problem, "auto", t, seed)
        shapes = {i: (p.outline, p.quantity, p.orientations) for i, p in enumerate(problem.pieces)}
        _, direct_len = spyrrow_pack(shapes, problem.width, time_limit=t, seed=seed)
        direct = problem.piece_area / (problem.width * direct_len)
        print(f"| {name} | {len(layout.pieces)} | {layout.density:.2%} | {direct:.2%} | "
              f"{record:.2f}% | {sec:.1f} |", flush=True)


def shirts(t: float, seed: int) -> None:
    from solver.nest import load_esicup
    from solver.wallpaper import Wallpaper

    print(f"\n### shirts (width 40) under a square p1 print (translations only), {t:g} s\n")
    print("| repeat | naive (free + covering radius, snap) | lattice-aware (auto; "
          "verified) | issue's naive |")
    print("|---|---|---|---|")
    for a, quoted in ((0.25, "72%"), (0.5, "61%"), (1.0, "44%")):
        problem = load_esicup(SHARED / "nesting" / "shirts.json")
        problem.fabric = Wallpaper("p1", (a, 0.0), (0.0, a))
        naive, _ = _run(problem, "naive", t, seed)
        ours, _ = _run(problem, "auto", t, seed)
        print(f"| {a:g} | {naive.density:.1%} | {ours.density:.1%} | {quoted} |", flush=True)


def garments(t: float, seed: int) -> None:
    from solver.garment import load_garment
    from solver.nest import NestProblem, Piece
    from solver.wallpaper import Wallpaper

    print(f"\n### Berkeley garments on a 1500 mm roll, gap 2 mm, p2 square print, {t:g} s\n")
    print("| garment | pieces | plain | repeat 20 | repeat 50 | repeat 100 | repeat 200 |")
    print("|---|---|---|---|---|---|---|")
    for rel in GARMENTS:
        g = load_garment(SHARED / "garments" / "berkeley_garment_library" / "Garments" / rel,
                         units="m")
        pieces = [Piece(f"p{i}", g.piece_outline(i)) for i in range(g.n_pieces)]
        cells = []
        for rep in (None, 20.0, 50.0, 100.0, 200.0):
            fabric = None if rep is None else Wallpaper("p2", (rep, 0.0), (0.0, rep))
            problem = NestProblem(pieces, 1500.0, gap=2.0, fabric=fabric)
            layout, _ = _run(problem, "auto", t, seed)
            cells.append(f"{layout.density:.1%} ({layout.length:.0f} mm)")
        print(f"| {Path(rel).stem} | {len(pieces)} | {' | '.join(cells)} |", flush=True)


DENSITY_PRINTS = (("p1", 50.0), ("p2", 50.0), ("p4m", 50.0))


def density(t: float, seed: int, wanted: list[str], method: str) -> None:
    """Issue 18 part 3: printed / plain marker density of every Berkeley garment's cut lines.

    The plain marker (sparrow, 0 and 180 degrees) and the printed ones (aligned position =
    pattern coordinates, moves = lattice vectors and the print's grain-keeping operations)
    get the same time, in the same process.
    """
    from bench.reshape import GARMENTS as LIBRARY
    from bench.reshape import berkeley_garments
    from solver.nest import NestProblem
    from solver.nest.sources import garment_pieces
    from solver.wallpaper import Wallpaper

    print(f"\n### Printed / plain density, Berkeley garments' cut lines, 1500 mm roll, gap 2 mm, "
          f"square prints, {t:g} s each, method {method}\n")
    heads = " | ".join(f"{g} {a:g} mm" for g, a in DENSITY_PRINTS)
    print(f"| garment | pieces | plain | {heads} |")
    print("|---|---|---|" + "---|" * len(DENSITY_PRINTS))
    if not LIBRARY.is_dir():
        print(f"(skipped: {LIBRARY} absent)")
        return
    cases, _ = berkeley_garments()
    ratios = []
    for name, g in cases:
        if wanted and not any(w in name for w in wanted):
            continue
        pieces = garment_pieces(g)
        plain, _ = _run(NestProblem(pieces, 1500.0, gap=2.0), "auto", t, seed)
        cells = [f"{plain.density:.1%}"]
        for group, a in DENSITY_PRINTS:
            problem = NestProblem(pieces, 1500.0, gap=2.0, fabric=Wallpaper(group, (a, 0.0),
                                                                           (0.0, a)))
            layout, sec = _run(problem, method, t, seed)
            ratios.append(layout.density / plain.density)
            cells.append(f"{layout.density:.1%} ({ratios[-1]:.3f}, {sec:.1f} s)")
        print(f"| {name} | {len(pieces)} | {' | '.join(cells)} |", flush=True)
    if ratios:
        print(f"\nprinted/plain: median {np.median(ratios):.3f}, min {min(ratios):.3f}, "
              f"{sum(r >= 0.95 for r in ratios)} of {len(ratios)} at least 0.95")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="bench.nest")
    ap.add_argument("--time", type=float, default=float(os.environ.get("BENCH_NEST_TIME", 30)))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--only", default="esicup,shirts,garments")
    ap.add_argument("--garments", default="", help="density: names containing one of these")
    ap.add_argument("--method", default="auto", help="density: the printed nesting method")
    args = ap.parse_args([] if argv is None else argv)
    if not SHARED.is_dir():
        print(f"bench/nest.py: {SHARED} is absent (fresh clone): skipped")
        return
    print(f"bench/nest.py  {time.strftime('%Y-%m-%d %H:%M')}  {platform.node()}  "
          f"{platform.processor() or platform.machine()}  {os.cpu_count()} cpus, "
          f"sparrow with 1 worker")
    for part in args.only.split(","):
        if part == "density":
            density(args.time, args.seed, [w for w in args.garments.split(",") if w],
                    args.method)
            continue
        {"esicup": esicup, "shirts": shirts, "garments": garments}[part](args.time, args.seed)


if __name__ == "__main__":
    import sys

    main(sys.argv[1:])
