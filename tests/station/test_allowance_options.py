"""A job's allowances: station.toml, then the job's options; refused at submission if wrong."""

from __future__ import annotations

import pytest

from station.allowance import rules_for_job
from station.config import ConfigError, example_toml, load_config
from station.pipeline import StationPipeline


def test_station_toml_sets_the_defaults_and_a_job_overrides_them(tmp_path):
    toml = tmp_path / "station.toml"
    toml.write_text("[allowance]\nseam_mm = 12\nhem_mm = 35\nnotch_spacing_mm = 80\n")
    config = load_config(toml)
    rules = rules_for_job(config, {})
    assert (rules.seam_mm, rules.hem_mm, rules.opening_mm) == (12.0, 35.0, 10.0)
    assert rules.notch_spacing_mm == 80.0
    job = rules_for_job(config, {"seam_allowance": 7, "allowance": {"3": 15, "hem": 25}})
    assert (job.seam_mm, job.hem_mm) == (7.0, 25.0) and job.overrides == {3: 15}
    assert "[allowance]" in example_toml() and "hem_mm = 20.0" in example_toml()
    toml.write_text("[allowance]\nseam_mm = -1\n")
    with pytest.raises(ConfigError, match="allowance.seam_mm must be at least 0"):
        load_config(toml)


@pytest.mark.parametrize("options, fault", [
    ({"seam_allowance": -3}, "seam_allowance"),
    ({"seam_allowance": True}, "seam_allowance"),
    ({"allowance": [10]}, "allowance must be an object"),
    ({"allowance": {"no-such-seam": 10}}, "no seam line, opening or piece"),
    ({"allowance": {"hem": "wide"}}, "must be a number"),
])
def test_submission_refuses_bad_allowance_options(data_dir, options, fault):
    pipeline = StationPipeline(load_config(None))
    garment = str(data_dir / "garments" / "berkeley" / "skirt-coarse.obj")
    pipeline.check(garment, None, {"units": "m"})  # the good job passes
    with pytest.raises(ValueError, match=fault):
        pipeline.check(garment, None, {"units": "m", **options})


def test_the_daemon_nests_a_job_with_its_own_allowances(tmp_path, data_dir):
    import json

    import numpy as np

    from solver.garment import load_garment
    from solver.placement import Placement
    from station.cli import main
    from station.steps.nest import nest_placement

    fabric = tmp_path / "fabric.json"
    fabric.write_text(json.dumps({"group": "p4m", "w1": [50, 0], "w2": [0, 50]}))
    garment = data_dir / "garments" / "garment_pattern_generator" / "tee.json"
    assert main(["align", str(garment), "--fabric", str(fabric), "--restarts", "1",
                 "-o", str(tmp_path / "P.json")]) == 0
    config = load_config(None, {"nest": {"seconds": 1.0}})
    placement = Placement.load(tmp_path / "P.json")
    layout = nest_placement(load_garment(garment), placement, config, None,
                            {"seam_allowance": 14, "allowance": {"hem": 26}})
    assert layout.allowance["seam_mm"] == 14.0 and layout.allowance["hem_mm"] == 26.0
    used = set(np.concatenate([p.allowance for p in layout.pieces]).tolist())
    assert {14.0, 26.0} <= used
