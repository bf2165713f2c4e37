"""The console commands chain as an operator uses them, and the CLI starts light."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from solver.garment import load_garment
from station.cli import main


def test_align_then_nest_keeps_the_garment_units(tmp_path, data_dir, capsys):
    """A Berkeley file is in metres and does not say so: the placement must remember."""
    garment = data_dir / "garments" / "berkeley" / "pants-coarse.obj"
    fabric = tmp_path / "fabric.json"
    fabric.write_text(json.dumps({"group": "p4m", "w1": [50, 0], "w2": [0, 50]}))
    placement = tmp_path / "placement.json"
    assert main(["align", str(garment), "--units", "m", "--fabric", str(fabric),
                 "--restarts", "2", "-o", str(placement), "--json"]) == 0
    assert json.loads(placement.read_text())["garment_units"] == "m"
    layout = tmp_path / "layout.json"
    assert main(["nest", str(placement), "-o", str(layout), "--width", "1500",
                 "--time", "1", "--json"]) == 0
    capsys.readouterr()
    pieces = json.loads(layout.read_text())["pieces"]
    g = load_garment(garment, units="m")
    nested = sorted(abs(_area(np.asarray(p["sew_line"]))) for p in pieces)
    np.testing.assert_allclose(nested, sorted(g.piece_areas()), rtol=1e-6)
    assert min(nested) > 1e4  # square millimetres of a real trouser leg, not of a stamp
    cut = sorted(abs(_area(np.asarray(p["outline"]))) for p in pieces)
    assert all(c > s for c, s in zip(cut, nested))  # the cut lines carry the allowances


def _area(ring: np.ndarray) -> float:
    x, y = ring.T
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


@pytest.mark.parametrize("heavy", ["scipy", "shapely", "serial", "skimage", "spyrrow",
                                   "ezdxf", "triangle", "numba"])
def test_station_starts_without_the_heavy_libraries(heavy):
    """`station --help` lists every command; commands import their stack when run."""
    code = ("import contextlib, io, sys, station.cli\n"
            "with contextlib.suppress(SystemExit), contextlib.redirect_stdout(io.StringIO()):\n"
            "    station.cli.main(['--help'])\n"
            f"print({heavy!r} in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "False", f"`station --help` imports {heavy}"
