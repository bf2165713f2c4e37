"""Benchmark of reshaping as a pattern maker signs it off (issue 36): the fit it buys
against the move bound, and the checks on garments the reshaper was not tuned on.

Bounds table: every Berkeley garment and the held-out specifications (GarmentCode's
pencil dress, the "robe", and mean shirt, the "blouse"; GPG's sleeveless dress and
jumpsuit), p4m 50 mm, aligned on grain with the global method (15 seeded starts), then
reshaped with the default options at each move bound (2, 5, 10, 20 mm), without any
move or area bound, and with the paper's method: E_fit after / aligned and CPU seconds,
plus, at the default 10 mm, the outline roughness and the largest change of a seam's
ease (`solver.reshape.quality`).

Limits table: what holds the fit back, one default changed at a time (the area bound,
the move bound, the gamma schedule, the ease kept, the outline smoothing, the targets'
refinement rounds) on the garments where the 10 mm default gains least.

Held-out table: the issue's checks as `station` runs them (align with its defaults, then
reshape, in process through `station.cli.main`), measured from the written OBJ files.

    python -m bench reshapebounds                      # both tables
    RESHAPE_BOUNDS=heldout python -m bench reshapebounds   # one: bounds|heldout|limits
    RESHAPE_BOUNDS_GARMENTS=robe,shorts ...            # garments whose name contains these

Writes nothing but temporary files; paste the tables into BENCHMARKS.md.
"""

from __future__ import annotations

import json
import os
import tempfile
import time
import warnings
from contextlib import redirect_stderr, redirect_stdout
from io import StringIO
from pathlib import Path

import numpy as np

from bench.reshape import GARMENTS, RESTARTS, SEED, _header, berkeley_garments

SHARED = GARMENTS.parents[1]
HELD_OUT = {  # name -> path under ../shared/data/garments
    "robe (GarmentCode pencil dress)": "garmentcode/repo_specs/dress_pencil_specification.json",
    "blouse (GarmentCode mean shirt)": "garmentcode/repo_specs/shirt_mean_specification.json",
    "GPG sleeveless dress": "garment_pattern_generator/dress_sleeveless.json",
    "GPG sleeveless jumpsuit": "garment_pattern_generator/jumpsuit_sleeveless.json",
}
BOUNDS = (2.0, 5.0, 10.0, 20.0)
P4M = {"group": "p4m", "w1": [50, 0], "w2": [0, 50], "units": "mm"}
PMM = {"group": "pmm", "w1": [60, 0], "w2": [0, 80], "units": "mm"}


def main() -> None:
    """RESHAPE_BOUNDS=bounds or =heldout runs one table; default both."""
    which = os.environ.get("RESHAPE_BOUNDS", "all")
    _header()
    if not GARMENTS.is_dir():
        print(f"(skipped: {GARMENTS} absent)")
        return
    if which in ("all", "bounds"):
        bounds_table()
    if which in ("all", "heldout"):
        heldout_table()
    if which in ("all", "limits"):
        limits_table()


def _cases() -> list[tuple[str, object]]:
    from solver.garment import load_garment

    wanted = [w for w in os.environ.get("RESHAPE_BOUNDS_GARMENTS", "").split(",") if w]
    cases, _ = berkeley_garments()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cases += [(name, load_garment(SHARED / path)) for name, path in HELD_OUT.items()]
    return [(n, g) for n, g in cases if not wanted or any(w in n for w in wanted)]


def _timed(g, placement, options):
    from solver.reshape import reshape

    cpu = time.process_time()
    new, report = reshape(g, placement, options=options)
    return report, time.process_time() - cpu


