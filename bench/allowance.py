"""Cut lines and notches on every Berkeley garment: time, extra cloth, and the baseline.

    python -m bench allowance

Per garment: the cut lines with the default allowances (10 mm seams, 20 mm hems, 10 mm
openings; per-edge strips, capped mitres, dart fills, one union per piece) and the notches,
against shapely's own uniform mitred buffer of every sew line (the baseline, same run;
with one allowance everywhere our cut line equals it, which is checked, except on pieces
with darts, whose folded wedge we keep). The cloth the
allowances add is the cut area over the sew area. Needs ../shared/data (skips, saying
so, when absent).
"""

from __future__ import annotations

import platform
import time
import warnings
from pathlib import Path

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"


def _best(fn, *args, repeats: int = 3):
    """Best of ``repeats`` wall times of ``fn(*args)``, and its result."""
    best, result = float("inf"), None
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = fn(*args)
        best = min(best, time.perf_counter() - t0)
    return best, result


def _ours(g, rules):
    from solver.garment.notches import cut_ready

    return cut_ready(g, rules)


def _baseline(sews):
    return [s.buffer(10.0, join_style="mitre", mitre_limit=2.0) for s in sews]


def main() -> None:
    import shapely

    from solver.garment import load_garment
    from solver.garment.allowance import AllowanceRules, cut_lines, dart_runs

    root = SHARED / "garments" / "berkeley_garment_library" / "Garments"
    if not root.is_dir():
        print(f"skipped: {root} is absent")
        return
    files = sorted(p for p in root.rglob("*.obj") if not p.stem.endswith("-w"))
    print(f"{platform.machine()}, {platform.python_version()}, {time.strftime('%Y-%m-%d')}")
    print("| garment | pieces | sew vertices | cut lines + notches ms | uniform buffer ms | "
          "ratio | notches | cloth added | uniform = buffer (no darts) |")
    print("|---|---|---|---|---|---|---|---|---|")
    rules = AllowanceRules()
    for path in files:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            g = load_garment(path, units="m")
        sews = [shapely.Polygon(g.piece_outline(i), g.piece_holes(i)) for i in range(g.n_pieces)]
        t_ours, (cuts, notches) = _best(_ours, g, rules)
        t_base, buffers = _best(_baseline, sews)
        uniform = cut_lines(g, AllowanceRules(10.0, 10.0, 10.0))
        plain = [i for i in range(g.n_pieces) if not dart_runs(g, i)]
        same = all(abs(uniform[i].cut.area - buffers[i].area) < 1e-6 * buffers[i].area
                   for i in plain)
        added = sum(c.cut.area for c in cuts) / sum(s.area for s in sews)
        n_notches = sum(len(n) for n in notches)
        name = str(path.relative_to(root))
        print(f"| {name} | {g.n_pieces} | {g.n_vertices} | {1e3 * t_ours:.1f} | "
              f"{1e3 * t_base:.1f} | {t_ours / t_base:.1f}x | {n_notches} | "
              f"{100 * (added - 1):.1f} % | {'yes' if same else 'NO'} |")


if __name__ == "__main__":
    main()
