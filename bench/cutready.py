"""Benchmark of issue 13's cut-ready checks on the grain and reshaping side.

Every Berkeley garment OBJ (as `bench.reshape.berkeley_garments` lists them) under a p4m
50 mm print and a pmm 60 x 80 mm plaid, aligned with the global method ON GRAIN (the
defaults: each piece's grain from its drape within 1 degree of the fabric's grain, x),
then reshaped with the default bounds (no vertex moves 10 mm, no piece's area 1 %).

Columns: E_fit of the seeded random starts (median), aligned, reshaped; reshaped/aligned
(the issue's aim: median <= 0.5 with every move <= 10 mm); the baseline in the same run
is the free-rotation alignment (``--grain off``): on-grain/free tells what the grain
costs; the largest off-grain angle, the largest move and the largest area change; the
marker density of the reshaped pieces' cut lines (default allowances: 10 mm seams, 20 mm
hems) nested on the printed fabric, 1600 mm wide (a common width for wide cloth: some
dress pieces are wider than a 1000 mm roll), 3 s (`solver.nest`), as the daemon does.

    python -m bench cutready                       # every garment, both prints
    CUTREADY_BENCH_GARMENTS=pants,tshirt ...       # garments whose name contains these
    CUTREADY_BENCH_PRINTS=p4m ...                  # one print

Writes nothing; paste the table into BENCHMARKS.md.
"""

from __future__ import annotations

import os
import time

import numpy as np

from bench.reshape import GARMENTS, RESTARTS, SEED, _header, berkeley_garments, random_median

PRINTS = {"p4m 50 mm": ("p4m", (50.0, 0.0), (0.0, 50.0)),
          "pmm 60x80 mm plaid": ("pmm", (60.0, 0.0), (0.0, 80.0))}


def main() -> None:
    from solver.align.driver import align
    from solver.reshape import reshape
    from solver.wallpaper import Wallpaper

    _header()
    if not GARMENTS.is_dir():
        print(f"(skipped: {GARMENTS} absent)")
        return
    wanted = [w for w in os.environ.get("CUTREADY_BENCH_GARMENTS", "").split(",") if w]
    prints = [w for w in os.environ.get("CUTREADY_BENCH_PRINTS", "").split(",") if w]
    if wanted:  # load only those (the full list compares every -m/-w pair first)
        from bench.reshape import _load

        notes = []
        cases = [(str(p.relative_to(GARMENTS).with_suffix("")), _load(p))
                 for p in sorted(GARMENTS.rglob("*.obj"))
                 if not p.stem.endswith(("-m", "-w"))
                 and any(w in str(p.relative_to(GARMENTS)) for w in wanted)]
    else:
        cases, notes = berkeley_garments()
    print(f"\nalign(method='global', restarts={RESTARTS}, seed={SEED}) on grain (1 deg), "
          "then reshape (max_move_mm=10, max_area_change=1 %)")
    print("| garment | print | E_fit random cm² | aligned free cm² | aligned on grain cm² | "
          "on-grain/free | reshaped cm² | reshaped/aligned | off-grain max ° | "
          "max move mm | max area change % | marker density with allowances | "
          "align s | reshape s |")
    print("|---|---|" + "---|" * 12)
    ratios, moves = [], []
    for label, (group, w1, w2) in PRINTS.items():
        if prints and group not in prints:
            continue
        wp = Wallpaper(group, w1, w2)
        for name, g in cases:
            t = time.perf_counter()
            placement = align(g, wp, method="global", restarts=RESTARTS, seed=SEED)
            t_align = time.perf_counter() - t
            free = align(g, wp, method="global", restarts=RESTARTS, seed=SEED,
                         grain_tol_deg=None)
            e_random, _ = random_median(g, wp)
            t = time.perf_counter()
            reshaped, r = reshape(g, placement)
            t_reshape = time.perf_counter() - t
            density = _marker_density(reshaped, placement)
            aligned = r.e_fit_before_mm2
            ratio = r.e_fit_after_mm2 / aligned if aligned else 0.0
            ratios.append(ratio)
            moves.append(r.max_displacement_mm)
            e_free = free.report["e_fit_aligned_mm2"]
            print(f"| {name} | {label} | {e_random / 100:.1f} | {e_free / 100:.1f} | "
                  f"{aligned / 100:.1f} | {aligned / e_free if e_free else 0:.2f} | "
                  f"{r.e_fit_after_mm2 / 100:.1f} | {ratio:.3f} | "
                  f"{placement.report['off_grain_max_deg']:.2f} | "
                  f"{r.max_displacement_mm:.2f} | {r.area_change_max_pct:.2f} | "
                  f"{100 * density:.1f} % | "
                  f"{t_align:.1f} | {t_reshape:.1f} |", flush=True)
    for note in notes:
        print(f"- {note}")
    if ratios:
        print(f"- reshaped/aligned: median {np.median(ratios):.3f} over {len(ratios)} runs "
              f"(aim <= 0.5); largest move {max(moves):.2f} mm (bound 10)", flush=True)


def _marker_density(garment, placement) -> float:
    """Density of a 1600 mm wide marker of the pieces' cut lines on the print (3 s)."""
    import tempfile
    from pathlib import Path

    from solver.garment import save_obj
    from solver.nest.solve import nest
    from solver.nest.sources import load_problem
    from station.allowance import rules_for_job
    from station.config import defaults

    with tempfile.TemporaryDirectory() as tmp:
        obj, placed = Path(tmp) / "garment.obj", Path(tmp) / "placement.json"
        save_obj(garment, obj)
        placement.garment, placement.garment_units = str(obj), "mm"
        placement.save(placed)
        problem = load_problem([placed], width=1600.0, gap=3.0,
                               allowance=rules_for_job(defaults(), {}))
        return float(nest(problem, time_limit=3.0).density)
