"""Benchmark of garment import (solver.garment): every OBJ and JSON garment in shared data.

Per file: faces, pieces, seam edges and the best of three wall-clock import times, with
a baseline in the same process for the OBJ files: a plain line-by-line Python parse of
the same file (parsing only, no welding or seams), so the ratio shows what parsing whole
blocks with NumPy buys on this noisy shared machine.

    python -m bench garment            # prints a Markdown table for BENCHMARKS.md
"""

from __future__ import annotations

import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2] / "shared" / "data" / "garments"
BUNDLED = Path(__file__).resolve().parents[1] / "tests" / "data" / "garments"


def _files() -> list[tuple[Path, dict]]:
    """(path, load_garment options) for every garment; bundled copies without shared."""
    root = ROOT if ROOT.is_dir() else BUNDLED
    out = []
    for path in sorted(root.rglob("*.obj")):
        if "arcsim_meshes" in path.parts or path.stem.endswith("-w"):
            continue  # ARCSim: local only; -w: same garment as its -m partner
        units = "m" if "berkeley" in str(path) else None
        out.append((path, {"units": units}))
    for path in sorted(root.rglob("*.json")):
        out.append((path, {}))
    return out


def _naive_parse(path: Path) -> int:
    """Line-by-line OBJ parse into Python lists (the baseline)."""
    v, vt, f = [], [], []
    with open(path) as fh:
        for line in fh:
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                v.append([float(x) for x in parts[1:4]])
            elif parts[0] == "vt":
                vt.append([float(x) for x in parts[1:3]])
            elif parts[0] == "f":
                f.append([[int(i) for i in c.split("/") if i] for c in parts[1:]])
    return len(f)


def _best(fn, repeat: int = 3) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def main() -> None:
    from solver.garment import load_garment

    print("| file | faces | pieces | seam edges | import ms | naive parse only ms | ratio |")
    print("|---|---|---|---|---|---|---|")
    for path, kw in _files():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            g = load_garment(path, **kw)
            t = _best(lambda p=path, k=kw: load_garment(p, **k))
        if path.suffix == ".obj":
            base = _best(lambda p=path: _naive_parse(p))
            extra = f"{base * 1000:.0f} | {base / t:.1f}x"
        else:
            extra = "- | -"
        name = path.relative_to(path.parents[2]) if len(path.parents) > 2 else path.name
        print(f"| {name} | {len(g.faces)} | {g.n_pieces} | {len(g.seam_edges)} | "
              f"{t * 1000:.0f} | {extra} |", flush=True)


if __name__ == "__main__":
    main()
