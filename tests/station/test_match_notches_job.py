"""``--match-notches`` as a job option (issue 34, item 5): `station submit`, an order file
and the daemon's job rules put the balance notches on the print's lattice lines, as the
command line's ``fit``/``nest``/``reshape`` do; a job that does not ask keeps ~200 mm."""

from __future__ import annotations

import argparse
import shutil
from collections import defaultdict

import numpy as np
import pytest

from solver.garment import load_garment
from solver.garment.allowance import AllowanceRules
from solver.garment.notches import cut_ready, placement_lattice
from solver.placement import Placement
from solver.wallpaper import Wallpaper
from station.allowance import rules_for_job
from station.commands import submit
from station.config import load_config
from station.order import read_order
from station.steps.submission import check_job
from untrusted import InputError

CONFIG = load_config(None)


def _on_lattice_share(garment, rules: AllowanceRules, placement: Placement) -> float:
    """The share of inner balance-notch stations with a twin on a lattice line."""
    _, notches = cut_ready(garment, rules, placement)
    lattice = placement_lattice(placement)
    stations = defaultdict(list)
    for q in (q for per_piece in notches for q in per_piece):
        f = lattice(q.piece, q.sew_point[None])[0]
        stations[q.seam_line, q.station].append(np.abs(f - np.round(f)).min() < 1e-6)
    last = defaultdict(int)
    for line, k in stations:
        last[line] = max(last[line], k)
    return float(np.mean([any(v) for (line, k), v in stations.items() if 0 < k < last[line]]))


def test_submit_sends_it_and_the_job_rules_match_the_lattice(data_dir) -> None:
    parser = argparse.ArgumentParser()
    submit.register(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["submit", "g.obj", "--fabric", "f.json", "--match-notches"])
    assert submit._options(args) == {"match_notches": True}
    plain = parser.parse_args(["submit", "g.obj", "--fabric", "f.json"])
    assert "match_notches" not in submit._options(plain)
    garment = str(data_dir / "garments" / "garment_pattern_generator" / "tee.json")
    check_job(garment, None, {"match_notches": True, "match_stripes": False}, CONFIG)
    with pytest.raises(ValueError, match="job option match_notches must be true or false"):
        check_job(garment, None, {"match_notches": "yes"}, CONFIG)
    # the rules a job's marker is cut with: on the lattice lines only when asked
    g = load_garment(data_dir / "garments" / "berkeley" / "pants-coarse.obj", units="m")
    placement = Placement.identity(g.n_pieces, Wallpaper("p4m", [60.0, 0.0], [0.0, 60.0],
                                                         [7.0, 3.0]))
    placement.angles[:] = np.radians(np.arange(g.n_pieces) * 30.0 + 10.0)
    asked, default = (rules_for_job(CONFIG, o) for o in ({"match_notches": True}, {}))
    assert asked.notch_on_print and not default.notch_on_print
    assert _on_lattice_share(g, default, placement) < 0.2
    assert _on_lattice_share(g, asked, placement) > 0.5


def test_an_order_file_asks_for_its_whole_marker(tmp_path, data_dir) -> None:
    shutil.copyfile(data_dir / "garments" / "garment_pattern_generator" / "tee.json",
                    tmp_path / "tee.json")
    body = '[[garment]]\npattern = "tee.json"\ncopies = 2\n'
    (tmp_path / "po.toml").write_text("match_notches = true\n" + body)
    order = read_order(tmp_path / "po.toml")
    assert order.match_notches and order.to_dict()["match_notches"]
    assert order.job_options({"restarts": 3}) == {"match_notches": True, "restarts": 3}
    assert order.job_options({"match_notches": False}) == {"match_notches": False}
    assert order.rules(AllowanceRules()).notch_on_print
    assert rules_for_job(CONFIG, order.job_options({})).notch_on_print
    (tmp_path / "plain.toml").write_text(body)
    plain = read_order(tmp_path / "plain.toml")
    assert not plain.match_notches and not plain.rules(AllowanceRules()).notch_on_print
    (tmp_path / "bad.toml").write_text('match_notches = "yes"\n' + body)
    with pytest.raises(InputError, match="match_notches"):
        read_order(tmp_path / "bad.toml")
