"""Nesting benchmark: ESICUP instances, shirts under square prints, Berkeley garments on a roll.

    python -m bench.nest [--time SECONDS]
                         [--only esicup,shirts,garments,budget,density,optimum]
                         [--seed S] [--budgets 1,3,10] [--cases tshirt,tshirt-p2,...]
                         [--garments tshirt,pants] [--method auto] [--solve S] [--probe S]

``make bench`` runs it with the time from $BENCH_NEST_TIME (default 30 s per run, the
issue's setting). Every layout is verified with ``verify_layout`` before it is counted.
``budget`` checks the ``--time T`` promise: wall time from the call to a verified layout,
over T, on plain and printed inputs (issue 18: within 10 %). The garments table gives
printed density / plain density (plain = the same pieces on grain, ``nest --plain``);
``optimum`` the best printed marker's proven bound (the dotted-board model, minutes).
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


def _run(problem, method: str, t: float, seed: int, any_phase: bool = False):
    from solver.nest import verify_layout
    from solver.nest.solve import nest

    t0 = time.monotonic()
    layout = nest(problem, time_limit=t, seed=seed, method=method, any_phase=any_phase)
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
    print("| garment | pieces | plain (`--plain`) | repeat 20 | repeat 50 | repeat 100 | "
          "repeat 200 |")
    print("|---|---|---|---|---|---|---|")
    for rel in GARMENTS:
        g = load_garment(SHARED / "garments" / "berkeley_garment_library" / "Garments" / rel,
                         units="m")
        pieces = [Piece(f"p{i}", g.piece_outline(i)) for i in range(g.n_pieces)]
        cells, plain = [], None
        for rep in (None, 20.0, 50.0, 100.0, 200.0):
            fabric = None if rep is None else Wallpaper("p2", (rep, 0.0), (0.0, rep))
            problem = NestProblem(pieces, 1500.0, gap=2.0, fabric=fabric)
            layout, _ = _run(problem, "auto", t, seed)
            plain = plain or layout.density
            ratio = "" if rep is None else f", {layout.density / plain:.2f} of plain"
            cells.append(f"{layout.density:.1%} ({layout.length:.0f} mm{ratio})")
        print(f"| {Path(rel).stem} | {len(pieces)} | {' | '.join(cells)} |", flush=True)


def _garment_problem(rel: str, repeat: float | None):
    from solver.garment import load_garment
    from solver.nest import NestProblem, Piece
    from solver.wallpaper import Wallpaper

    g = load_garment(SHARED / "garments" / "berkeley_garment_library" / "Garments" / rel,
                     units="m")
    pieces = [Piece(f"p{i}", g.piece_outline(i)) for i in range(g.n_pieces)]
    fabric = None if repeat is None else Wallpaper("p2", (repeat, 0.0), (0.0, repeat))
    return NestProblem(pieces, 1500.0, gap=2.0, fabric=fabric)


def _stripes_problem(rel: str, period: float):
    """A garment under a stripe print: pm, free to slide along the stripes in 1 mm steps
    (``station.stripes``), the period across them."""
    from solver.wallpaper import Wallpaper
    from station.stripes import STRIPE_SLIDE_MM

    problem = _garment_problem(rel, None)
    problem.fabric = Wallpaper("pm", (STRIPE_SLIDE_MM, 0.0), (0.0, period))
    return problem


def _esicup_problem(name: str, repeat: float | None):
    from solver.nest import load_esicup
    from solver.wallpaper import Wallpaper

    problem = load_esicup(SHARED / "nesting" / f"{name}.json")
    if repeat is not None:
        problem.fabric = Wallpaper("p1", (repeat, 0.0), (0.0, repeat))
    return problem


BUDGET_CASES = {  # name: (problem maker, argument, print repeat or None for plain)
    "tshirt": (_garment_problem, GARMENTS[0], None),
    "tshirt-p2-50": (_garment_problem, GARMENTS[0], 50.0),
    "pants": (_garment_problem, GARMENTS[1], None),
    "pants-p2-50": (_garment_problem, GARMENTS[1], 50.0),
    "skirt": (_garment_problem, GARMENTS[2], None),
    "skirt-p2-50": (_garment_problem, GARMENTS[2], 50.0),
    "pants-stripes-30": (_stripes_problem, GARMENTS[1], 30.0),
    "shirts": (_esicup_problem, "shirts", None),
    "shirts-p1-0.5": (_esicup_problem, "shirts", 0.5),
    "swim": (_esicup_problem, "swim", None),
    "albano-p1-20": (_esicup_problem, "albano", 20.0),
}


def budget(budgets: list[float], seed: int, cases: list[str]) -> None:
    """Wall time of nest + verification over the promised T (sparrow's thread, the fills,
    building and verifying the layout all inside)."""
    import numpy as np

    from solver.nest import verify_layout
    from solver.nest.solve import nest
    from solver.wallpaper import Wallpaper

    # process start-up, as `station nest` does before its clock starts: the kernel's cache
    Wallpaper("p1", (1.0, 0.0), (0.0, 1.0)).lattice_residual(np.zeros((1, 2)))
    print(f"\n### `--time T` on budget: wall / T, nest + verification, seed {seed}\n")
    print("| input | pieces | " + " | ".join(f"T = {t:g} s" for t in budgets) + " |")
    print("|---|---|" + "---|" * len(budgets))
    worst = (0.0, "")
    for name in cases:
        make, arg, repeat = BUDGET_CASES[name]
        cells = []
        for t in budgets:
            problem = make(arg, repeat)
            t0 = time.monotonic()
            layout = nest(problem, time_limit=t, seed=seed)
            faults = verify_layout(layout, problem)
            ratio = (time.monotonic() - t0) / t
            if faults:
                raise RuntimeError(f"invalid layout ({name}, T={t:g}): {faults[0]}")
            worst = max(worst, (ratio, f"{name} at T = {t:g} s"))
            cells.append(f"{ratio:.2f} ({layout.density:.1%})")
        print(f"| {name} | {len(problem.items())} | {' | '.join(cells)} |", flush=True)
    print(f"\nworst: {worst[0]:.2f} x T ({worst[1]}); load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cpus")


# p4m keeps the grain with the same operations as p2 (the half turns about the half
# lattice points; its quarter turns and mirrors turn or flip the grain): same markers
DENSITY_PRINTS = (("p1", 50.0), ("p2", 50.0))
BEFORE = ("joint", "fill", "coset")  # nest_lattice's default before the dotted-board model


def density(t: float, seed: int, wanted: list[str], method: str, any_phase: bool = False
            ) -> None:
    """Issue 18 part 3: printed / plain marker density of every Berkeley garment's cut lines.

    The plain marker (sparrow, 0 and 180 degrees), and per print the default strategies
    before the dotted-board model (``BEFORE``) and ``method`` (aligned position = pattern
    coordinates, moves = lattice vectors and the print's grain-keeping operations) get the
    same time, in one process. ``any_phase`` (issue 35): before = ``method`` at the
    print's phase at the roll's start, now = ``method`` free to start at any phase
    (density of the marker, from its start; the cell adds where it starts, ``phase_mm``).
    """
    from bench.reshape import GARMENTS as LIBRARY
    from bench.reshape import berkeley_garments
    from solver.nest import verify_layout
    from solver.nest.lattice import nest_lattice

    print(f"\n### Printed / plain density, Berkeley garments' cut lines, 1500 mm roll, gap 2 mm, "
          f"square prints, {t:g} s each\n")
    before = (f"method {method} at the print's phase at the roll's start" if any_phase else
              f"strategies {'+'.join(BEFORE)}")
    now = f"method {method}{', free to start at any phase' if any_phase else ''}"
    print(f"Cells: density (printed / plain, wall s). before = {before}; now = {now}.\n")
    heads = " | ".join(f"{g} {a:g} mm {when}" for g, a in DENSITY_PRINTS
                       for when in ("before", "now"))
    print(f"| garment | pieces | plain | {heads} |")
    print("|---|---|---|" + "---|" * 2 * len(DENSITY_PRINTS))
    if not LIBRARY.is_dir():
        print(f"(skipped: {LIBRARY} absent)")
        return
    cases, _ = berkeley_garments()
    ratios: dict[str, list[float]] = {"before": [], "now": []}
    for name, g in cases:
        if wanted and not any(w in name for w in wanted):
            continue
        pieces, plain, printed = _garment_problems(g, t, seed)
        cells = [f"{plain.density:.1%}"]
        for problem in printed:
            t0 = time.monotonic()
            if any_phase:
                old, sec = _run(problem, method, t, seed)
            else:
                old = nest_lattice(problem, time_limit=t, seed=seed, strategies=BEFORE)
                sec = time.monotonic() - t0
            if verify_layout(old, problem):
                raise RuntimeError(f"invalid layout (before): {verify_layout(old, problem)[0]}")
            for when, (layout, s) in (("before", (old, sec)),
                                      ("now", _run(problem, method, t, seed, any_phase))):
                ratios[when].append(layout.density / plain.density)
                phase = f", from {layout.phase_mm:.0f} mm" if when == "now" and any_phase else ""
                cells.append(f"{layout.density:.1%} ({ratios[when][-1]:.3f}, {s:.1f} s{phase})")
        print(f"| {name} | {len(pieces)} | {' | '.join(cells)} |", flush=True)
    for when, r in ratios.items():
        if r:
            print(f"\nprinted/plain {when}: median {np.median(r):.3f}, min {min(r):.3f}, "
                  f"{sum(x >= 0.95 for x in r)} of {len(r)} at least 0.95")
    print(f"\nload average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cpus at the end")


def _garment_problems(g, t: float, seed: int):
    """A garment's cut lines, their plain marker (``t`` s) and the printed problems of
    ``DENSITY_PRINTS``: the setting of the density and optimum tables."""
    from solver.nest import NestProblem
    from solver.nest.sources import garment_pieces
    from solver.wallpaper import Wallpaper

    pieces = garment_pieces(g)
    plain, _ = _run(NestProblem(pieces, 1500.0, gap=2.0), "auto", t, seed)
    return pieces, plain, [NestProblem(pieces, 1500.0, gap=2.0,
                                       fabric=Wallpaper(group, (a, 0.0), (0.0, a)))
                           for group, a in DENSITY_PRINTS]


PHASE = "; the marker may start at any phase of the print along the roll"
OPTIMUM_MAX_PIECES = 6  # by default, garments nested to a proven bound (the 4-6)


def optimum(t: float, seed: int, wanted: list[str], solve_s: float, probe_s: float,
            any_phase: bool = False) -> None:
    """Issue 18 part 3: how dense can a printed marker be at all? Per garment and print:
    the default nest (``t`` s) hints the dotted-board model (:mod:`solver.nest.dotted`),
    which runs up to ``solve_s`` s; without a proof, feasibility probes (``probe_s`` s
    each, another ``solve_s`` in all) first at the length that would be 0.95 of plain,
    then bisecting, narrow [bound, best]. plain = sparrow's marker of the same pieces
    (0/180 degree turns), a heuristic: the best plain marker is at least that dense, so a
    printed bound below 0.95 of it is below 0.95 of the best plain marker too.
    ``any_phase``: the marker may start at any phase of the print along the roll (its
    length is its span plus the gaps, see :func:`solver.nest.dotted.dotted_nest`).
    """
    from bench.reshape import GARMENTS as LIBRARY
    from bench.reshape import berkeley_garments
    from solver.nest import verify_layout
    from solver.nest.dotted import dotted_nest, narrow_bound
    from solver.nest.instance import compose, invert
    from solver.nest.layout import build_layout

    print(f"\n### The best printed marker: dotted-board model to a proven bound, Berkeley "
          f"garments' cut lines (at most {OPTIMUM_MAX_PIECES} pieces), 1500 mm roll, gap 2 mm; "
          f"default nest {t:g} s as the hint, CP-SAT {solve_s:g} s, probes {probe_s:g} s "
          f"(another {solve_s:g} s){PHASE if any_phase else ''}\n")
    print("Cells: best found mm (proven bound mm; printed/plain of the best, at most "
          "plain/bound; wall s). `opt`: the best is proven shortest (within 0.5 mm).\n")
    heads = " | ".join(f"{g} {a:g} mm" for g, a in DENSITY_PRINTS)
    print(f"| garment | pieces | plain | {heads} |")
    print("|---|---|---|" + "---|" * len(DENSITY_PRINTS))
    if not LIBRARY.is_dir():
        print(f"(skipped: {LIBRARY} absent)")
        return
    cases, _ = berkeley_garments()
    for name, g in cases:
        if not any(w in name for w in wanted) if wanted else g.n_pieces > OPTIMUM_MAX_PIECES:
            continue  # named garments run whatever their size
        pieces, plain, printed = _garment_problems(g, t, seed)
        cells = [f"{plain.density:.1%} ({plain.length:.0f} mm)"]
        for problem in printed:
            items = problem.items()
            t0 = time.monotonic()
            layout, _ = _run(problem, "auto", t, seed)
            hint = [compose(p.transform, invert(problem.pieces[it.piece].base))
                    for p, it in zip(layout.pieces, items)]
            r = dotted_nest(problem, items, time_limit=solve_s, hint=hint, any_phase=any_phase)
            if r is not None and not r.optimal:
                r = narrow_bound(problem, items, r, time_limit=solve_s, probe=probe_s,
                                 first=plain.length / 0.95, any_phase=any_phase)
            if r is None:
                cells.append(f"{layout.length:.0f} (no bound; {time.monotonic() - t0:.0f} s)")
                continue
            best = build_layout(problem, items, r.moves)
            if verify_layout(best, problem):
                raise RuntimeError(f"invalid layout (dotted): {verify_layout(best, problem)[0]}")
            cells.append(f"{r.length:.1f} ({r.bound:.1f}; {plain.length / r.length:.3f}, "
                         f"at most {plain.length / r.bound:.3f}; {time.monotonic() - t0:.0f} s"
                         f"{'; opt' if r.optimal else ''})")
        print(f"| {name} | {len(pieces)} | {' | '.join(cells)} |", flush=True)
    print(f"\nload average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cpus at the end")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="bench.nest")
    ap.add_argument("--time", type=float, default=float(os.environ.get("BENCH_NEST_TIME", 30)))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--only", default="esicup,shirts,garments,budget")
    ap.add_argument("--budgets", default="1,3,10", help="T values for the budget table")
    ap.add_argument("--cases", default=",".join(BUDGET_CASES),
                    help="inputs of the budget table")
    ap.add_argument("--garments", default="", help="density: names containing one of these")
    ap.add_argument("--method", default="auto", help="density: the printed nesting method")
    ap.add_argument("--solve", type=float, default=60.0,
                    help="optimum: CP-SAT seconds, and as many for the bound's probes")
    ap.add_argument("--probe", type=float, default=20.0, help="optimum: seconds per probe")
    ap.add_argument("--any-phase", action="store_true",
                    help="optimum, density: the marker may start at any phase of the print")
    args = ap.parse_args([] if argv is None else argv)
    if not SHARED.is_dir():
        print(f"bench/nest.py: {SHARED} is absent (fresh clone): skipped")
        return
    print(f"bench/nest.py  {time.strftime('%Y-%m-%d %H:%M')}  {platform.node()}  "
          f"{platform.processor() or platform.machine()}  {os.cpu_count()} cpus, "
          f"sparrow with 1 worker")
    for part in args.only.split(","):
        if part == "budget":
            budget([float(t) for t in args.budgets.split(",")], args.seed,
                   args.cases.split(","))
        elif part == "optimum":
            optimum(args.time, args.seed, [w for w in args.garments.split(",") if w],
                    args.solve, args.probe, args.any_phase)
        elif part == "density":
            density(args.time, args.seed, [w for w in args.garments.split(",") if w],
                    args.method, args.any_phase)
        else:
            {"esicup": esicup, "shirts": shirts, "garments": garments}[part](args.time,
                                                                             args.seed)


if __name__ == "__main__":
    import sys

    main(sys.argv[1:])
