"""--symmetrise as a job option and through nesting: the pattern the job was aligned on is
the one that is cut."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from solver.garment import load_garment
from station.config import load_config
from station.pipeline import StationPipeline
from station.simstation import simulated_pipeline
from station.steps.garment import symmetrise_job


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
    import shapely

    from solver.nest.sources import pieces_from_placement
    from station.cli import main

    fabric = tmp_path / "fabric.json"
    fabric.write_text(json.dumps({"group": "pmm", "w1": [60, 0], "w2": [0, 80]}))
    garment = data_dir / "garments" / "berkeley" / "tshirt-coarse.obj"
    out = tmp_path / "P.json"
    assert main(["align", str(garment), "--units", "m", "--fabric", str(fabric),
                 "--restarts", "1", "--symmetrise", "-o", str(out)]) == 0
    pieces, _ = pieces_from_placement(out)  # what `station nest P.json` cuts
    area = [shapely.Polygon(p.outline).area for p in pieces]
    drawn = load_garment(garment, units="m").piece_areas()
    for a, b in ((0, 1), (2, 3), (4, 5)):  # the pairs of this t-shirt
        # as drawn the halves differ; cut, each pair is one pattern
        assert abs(drawn[a] - drawn[b]) > 1e-4 * drawn[a]
        assert area[a] == pytest.approx(area[b], rel=1e-7)


def test_a_job_asking_for_symmetrise_is_aligned_reshaped_and_cut_as_one_pattern(tmp_path,
                                                                              data_dir):
    from solver.garment.symmetry import fit_pairs, mirror_correspondence
    from station.daemon import JobControl
    from station.jobstore import JobStore

    garment = data_dir / "garments" / "berkeley" / "tshirt-coarse.obj"
    fabric = tmp_path / "pmm.json"
    fabric.write_text(json.dumps({"group": "pmm", "w1": [60, 0], "w2": [0, 80]}))
    config = load_config(None, {"nest": {"seconds": 1.0}, "reshape": {"enabled": True},
                                "align": {"restarts": 2, "method": "paper"}})
    pipeline = simulated_pipeline(config)
    store = JobStore(tmp_path / "jobs.db")
    job = store.submit(str(garment), str(fabric), {"units": "m", "symmetrise": True})
    control = JobControl(job.id)
    plan = pipeline.plan(job, pipeline.capture(job, tmp_path, control), tmp_path,
                         control).record()
    store.close()
    report = json.loads(Path(plan["report"]).read_text())
    assert sorted(map(tuple, report["symmetrise"]["pairs"])) == [(0, 1), (2, 3), (4, 5)]
    assert {m for *_, m in report["align"]["symmetry"]["pairs"]} == {"mirror"}
    cut = load_garment(tmp_path / "garment-reshaped.obj")  # what the station cut
    for p in fit_pairs(cut, [(0, 1), (2, 3), (4, 5)]):
        assert mirror_correspondence(cut, p) is not None
