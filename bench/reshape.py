"""Benchmark of pattern reshaping (paper Sec. 5, Table 1 bottom rows; issue 4) and its scaling.

Garments table (what issue 4 checks): every Berkeley garment OBJ, p4m print of 50 mm
repeat, aligned with the global method (`solver.align.driver.align`, 15 seeded starts),
then `solver.reshape.reshape`. E_fit for a random placement is the median over the same
15 seeded random starts the aligner drew, each measured with `solver.fit.fit_report`.

Scaling table: shorts-iso (p4m) refined by `solver.garment.refine.subdivided` from 3k to
192k faces; next to each reshape, one CHOLMOD factorisation of the conformal matrix of the
same mesh (as `solver.reshape.optimise` factorises its model) as an in-process baseline.

Groups table (optional): p4m / pmm / p6m on six garments, aligned by the paper's method.

    python -m bench reshape                          # garments + scaling (+ groups)
    RESHAPE_BENCH=garments python -m bench reshape   # one table: garments|scaling|groups
    RESHAPE_BENCH_LEVELS=3 ...                       # scaling stops at ~48k faces

Writes nothing; paste the tables into BENCHMARKS.md.
"""

from __future__ import annotations

import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

GARMENTS = Path(__file__).resolve().parents[2] / "shared" / "data" / "garments" / \
    "berkeley_garment_library" / "Garments"
BUNDLED = Path(__file__).resolve().parents[1] / "tests" / "data" / "garments" / "berkeley"
SCALING_CASE = "shorts/isotropic/shorts-iso.obj"
CASES = ["shorts/isotropic/shorts-iso.obj", "pants/isotropic/pants-iso.obj",
         "skirt/isotropic/skirt-iso.obj", "tshirt/isotropic/tshirt-iso.obj",
         "shirt/isotropic/shirt-iso.obj", "dress3/draped/dress3-iso-draped.obj"]
GROUPS = {"p4m": ((50.0, 0.0), (0.0, 50.0)), "pmm": ((50.0, 0.0), (0.0, 30.0)),
          "p6m": ((50.0, 0.0), (-25.0, 25.0 * 3**0.5))}
RESTARTS = 15
SEED = 0


def main() -> None:
    """RESHAPE_BENCH=garments, =scaling or =groups runs one table; default all three."""
    which = os.environ.get("RESHAPE_BENCH", "all")
    _header()
    if which in ("all", "garments"):
        garments_table()
    if which in ("all", "scaling"):
        scaling_table()
    if which in ("all", "groups"):
        groups_table()


def _header() -> None:
    print(f"# bench/reshape.py  {time.strftime('%Y-%m-%d %H:%M')}  "
          f"{platform.processor() or platform.machine()}  {os.cpu_count()} cores, "
          f"load average {' '.join(f'{x:.1f}' for x in os.getloadavg())} (wall time "
          "inflates with load; CPU time is the process's own)", flush=True)


def _load(path: Path):
    import warnings

    from solver.garment import load_garment

    with warnings.catch_warnings():  # the combined files' welding notes, not news here
        warnings.simplefilter("ignore")
        return load_garment(path, units="m")


def _corner_key(g) -> list:
    """Sorted per-face (uv, xyz) corner tuples: the geometry independent of numbering."""
    c = np.concatenate([g.uv[g.faces], g.xyz[g.faces]], axis=2)  # (F,3,5)
    return sorted(tuple(sorted(map(tuple, f))) for f in c.tolist())


def _seam_key(g) -> list:
    """Sorted seam edges as unordered pairs of uv end points on both twins."""
    e = g.seam_edges
    out = []
    for row in np.concatenate([g.uv[e[:, :2]], g.uv[e[:, 2:]]], axis=1).tolist():
        a, b = sorted(map(tuple, row[:2])), sorted(map(tuple, row[2:]))
        out.append(tuple(sorted([tuple(a), tuple(b)])))
    return sorted(out)


def _same_geometry(a, b) -> bool:
    """Same faces (pattern and drape, exactly) and the same seams, whatever the numbering."""
    if (a.xyz is None or b.xyz is None or len(a.faces) != len(b.faces)
            or a.n_vertices != b.n_vertices or len(a.seam_edges) != len(b.seam_edges)):
        return False
    return _corner_key(a) == _corner_key(b) and _seam_key(a) == _seam_key(b)


