"""Bites (issue 35): a marker longer than the table, and finding the print after an advance.

    python -m bench.bites [--time SECONDS] [--only markers,register]

``markers``: the marker's length with bite boundaries against the same marker with none
(`solver.nest.bites.plan_bites`: the rest of the marker moved off each boundary, then
also with the moved pieces pulled back), and a nest of the same pieces fenced at the
boundaries (`fenced_nest`, the same time): for an order of three Berkeley t-shirts on the
default 1000 mm table (window 1600 mm) and ESICUP instances (window a third of their
marker). `nest_in_bites` keeps the shortest of the three.
``register``: seconds to measure one advance from two photographs of the window.
Needs ../shared/data for ``markers`` (skips, saying so, when absent).
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

from simulators.classics import classic_print
from simulators.fabric import random_print
from simulators.roll import Conveyor, RollCamera, RollPrint
from solver.garment import load_garment
from solver.nest import NestProblem, Piece, load_esicup
from solver.nest.bites import Bite, fenced_nest, plan_bites
from solver.nest.solve import nest
from solver.wallpaper import Wallpaper
from station.steps.bites import BiteStep, RollTrack, measure_bite_advance

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"
TSHIRT = "berkeley_garment_library/Garments/tshirt/isotropic/tshirt-iso.obj"


def _tshirt_order(copies: int, repeat: float | None) -> NestProblem:
    g = load_garment(SHARED / "garments" / TSHIRT, units="m")
    pieces = [Piece(f"p{i}", g.piece_outline(i), quantity=copies) for i in range(g.n_pieces)]
    fabric = None if repeat is None else Wallpaper("p2", (repeat, 0.0), (0.0, repeat))
    return NestProblem(pieces, 1000.0, gap=3.0, fabric=fabric)


def _row(name: str, problem: NestProblem, window: float | None, t: float) -> None:
    free = nest(problem, time_limit=t, seed=0)  # the marker with no boundaries
    window = window or round(free.length / 3, 1)
    lattice = problem.lattice
    t0 = time.monotonic()
    plans = {"moved": plan_bites(free, window, lattice=lattice),
             "pulled": plan_bites(free, window, lattice=lattice, pull=True)}
    sec = time.monotonic() - t0
    fenced = fenced_nest(problem, window, free.length, time_limit=t, seed=0)
    plans["fenced"] = plan_bites(fenced, window, lattice=lattice)
    cells = [f"{p.layout.length:.0f} ({p.layout.length / free.length - 1:+.1%}, "
             f"{len(p.bites)} bites)" for p in plans.values()]
    print(f"| {name} | {window:g} | {free.length:.0f} | {' | '.join(cells)} | {sec:.2f} |",
          flush=True)


def markers(t: float) -> None:
    if not SHARED.is_dir():
        print(f"bench/bites.py: {SHARED} is absent (fresh clone): markers skipped")
        return
    print(f"\n### Marker length in bites against no boundaries, {t:g} s per nest\n")
    print("| marker | window | no boundaries | moved off the boundaries | and pulled back | "
          "nested fenced | seconds to move and pull |")
    print("|---|---|---|---|---|---|---|")
    _row("3 t-shirts, plain, 1000 mm roll", _tshirt_order(3, None), 1600.0, t)
    _row("3 t-shirts, p2 50 mm, 1000 mm roll", _tshirt_order(3, 50.0), 1600.0, t)
    for name in ("shirts", "trousers"):
        _row(f"ESICUP {name}, plain", load_esicup(SHARED / "nesting" / f"{name}.json"), None, t)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="bench.bites")
    ap.add_argument("--time", type=float, default=float(os.environ.get("BENCH_NEST_TIME", 10)))
    ap.add_argument("--only", default="markers,register")
    args = ap.parse_args([] if argv is None else argv)
    print(f"bench/bites.py  {platform.node()}  {platform.processor() or platform.machine()}  "
          f"{os.cpu_count()} cpus")
    parts = args.only.split(",")
    if "markers" in parts:
        markers(args.time)
    if "register" in parts:
        register()


def register(advances: int = 12) -> None:
    """Seconds and error of one measured advance on the default table's window (1600 x
    1000 mm at 1 mm per pixel), the simulated roll slipping up to 3 mm and 0.2 degrees:
    on a p2 print, and on stripes along the roll, where the print cannot give the advance
    and the kerfs of the last bite's pieces across the shared strip do (both measured, as
    the station does: `station.steps.bites.measure_bite_advance`)."""
    print(f"\n### Finding the print again: {advances} advances per row, 1600 x 1000 mm window "
          "at 1 mm/px\n")
    print("| print | commanded advance | shared strip | measured from | seconds per bite "
          "(median, max) | advance error max | skew error max |")
    print("|---|---|---|---|---|---|---|")
    design = random_print("p2", 50.0, seed=7)
    lattice = np.column_stack([design.wallpaper.w1, design.wallpaper.w2])
    for commanded in (800.0, 1400.0, 1540.0):
        _register_row("p2 50 mm", design, lattice, commanded, advances)
    _register_row("stripes along", classic_print("stripes", 20.0, rotation=90.0), None,
                  1540.0, advances)


def _register_row(name: str, design, lattice: np.ndarray | None, commanded: float,
                  advances: int) -> None:
    """One row of `register`: ``advances`` advances of ``commanded`` mm, each after an
    oval piece was cut into the cloth that stays in view."""
    conv = Conveyor(pivot=(799.5, 499.5), seed=11)
    camera = RollCamera(RollPrint(design, width=1000.0), conv, (0.0, 0.0, 1600.0, 1000.0))
    secs, err_a, err_s, sources = [], [], [], set()
    before = camera.photograph()
    t = np.linspace(0.0, 2 * np.pi, 120, endpoint=False)
    for _ in range(advances):
        ring = np.column_stack([1540.0 + 50.0 * np.cos(t), 500.0 + 300.0 * np.sin(t)])
        camera.burn(np.column_stack([ring, np.roll(ring, -1, axis=0)]))
        previous = BiteStep(RollTrack(), Bite(0, 0.0, 0.0, (), 0.0), before,
                            cut_photograph=camera.photograph())
        p0 = conv.pose
        p1 = conv.advance(commanded)
        after = camera.photograph()
        t0 = time.perf_counter()
        adv, source = measure_bite_advance(previous, after, commanded_mm=commanded,
                                           lattice=lattice)
        secs.append(time.perf_counter() - t0)
        sources.add(source)
        a = np.radians(p0.angle_deg)
        along = np.cos(a) * (p1.along - p0.along) + np.sin(a) * (p1.across - p0.across)
        err_a.append(abs(adv.advance_mm - along))
        err_s.append(abs(adv.skew_deg - (p1.angle_deg - p0.angle_deg)))
        before = after
    print(f"| {name} | {commanded:g} mm | {1600 - commanded:g} mm | {', '.join(sorted(sources))} "
          f"| {np.median(secs):.2f}, {max(secs):.2f} | {max(err_a):.3f} mm "
          f"| {max(err_s):.4f} deg |", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
