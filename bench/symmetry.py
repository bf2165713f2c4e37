"""Symmetric placement benchmark (issue 14): the price and the speed of mirrored pairs.

For every Berkeley garment of the alignment benchmark that has left/right pairs, under
each print of that benchmark, with the global method on grain (1 degree, 15 restarts,
seed 0): E_fit of the unconstrained alignment and of the symmetric one (pairs as a hard
constraint), their ratio (aim: <= 1.25 where the pairs are mirrored), and the CPU time
of each, measured in the same run (aim: the symmetric search at least as fast).

    python -m bench symmetry
    BENCH_ALIGN_ONLY=tshirt,pants python -m bench symmetry
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from bench.align import BERKELEY, PRINTS, fabric, pairs_run_start


def main() -> None:
    from solver.align.driver import align
    from solver.align.symmetric import align_symmetric
    from solver.garment import load_garment
    from solver.garment.grain import paired_grains
    from solver.garment.symmetry import mirror_pairs

    root, only = pairs_run_start()
    if root is None:
        return
    print("| garment | print | pairs | E_fit free cm² | E_fit symmetric cm² | sym/free "
          "| CPU s free | CPU s symmetric | time sym/free |")
    print("|---|---|---|---|---|---|---|---|---|")
    ratios, speed, same = [], [], []
    warm = load_garment(Path(__file__).resolve().parents[1] / "examples" / "tshirt-iso.obj",
                        units="m")  # compiled kernels load once, before anything is timed
    align_symmetric(warm, fabric("pmm", 45.0), mirror_pairs(warm), method="global",
                    restarts=2, compare=True)
    for rel in BERKELEY:
        if only and not any(w in rel for w in only):
            continue
        g = load_garment(root / rel, units="m")
        pairs = mirror_pairs(g)
        if not pairs:
            continue
        paired = g.copy()  # the unconstrained baseline, with the grains align_symmetric uses
        paired.grain = paired_grains(g.grains(), pairs)
        for group, repeat in PRINTS.items():
            wp = fabric(group, repeat)
            opts = dict(method="global", restarts=15, seed=0, grain_tol_deg=1.0)
            t0 = time.process_time()  # CPU seconds: the machine is shared, wall time is not
            placement = align_symmetric(g, wp, pairs, compare=False, **opts)
            t_sym = time.process_time() - t0
            t0 = time.process_time()
            free = align(paired, wp, **opts).report["e_fit_aligned_mm2"]
            t_free = time.process_time() - t0
            sym = placement.report["symmetry"]
            constrained = sym["e_fit_symmetric_mm2"]
            modes = sorted({m for *_, m in sym["pairs"]})
            ratio = constrained / free if free > 0 else 1.0
            if modes == ["mirror"]:
                ratios.append(ratio)
                speed.append(t_sym / t_free)
            elif modes == ["same"]:
                same.append((ratio, sym["e_fit_quotient_search_mm2"] / constrained))
            print(f"| {rel.split('/')[-1]} | {group} {repeat:g} mm | {len(pairs)} "
                  f"{'/'.join(modes)} | {free / 100:.1f} | {constrained / 100:.1f} | "
                  f"{ratio:.2f} | {t_free:.2f} | {t_sym:.2f} | {t_sym / t_free:.2f} |",
                  flush=True)
    if ratios:
        print(f"\nmirrored pairs: E_fit symmetric/free median {np.median(ratios):.2f}, "
              f"max {np.max(ratios):.2f} ({np.mean(np.array(ratios) <= 1.25):.0%} within "
              f"1.25); time symmetric/free median {np.median(speed):.2f}, "
              f"max {np.max(speed):.2f}")
    if same:
        price, gain = np.array(same).T
        print(f"\"same\" pairs: E_fit symmetric/free median {np.median(price):.2f}, max "
              f"{np.max(price):.2f}; the quotient's stand-in answer was {np.median(gain):.2f}x "
              f"(median) the E_fit the search on the garment cut then found")
