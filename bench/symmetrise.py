"""``--symmetrise`` benchmark (issue 14): what making each pair one pattern costs or gains.

For every Berkeley garment of the alignment benchmark that has left/right pairs, under a
mirror print (pmm), a square one (p4m) and one without mirrors (p1): the symmetric
alignment (global method on grain, 1 degree, 15 restarts, seed 0) of the garment as it
is (the baseline) and of the symmetrised garment, in the same run: E_fit, their ratio,
the time of each, how many pairs were symmetrised and the largest outline move.

    python -m bench symmetrise
    BENCH_ALIGN_ONLY=tshirt,pants python -m bench symmetrise
"""

from __future__ import annotations

import time

import numpy as np

from bench.align import BERKELEY, fabric, pairs_run_start

PRINTS = {"p1": 30.0, "pmm": 45.0, "p4m": 90.0}


def main() -> None:
    from solver.align.symmetric import align_symmetric
    from solver.garment import load_garment
    from solver.garment.symmetrise import symmetrise
    from solver.garment.symmetry import mirror_pairs

    root, only = pairs_run_start()
    if root is None:
        return
    print("| garment | print | pairs symmetrised | largest move mm | s symmetrise "
          "| E_fit as is cm² | E_fit symmetrised cm² | ratio | s as is | s symmetrised |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    ratios = []
    for rel in BERKELEY:
        if only and not any(w in rel for w in only):
            continue
        g = load_garment(root / rel, units="m")
        pairs = mirror_pairs(g)
        if not pairs:
            continue
        t0 = time.perf_counter()
        sym = symmetrise(g, pairs)
        t_sym = time.perf_counter() - t0
        h_pairs = mirror_pairs(sym.garment)
        move = max((m.max_mm for m in sym.moves), default=0.0)
        for group, repeat in PRINTS.items():
            wp = fabric(group, repeat)
            runs = []
            for garment, found in ((g, pairs), (sym.garment, h_pairs)):
                t0 = time.perf_counter()
                placement = align_symmetric(garment, wp, found, method="global", restarts=15,
                                            seed=0, grain_tol_deg=1.0, compare=False)
                runs.append((placement.report["e_fit_aligned_mm2"],
                             time.perf_counter() - t0))
            (e0, s0), (e1, s1) = runs
            ratio = e1 / e0 if e0 > 0 else 1.0
            ratios.append(ratio)
            print(f"| {rel.split('/')[-1]} | {group} {repeat:g} mm | {len(sym.pairs)}/"
                  f"{len(pairs)} | {move:.2f} | {t_sym:.2f} | {e0 / 100:.1f} | {e1 / 100:.1f} "
                  f"| {ratio:.2f} | {s0:.2f} | {s1:.2f} |", flush=True)
    if ratios:
        print(f"\nE_fit symmetrised / as is: median {np.median(ratios):.2f}, "
              f"range {np.min(ratios):.2f}-{np.max(ratios):.2f}")


if __name__ == "__main__":
    main()