def bounds_table() -> None:
    """E_fit reshaped / aligned against the move bound, every garment, p4m 50 mm."""
    from solver.align.driver import align
    from solver.reshape import ReshapeOptions
    from solver.wallpaper import Wallpaper

    wp = Wallpaper.from_dict(P4M)
    print(f"\np4m 50 mm, align(method='global', restarts={RESTARTS}, seed={SEED}) on grain "
          "(1 deg), then reshape; each cell: reshaped/aligned E_fit (CPU s)")
    heads = [f"{b:g} mm" for b in BOUNDS] + ["no move or area bound", "paper (Sec. 5)"]
    print("| garment | faces | aligned cm² | " + " | ".join(heads) + " | roughness p95 / max "
          "mm (10 mm) | largest ease change / notch drift mm (10 mm) |")
    print("|---|---|---|" + "---|" * (len(heads) + 2))
    ratios = {h: [] for h in heads}
    for name, g in _cases():
        placement = align(g, wp, method="global", restarts=RESTARTS, seed=SEED)
        options = [ReshapeOptions(max_move_mm=b) for b in BOUNDS] + [
            ReshapeOptions(max_move_mm=np.inf, max_area_change=np.inf), ReshapeOptions.paper()]
        cells, at10 = [], None
        for head, opt in zip(heads, options):
            r, cpu = _timed(g, placement, opt)
            ratios[head].append(r.e_fit_ratio)
            cells.append(f"{r.e_fit_ratio:.3f} ({cpu:.1f})")
            at10 = r if opt.max_move_mm == 10.0 and np.isfinite(opt.max_area_change) else at10
        print(f"| {name} | {len(g.faces)} | {at10.e_fit_before_mm2 / 100:.1f} | "
              + " | ".join(cells) + f" | {at10.roughness_p95_mm:.2f} / "
              f"{at10.roughness_max_mm:.2f} | {at10.ease_change_max_mm:.2f} / "
              f"{at10.sewn_drift_max_mm:.2f} |", flush=True)
    print("| median | | | " + " | ".join(f"{np.median(v):.3f}" for v in ratios.values())
          + " | | |", flush=True)


def _station(*argv: str) -> tuple[int, str, str]:
    """``station ARGV`` in process: exit code, stdout, stderr."""
    from station.cli import main as station_main

    out, err = StringIO(), StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = station_main(list(argv))
    return code, out.getvalue(), err.getvalue()


def _measured(source: Path, written: Path, subdivisions: int, fabric) -> tuple:
    """Roughness p95 and max, the largest seam ease change and notch drift, and the
    flips, from the OBJ
    ``written`` against the input ``source`` written the same way (subdivided as reshape
    did)."""
    from solver.garment import load_garment, save_obj
    from solver.garment.refine import refined
    from solver.reshape.energy import signed_areas
    from solver.reshape.quality import outline_roughness, seam_ease_changes

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        g = load_garment(source)
        if subdivisions:
            g, _ = refined(g, fabric.covering_radius)
        before = written.with_name(written.stem + "-input.obj")
        save_obj(g, before)
        a, b = load_garment(before), load_garment(written)
    rough = outline_roughness(a, b.uv)
    seams = seam_ease_changes(a, b.uv)
    ease = max(abs(s["ease_change_mm"]) for s in seams)
    drift = max(s["sewn_drift_mm"] for s in seams)
    return (float(np.percentile(rough, 95)), float(rough.max()), ease, drift,
            int(np.sum(signed_areas(b.uv, b.faces) <= 0)))


