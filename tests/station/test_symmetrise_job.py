"""--symmetrise as a job option and through nesting: the pattern the job was aligned on is
the one that is cut."""

from __future__ import annotations

import json

import pytest

from solver.garment import load_garment
from station.config import load_config
from station.pipeline import StationPipeline, symmetrise_job


def test_the_job_option_is_checked_and_hears_the_vetoed_pairs(data_dir):
    garment = data_dir / "garments" / "berkeley" / "tshirt-coarse.obj"
    pipeline = StationPipeline(load_config(None))
    pipeline.check(str(garment), None, {"units": "m", "symmetrise": True})
    with pytest.raises(ValueError, match="symmetrise must be true or false"):
        pipeline.check(str(garment), None, {"units": "m", "symmetrise": "yes"})
    g = load_garment(garment, units="m")
    same, record = symmetrise_job(g, {})
    assert same is g and record is None  # not asked: nothing done
    _, record = symmetrise_job(g, {"symmetrise": True, "pairs": {"not_pairs": [[0, 1]]}})
    assert sorted((p.first, p.second) for p in record.pairs) == [(2, 3), (4, 5)]


def test_nesting_cuts_the_symmetrised_pattern_the_placement_was_made_on(tmp_path, data_dir):
    from station.cli import main
    from station.pipeline import nest_placement

    fabric = tmp_path / "fabric.json"
    fabric.write_text(json.dumps({"group": "pmm", "w1": [60, 0], "w2": [0, 80]}))
    garment = data_dir / "garments" / "berkeley" / "tshirt-coarse.obj"
    out = tmp_path / "P.json"
    assert main(["align", str(garment), "--units", "m", "--fabric", str(fabric),
                 "--restarts", "1", "--symmetrise", "-o", str(out)]) == 0
    layout = nest_placement(out, load_config(None, {"nest": {"seconds": 1.0}}), None, {})
    area = {p.name: p.polygon().area for p in layout.pieces}
    drawn = load_garment(garment, units="m").piece_areas()
    for a, b in ((0, 1), (2, 3), (4, 5)):  # the pairs of this t-shirt
        # as drawn the halves differ; cut, each pair is one pattern
        assert abs(drawn[a] - drawn[b]) > 1e-4 * drawn[a]
        assert area[f"piece{a}"] == pytest.approx(area[f"piece{b}"], rel=1e-7)