def berkeley_garments() -> tuple[list[tuple[str, object]], list[str]]:
    """(name, garment) for every OBJ under GARMENTS, and notes on what was skipped.

    A ``-m``/``-w`` file loads as the pair (`load_garment` finds the partner), so both
    name one garment; it is skipped only when that garment's geometry equals the
    combined file beside it, and measured under its own name otherwise.
    """
    out, notes, seen = [], [], set()
    for path in sorted(GARMENTS.rglob("*.obj")):
        name = str(path.relative_to(GARMENTS).with_suffix(""))
        stem = path.stem
        if stem.endswith(("-m", "-w")):
            pair = stem[:-2]
            if (path.parent, pair) in seen:
                continue
            seen.add((path.parent, pair))
            base = path.with_name(pair + ".obj")
            g = _load(path)
            if base.is_file() and _same_geometry(g, _load(base)):
                notes.append(f"{pair}-m/-w skipped: as a pair it has exactly the faces "
                             f"(pattern and drape coordinates) and seams of {pair}.obj")
                continue
            out.append((name[:-2] + "-m/-w", g))
            continue
        out.append((name, _load(path)))
    return out, notes


def random_median(g, wp, restarts: int = RESTARTS, seed: int = SEED) -> tuple[float, float]:
    """(median, mean) E_fit mm² of the seeded random starts the aligner begins from
    (`align_paper`, and `align_global` through it, draw them first from
    ``default_rng(seed)``), each measured with `fit_report`."""
    from solver.align.problem import AlignProblem
    from solver.fit import fit_report
    from solver.placement import Placement

    problem = AlignProblem.build(g, wp)
    ang, t = problem.random_starts(np.random.default_rng(seed), restarts)
    e = np.array([fit_report(g, Placement(ang[k], t[k], wp)).e_fit_mm2
                  for k in range(restarts)])
    return float(np.median(e)), float(e.mean())


def crossing_outlines(g) -> int:
    """Pieces whose outer outline is not a simple ring (a cutter cannot follow it)."""
    import shapely

    return sum(not shapely.LinearRing(g.piece_outline(i)).is_simple
               for i in range(g.n_pieces))


def timed_reshape(g, placement):
    """reshape() with its CPU (all threads of the process) and wall seconds."""
    from solver.reshape import reshape

    cpu, wall = time.process_time(), time.perf_counter()
    new, r = reshape(g, placement)
    return new, r, time.process_time() - cpu, time.perf_counter() - wall


def garments_table() -> None:
    """Issue 4's check: every Berkeley garment, p4m 50 mm, global alignment, reshape."""
    from solver.align.driver import align
    from solver.wallpaper import Wallpaper

    if not GARMENTS.is_dir():
        print(f"(garments table skipped: {GARMENTS} absent)")
        return
    wp = Wallpaper("p4m", *GROUPS["p4m"])
    cases, notes = berkeley_garments()
    print(f"\np4m {GROUPS['p4m']} mm, align(method='global', restarts={RESTARTS}, "
          f"seed={SEED}), then reshape (default ReshapeOptions)")
    print("| garment | faces | subdivisions | E_fit random cm² | aligned cm² | reshaped cm² | "
          "reshaped/aligned | reshaped/random | L init cm | L final cm | eps cm | γ rounds | "
          "iterations | max move mm | flips | crossing outlines in/out | align wall s | "
          "reshape CPU s | reshape wall s |")
    print("|---|" + "---|" * 18)
    random_check = []
    for name, g in cases:
        t = time.perf_counter()
        placement = align(g, wp, method="global", restarts=RESTARTS, seed=SEED)
        t_align = time.perf_counter() - t
        e_med, e_mean = random_median(g, wp)
        rep_mean = placement.report["e_fit_random_mm2"]
        random_check.append(abs(e_mean - rep_mean) / max(rep_mean, 1e-12))
        new, r, cpu, wall = timed_reshape(g, placement)
        aligned = r.e_fit_before_mm2
        print(f"| {name} | {len(g.faces)} | {r.subdivisions} | {e_med / 100:.1f} | "
              f"{aligned / 100:.1f} | {r.e_fit_after_mm2 / 100:.1f} | "
              f"{r.e_fit_after_mm2 / aligned if aligned else 0:.3f} | "
              f"{r.e_fit_after_mm2 / e_med:.3f} | "
              f"{r.length_mismatch_initial_mm / 10:.2f} | "
              f"{r.length_mismatch_final_mm / 10:.2f} | {r.epsilon_mm / 10:.2f} | "
              f"{r.gamma_rounds} | {r.iterations} | {r.max_displacement_mm:.1f} | "
              f"{r.flipped_triangles} | {crossing_outlines(g)}/{crossing_outlines(new)} | "
              f"{t_align:.1f} | {cpu:.2f} | {wall:.2f} |", flush=True)
    for note in notes:
        print(f"- {note}")
    print(f"- random column: median of {RESTARTS} seeded random starts via fit_report; their "
          f"mean matches placement.report['e_fit_random_mm2'] within "
          f"{max(random_check):.1e} (relative)", flush=True)


