"""Left/right pairs through nesting (issue 14): LAYOUT.json records them, and
verify_layout checks that each "mirror" pair's print is still mirrored on the fabric."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from solver.align.symmetric import align_symmetric
from solver.garment import load_garment
from solver.garment.symmetry import mirror_pairs
from solver.nest import Layout, verify_layout
from solver.nest.solve import nest
from solver.nest.sources import load_problem
from solver.placement import Placement
from solver.wallpaper import Wallpaper

DATA = Path(__file__).resolve().parents[1] / "data"
PMM = Wallpaper("pmm", (45.0, 0.0), (0.0, 60.0), origin=(4.0, 2.0))


@pytest.fixture(scope="module")
def paired(tmp_path_factory):
    """The Berkeley t-shirt aligned with its three pairs mirrored, saved as PLACEMENT.json."""
    path = DATA / "garments" / "berkeley" / "tshirt-coarse.obj"
    garment = load_garment(path, units="m")
    placement = align_symmetric(garment, PMM, mirror_pairs(garment), compare=False,
                                method="paper", restarts=2, grain_tol_deg=1.0)
    placement.garment, placement.garment_units = str(path), "m"
    out = tmp_path_factory.mktemp("pairs") / "PLACEMENT.json"
    placement.save(out)
    return out, placement


def test_layout_records_pairs_and_keeps_them_mirrored(paired, tmp_path) -> None:
    path, placement = paired
    assert sorted(m for *_, m in placement.pairs) == ["mirror"] * 3
    problem = load_problem([path], width=1500.0, gap=3.0, quantity=2)
    layout = nest(problem, time_limit=2.0)
    names = [p.name for p in problem.pieces]
    expected = {(names[i], names[j]) for i, j, _ in placement.pairs}
    # every copy of a pair's first piece is paired with one copy of its second
    got = [(layout.pieces[a].name, layout.pieces[b].name, m) for a, b, m in layout.pairs]
    assert len(got) == 2 * len(expected)
    assert {(a, b) for a, b, _ in got} == expected and {m for *_, m in got} == {"mirror"}
    assert verify_layout(layout, problem) == []
    out = tmp_path / "LAYOUT.json"
    layout.save(out)
    assert Layout.load(out).pairs == layout.pairs
    # a layout that loses its pairs is refused
    layout.pairs = layout.pairs[1:]
    assert any("pairs" in f for f in verify_layout(layout, problem))


def test_a_pair_whose_print_is_not_mirrored_is_reported(paired, tmp_path) -> None:
    _, placement = paired
    i, j, _ = placement.pairs[0]
    broken = Placement.from_dict(placement.to_dict())
    broken.translations[j] += 0.5 * np.asarray(PMM.w1) + (3.0, 0.0)  # off by 25.5 mm
    path = tmp_path / "PLACEMENT.json"
    broken.save(path)
    problem = load_problem([path], width=1500.0, gap=3.0)
    layout = nest(problem, time_limit=2.0)
    faults = verify_layout(layout, problem)
    names = [p.name for p in problem.pieces]
    assert len(faults) == 1 and "no longer mirrored" in faults[0]
    assert names[i] in faults[0] and names[j] in faults[0]
