"""Benchmark of seam inference (solver.seams) on CAD-like exports of garments with known seams.

Every garment in shared data whose seams are known (GarmentCode and Garment-Pattern-Generator
JSON, Berkeley OBJ) is written as a CAD would write it (`solver.seams.export`: cut line, turn
points, balance notches, grain line, pieces turned at random, no seam data), read back as any
DXF is (`solver.garment.dxf`), its seams inferred from the file alone and scored against the
truth (`solver.seams.score`): the share of the true seam length found between the right two
pieces at the right place (recall) and the share of the inferred length that is true.

    python -m bench seams            # prints a Markdown table for BENCHMARKS.md
    SEAMS_HALF=0 python -m bench seams   # every other garment only (0 or 1): tune on one
                                         # half, check on the other
    SEAMS_NET=1 python -m bench seams    # net exports (no allowance) read as the station
                                         # reads a file that does not say: 10 mm inside
"""

from __future__ import annotations

import os
import tempfile
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2] / "shared" / "data" / "garments"
ALLOWANCE_MM = 10.0  # the station's default, which a file that does not say is read with


def garments() -> list[tuple[Path, dict]]:
    """(path, load options) of every garment with known seams in shared data."""
    out = [(p, {}) for p in sorted(ROOT.glob("garmentcode/**/*.json"))]
    out += [(p, {}) for p in sorted(ROOT.glob("garment_pattern_generator/*.json"))]
    out += [(p, {"units": "m"}) for p in sorted(ROOT.glob("berkeley_garment_library/**/*.obj"))
            if not p.stem.endswith("-w")]
    half = os.environ.get("SEAMS_HALF", "")
    return out[int(half)::2] if half in ("0", "1") else out


def run_one(path: Path, options: dict, seed: int = 0):
    """(score, pieces, true seams, inferred seams, seconds) for one garment."""
    from solver.garment import load_garment
    from solver.garment.dxf import read_dxf_pattern
    from solver.garment.dxf_garment import infer_pattern_seams
    from solver.seams.export import export_cad_dxf
    from solver.seams.score import onto, sample_seams, score_seams

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        g = load_garment(path, **options)
        with tempfile.TemporaryDirectory() as tmp:
            dxf = Path(tmp) / "export.dxf"
            net = os.environ.get("SEAMS_NET") == "1"
            truth = export_cad_dxf(g, dxf, allowance_mm=0.0 if net else ALLOWANCE_MM,
                                   seed=seed)
            t = time.perf_counter()
            pattern = read_dxf_pattern(dxf, allowance_mm=ALLOWANCE_MM)
            seams, pieces, _ = infer_pattern_seams(pattern.cut_list())
            seconds = time.perf_counter() - t
    score = score_seams(onto(truth, pieces), sample_seams(seams, pieces))
    return score, g.n_pieces, len(g.seam_lines), len(seams), seconds


def main() -> None:
    if not ROOT.is_dir():
        print(f"skipped: {ROOT} is absent (the shared garments are needed)")
        return
    print("| garment | pieces | true seams | inferred | true length m | found % | "
          "inferred true % | s |")
    print("|---|---|---|---|---|---|---|---|")
    tot_t = tot_found = tot_i = tot_right = 0.0
    for path, options in garments():
        score, n, n_true, n_inf, sec = run_one(path, options)
        tot_t += score.true_mm
        tot_found += score.recall * score.true_mm
        tot_i += score.inferred_mm
        tot_right += score.precision * score.inferred_mm
        print(f"| {path.relative_to(ROOT)} | {n} | {n_true} | {n_inf} | "
              f"{score.true_mm / 1000:.2f} | {100 * score.recall:.1f} | "
              f"{100 * score.precision:.1f} | {sec:.2f} |", flush=True)
    print(f"| **all** | | | | {tot_t / 1000:.2f} | {100 * tot_found / tot_t:.1f} | "
          f"{100 * tot_right / max(tot_i, 1e-9):.1f} | |")


if __name__ == "__main__":
    main()