def factorisation_seconds(g, repeats: int = 3) -> float:
    """CPU seconds (best of ``repeats``) of one CHOLMOD factorisation (cholespy, COO input,
    as `solver.reshape.optimise` does) of the conformal matrix of ``g``'s pattern plus the
    solver's 1e-8 x mean-diagonal regularisation (the matrix alone is singular)."""
    import scipy.sparse as sp
    from cholespy import CholeskySolverD, MatrixType

    from solver.reshape.energy import conformal_matrix

    q = conformal_matrix(g.uv, g.faces)
    m = sp.coo_matrix(q + 1e-8 * float(np.abs(q.diagonal()).mean()) * sp.eye(q.shape[0]))
    rows, cols, vals = m.row.astype(np.int32), m.col.astype(np.int32), m.data.astype(np.float64)
    best = np.inf
    for _ in range(repeats):
        cpu = time.process_time()
        CholeskySolverD(m.shape[0], rows, cols, vals, MatrixType.COO)
        best = min(best, time.process_time() - cpu)
    return best


def scaling_table() -> None:
    """One garment, p4m, refined by midpoint subdivision from ~3k to ~192k faces."""
    from solver.align.driver import align
    from solver.garment.refine import subdivided
    from solver.wallpaper import Wallpaper

    base = GARMENTS / SCALING_CASE if GARMENTS.is_dir() else BUNDLED / "shorts-iso.obj"
    g = _load(base)
    wp = Wallpaper("p4m", *GROUPS["p4m"])
    placement = align(g, wp, method="global", restarts=RESTARTS, seed=SEED)
    print(f"\n{base.stem}, p4m 50 mm, one global alignment (15 starts) reused at every level; "
          "levels made with solver.garment.refine.subdivided")
    print("| level | faces | vertices | subdivisions by reshape | E_fit aligned cm² | "
          "reshaped cm² | reshaped/aligned | L final / eps | γ rounds | iterations | "
          "factorisations | flips | crossing outlines | reshape wall s | reshape CPU s | "
          "CPU s per 1k faces | CPU ms per iteration | conformal factorisation CPU s | "
          "reshape / factorisation |")
    print("|---|" + "---|" * 18)
    for level in range(int(os.environ.get("RESHAPE_BENCH_LEVELS", "4"))):
        if level:
            g = subdivided(g)
        print(f"(level {level}: {len(g.faces)} faces, reshaping ...)", file=sys.stderr,
              flush=True)
        new, r, cpu, wall = timed_reshape(g, placement)
        fac = factorisation_seconds(g)
        print(f"| {level} | {len(g.faces)} | {g.n_vertices} | {r.subdivisions} | "
              f"{r.e_fit_before_mm2 / 100:.1f} | {r.e_fit_after_mm2 / 100:.1f} | "
              f"{r.e_fit_ratio:.3f} | "
              f"{r.length_mismatch_final_mm / 10:.2f} / {r.epsilon_mm / 10:.2f} cm | "
              f"{r.gamma_rounds} | {r.iterations} | {r.factorisations} | "
              f"{r.flipped_triangles} | {crossing_outlines(new)} | {wall:.2f} | {cpu:.2f} | "
              f"{1000 * cpu / len(g.faces):.3f} | {1000 * cpu / max(r.iterations, 1):.1f} | "
              f"{fac:.3f} | {cpu / fac:.1f} |", flush=True)


def groups_table() -> None:
    """Six garments x p4m / pmm / p6m, paper alignment (the older Table 1-style view)."""
    from solver.align.driver import align
    from solver.wallpaper import Wallpaper

    if not GARMENTS.is_dir():
        print(f"(groups table skipped: {GARMENTS} absent)")
        return
    print(f"\nsix garments x three groups, align(method='paper', restarts={RESTARTS}, "
          f"seed={SEED}), then reshape")
    print("| garment | faces | subdivisions | group | E_fit random cm² | aligned cm² | "
          "reshaped cm² | reshaped/aligned | reshaped/random | L final / eps cm | "
          "iterations | flips | crossing outlines | reshape CPU s | reshape wall s |")
    print("|---|" + "---|" * 14)
    for case in CASES:
        g = _load(GARMENTS / case)
        for group, (w1, w2) in GROUPS.items():
            wp = Wallpaper(group, w1, w2)
            placement = align(g, wp, method="paper", restarts=RESTARTS, seed=SEED)
            e_med, _ = random_median(g, wp)
            new, r, cpu, wall = timed_reshape(g, placement)
            print(f"| {Path(case).stem} | {len(g.faces)} | {r.subdivisions} | {group} | "
                  f"{e_med / 100:.1f} | {r.e_fit_before_mm2 / 100:.1f} | "
                  f"{r.e_fit_after_mm2 / 100:.1f} | {r.e_fit_ratio:.3f} | "
                  f"{r.e_fit_after_mm2 / e_med:.3f} | "
                  f"{r.length_mismatch_final_mm / 10:.2f} / {r.epsilon_mm / 10:.2f} | "
                  f"{r.iterations} | {r.flipped_triangles} | {crossing_outlines(new)} | "
                  f"{cpu:.2f} | {wall:.2f} |", flush=True)


if __name__ == "__main__":
    main()