def _check(tmp: Path, name: str, fabric: dict, align_args: list[str],
           reshape_args: list[str]) -> None:
    """One row: align and reshape through `station`, measure the written OBJ."""
    from solver.wallpaper import Wallpaper

    source = SHARED / HELD_OUT[name]
    spec = tmp / f"{fabric['group']}.json"
    spec.write_text(json.dumps(fabric))
    placement, out = tmp / "placement.json", tmp / "reshaped.obj"
    t = time.perf_counter()
    code, _, err = _station("align", str(source), "--fabric", str(spec), "-o", str(placement),
                            *align_args)
    t_align = time.perf_counter() - t
    if code:
        print(f"| {name} | align failed: {err.strip().splitlines()[-1]} |")
        return
    t = time.perf_counter()
    code, text, err = _station("reshape", str(source), "--fabric", str(spec), "--placement",
                               str(placement), "-o", str(out), "--json", *reshape_args)
    t_reshape = time.perf_counter() - t
    if code:
        print(f"| {name} | reshape failed: {err.strip().splitlines()[-1]} |")
        return
    rep = json.loads(text)
    p95, worst, ease, drift, flips = _measured(source, out, rep["subdivisions"],
                                        Wallpaper.from_dict(fabric))
    print(f"| {name} | {fabric['group']} | {' '.join(align_args) or '(defaults)'} | "
          f"{' '.join(reshape_args) or '(defaults)'} | {rep['e_fit_before_mm2'] / 100:.1f} | "
          f"{rep['e_fit_after_mm2'] / 100:.1f} | {rep['e_fit_ratio']:.3f} | {p95:.2f} | "
          f"{worst:.2f} | {ease:.2f} | {drift:.2f} | {rep['max_displacement_mm']:.1f} | "
          f"{flips} | "
          f"{t_align:.1f} | {t_reshape:.1f} |", flush=True)


def heldout_table() -> None:
    """The issue's checks, as `station` runs them, measured from the written OBJ."""
    print("\nheld-out garments through `station align` and `station reshape`, measured from "
          "the written OBJ (roughness: the outline displacement its 10 mm moving average "
          "does not explain; ease: largest change of a seam's side length difference)")
    print("| garment | print | align options | reshape options | aligned cm² | reshaped cm² | "
          "reshaped/aligned | roughness p95 mm | roughness max mm | largest ease change mm | "
          "largest notch drift mm | largest move mm | flipped triangles | align wall s | "
          "reshape wall s |")
    print("|---|---|---|---|" + "---|" * 11)
    robe = list(HELD_OUT)[0]
    rows = [(name, fabric, [], []) for name in HELD_OUT for fabric in (PMM, P4M)]
    rows += [(robe, P4M, ["--grain", "off", "--no-symmetry"], ["--no-symmetry"]),
             (robe, P4M, ["--grain", "off", "--no-symmetry"],
              ["--no-symmetry", "--method", "paper"])]
    with tempfile.TemporaryDirectory() as tmp:
        for name, fabric, align_args, reshape_args in rows:
            _check(Path(tmp), name, fabric, align_args, reshape_args)


LIMITED = ("dress/coarse", "pants/coarse", "tshirt/coarse", "skirt/isotropic", "robe", "GPG")
VARIANTS = {
    "defaults": {},
    "no area bound": {"max_area_change": np.inf},
    "20 mm move bound": {"max_move_mm": 20.0},
    "gamma0 = 4": {"gamma0": 4.0},
    "gamma0 = 0.25": {"gamma0": 0.25},
    "twins to equal lengths (no ease kept)": {"keep_ease": False},
    "no outline smoothing": {"smooth_mm": 0.0, "corner_smooth_mm": 0.0},
    "8 rounds of matched targets": {"refinements": 8, "refine_gain": 0.0},
}


def limits_table() -> None:
    """Reshaped/aligned with one default changed at a time, p4m 50 mm."""
    from solver.align.driver import align
    from solver.reshape import ReshapeOptions
    from solver.wallpaper import Wallpaper

    wp = Wallpaper.from_dict(P4M)
    print("\np4m 50 mm, aligned as in the bounds table; reshaped/aligned E_fit with one "
          "default changed (largest ease change mm, CPU s)")
    print("| garment | " + " | ".join(VARIANTS) + " |")
    print("|---|" + "---|" * len(VARIANTS))
    for name, g in _cases():
        if not any(k in name for k in LIMITED):
            continue
        placement = align(g, wp, method="global", restarts=RESTARTS, seed=SEED)
        cells = []
        for changes in VARIANTS.values():
            r, cpu = _timed(g, placement, ReshapeOptions(**changes))
            cells.append(f"{r.e_fit_ratio:.3f} ({r.ease_change_max_mm:.1f}, {cpu:.1f})")
        print(f"| {name} | " + " | ".join(cells) + " |", flush=True)
