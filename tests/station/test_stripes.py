"""A stripe print (FABRIC.json ``kind: stripes``, as `station detect` writes it) is read by
the commands as the 1-D lattice that matches stripes across the seams; a broken one is a
one-line error."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from solver.fit import fit_report
from solver.garment import load_garment
from solver.placement import Placement
from station.cli import main
from station.cliargs import load_fabric
from station.stripes import STRIPE_SLIDE_MM, stripe_print
from untrusted import InputError

PANTS = Path(__file__).resolve().parents[1] / "data" / "garments" / "berkeley" / "pants-coarse.obj"


def _stripes(tmp_path, **fields) -> Path:
    path = tmp_path / "stripes.json"
    path.write_text(json.dumps({"group": None, "kind": "stripes", "period": 1.5,
                                "direction_deg": 0.0, "units": "cm", **fields}))
    return path


def test_a_stripe_print_is_a_pm_lattice_with_its_period_across_the_stripes(tmp_path):
    wp = load_fabric(_stripes(tmp_path, direction_deg=30.0))
    along = np.array([np.cos(np.radians(30.0)), np.sin(np.radians(30.0))])
    assert wp.group == "pm"
    assert np.allclose(wp.w1, STRIPE_SLIDE_MM * along)  # a short step along the stripes
    assert np.isclose(np.hypot(*wp.w2), 15.0) and abs(wp.w2 @ along) < 1e-9  # cm -> mm
    # every point is equivalent to its mirror across the stripes (the reflection along
    # them) and to itself shifted along them: the symmetries every stripe sequence has
    p = np.array([[3.0, 7.0], [-20.0, 4.5], [0.3, -0.2]])
    mirrored = p - 2 * (p @ along)[:, None] * along
    assert np.abs(wp.closest(p, mirrored)[0]).max() < 1e-9
    assert np.abs(wp.closest(p, p + 137.0 * along)[0]).max() < 1e-9
    # and nothing across them but whole periods
    assert np.allclose(np.linalg.norm(wp.closest(p, p + 5.0 * wp.w2 / 15.0)[0], axis=1), 5.0)


def test_align_matches_stripes_across_the_seams(tmp_path, capsys):
    out = tmp_path / "placement.json"
    assert main(["align", str(PANTS), "--units", "m", "--fabric", str(_stripes(tmp_path)),
                 "--method", "global", "--restarts", "2", "-o", str(out), "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    placement = Placement.load(out)
    assert placement.fabric.group == "pm"
    fit = fit_report(load_garment(PANTS, units="m"), placement)
    across = placement.fabric.w2 / np.linalg.norm(placement.fabric.w2)
    # stripes meet across the seams: the mismatch across them (what shows) is below the
    # 3.75 mm that stripes falling anywhere would average (curved seams of different
    # shapes cannot meet everywhere: the t-shirt's straight side seams do, see
    # tests/station/test_capture_fabric.py)
    gap = np.abs(fit.vector @ across)
    assert np.average(gap, weights=fit.length) < 0.8 * 15.0 / 4
    assert rep["e_fit_aligned_mm2"] < 0.9 * rep["e_fit_random_mm2"]


@pytest.mark.parametrize("fields, fault", [
    ({"period": "wide"}, "period must be a number"),
    ({"period": 0.01}, "period = 0.01 is out of range"),
    ({"direction_deg": None}, "direction_deg must be a number"),
    ({"units": "furlong"}, "furlong"),
])
def test_a_broken_stripe_print_is_a_one_line_error(tmp_path, capsys, fields, fault):
    path = _stripes(tmp_path, **fields)
    with pytest.raises(InputError, match=fault):
        stripe_print(json.loads(path.read_text()), 0.0, str(path))
    assert main(["align", str(PANTS), "--units", "m", "--fabric", str(path),
                 "-o", str(tmp_path / "x.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"station: {path}") or str(path) in err
    assert "\n" not in err and "Traceback" not in err
