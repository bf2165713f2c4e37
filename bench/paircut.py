"""Do left and right pieces cut as mirror images? A sweep of every garment with pairs.

For every Berkeley, GarmentCode, Garment-Pattern-Generator and ARCSim garment in
../shared that has mirror pairs: the pairs are symmetrised (one pattern cut twice), then
each pair's cut lines and notches are compared, one piece flipped onto the other
(`solver.garment.symmetry.cut_mismatch`), twice:

* ``flat``: the symmetrised pattern as it is (`cut_ready` without a placement);
* ``pmm``: aligned under a pmm 60 x 80 mm plaid with the pairs mirrored, then reshaped
  with the pairs tied (``station align`` then ``station reshape``), notches on the
  print's lattice lines.

A pair mirrors when both gaps are within 0.1 mm (``TOLERANCE_MM``). Each garment prints
one line per pair that does not; the summary counts pairs checked and mirroring.

    python -m bench paircut
    BENCH_PAIRCUT_ONLY=jacket,pants python -m bench paircut     # names containing these
    BENCH_PAIRCUT_FLAT=1 python -m bench paircut                # the flat check only
"""

from __future__ import annotations

import os
import time
import warnings
from pathlib import Path

TOLERANCE_MM = 0.1
SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "garments"


def garments(root: Path = SHARED) -> list[Path]:
    """The shared garments a pair sweep reads (Berkeley meshes, not their -m/-w halves)."""
    files = [f for f in sorted((root / "berkeley_garment_library").rglob("*.obj"))
             if not f.stem.endswith(("-m", "-w"))]
    files += sorted((root / "garment_pattern_generator").glob("*.json"))
    files += sorted((root / "garmentcode").rglob("*specification*.json"))
    files += sorted((root / "arcsim_meshes").glob("*.obj"))
    return files


def load(path: Path):
    """A shared garment as the sweeps load it (meshes in metres, warnings hushed)."""
    from solver.garment import load_garment

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_garment(path, units="m" if path.suffix == ".obj" else None)


def check(garment, pairs, placement=None) -> list[tuple[int, int, float, float]]:
    """Per pair (first, second, cut-line gap mm, notch gap mm) of the garment's cut."""
    from solver.garment.allowance import AllowanceRules
    from solver.garment.notches import cut_ready
    from solver.garment.symmetry import cut_mismatch

    cuts, notches = cut_ready(garment, AllowanceRules(), placement)
    return [(p.first, p.second, *cut_mismatch(p, cuts, notches)) for p in pairs]


def aligned_reshaped(garment, pairs):
    """The garment reshaped under a pmm plaid with its pairs mirrored, and the placement."""
    from solver.align.symmetric import align_symmetric
    from solver.garment.symmetry import fit_pairs
    from solver.reshape import reshape
    from solver.wallpaper import Wallpaper

    placement = align_symmetric(garment, Wallpaper("pmm", (60, 0), (0, 80)), pairs,
                                compare=False, method="paper", restarts=1, grain_tol_deg=1.0)
    new, _ = reshape(garment, placement, pairs=fit_pairs(garment,
                                                         [p[:2] for p in placement.pairs]))
    return new, placement


def main() -> None:
    from solver.garment.symmetrise import symmetrise
    from solver.garment.symmetry import fit_pairs, mirror_pairs

    if not SHARED.is_dir():
        print(f"{SHARED} is absent: nothing to sweep")
        return
    only = [w for w in os.environ.get("BENCH_PAIRCUT_ONLY", "").split(",") if w]
    scenarios = ["flat"] if os.environ.get("BENCH_PAIRCUT_FLAT") else ["flat", "pmm"]
    counts = {s: [0, 0, 0] for s in scenarios}  # checked, cut lines mirror, notches mirror
    for path in garments():
        name = str(path.relative_to(SHARED))
        if only and not any(w in name for w in only):
            continue
        g = load(path)
        pairs = mirror_pairs(g)
        if not pairs:
            continue
        t0 = time.perf_counter()
        sym = symmetrise(g, pairs)
        rows = {"flat": check(sym.garment, sym.pairs)}
        if "pmm" in scenarios:
            new, placement = aligned_reshaped(sym.garment, sym.pairs)
            rows["pmm"] = check(new, fit_pairs(new, [p[:2] for p in placement.pairs]),
                                placement)
        print(f"{name}: {len(pairs)} pairs, {len(sym.pairs)} symmetrised, "
              f"{time.perf_counter() - t0:.1f} s", flush=True)
        for scenario, found in rows.items():
            c = counts[scenario]
            for i, j, cut, notch in found:
                c[0] += 1
                c[1] += cut <= TOLERANCE_MM
                c[2] += notch <= TOLERANCE_MM
                if max(cut, notch) > TOLERANCE_MM:
                    print(f"  {scenario} pair {i}~{j}: cut lines {cut:.3f} mm, "
                          f"notches {notch:.3f} mm")
    for scenario, (n, cut, notch) in counts.items():
        print(f"{scenario}: {n} pairs checked, cut lines mirror {cut}, notches mirror {notch} "
              f"(within {TOLERANCE_MM} mm)")
