"""`station nest PLACEMENT.json --plain`: the same pieces on plain cloth, still on grain.

The plain marker is the baseline every printed marker is measured against, so it must
nest exactly the pieces the printed one nests (same cut lines), with the grain rule of
the placement (turns by 0/180 degrees from the aligned position, 0 only with a nap)
and no print constraint.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from solver.nest import Layout
from solver.nest.instance import angle_of, compose, invert
from solver.placement import Placement
from station.cli import main

DATA = Path(__file__).resolve().parents[1] / "data"


@pytest.fixture(scope="module")
def placement(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("plain")
    fabric = tmp / "fabric.json"
    fabric.write_text(json.dumps({"group": "p4m", "w1": [50, 0], "w2": [0, 50]}))
    out = tmp / "placement.json"
    assert main(["align", str(DATA / "garments" / "berkeley" / "tshirt-coarse.obj"),
                 "--units", "m", "--fabric", str(fabric), "--restarts", "2",
                 "-o", str(out), "--json"]) == 0
    return out


def turns_from_aligned(layout: Layout, placement: Placement) -> list[float]:
    """Each piece's turn (deg) relative to its aligned position on the print."""
    out = []
    for p, a, t in zip(layout.pieces, placement.angles, placement.translations):
        r = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        base = np.column_stack([r.T, -r.T @ t])  # garment -> aligned frame
        g = compose(p.transform, invert(base))
        assert not p.mirrored and np.linalg.det(g[:, :2]) > 0  # nothing flipped face down
        out.append(angle_of(g, False) % 360.0)
    return out


def _nest(placement, tmp_path, capsys, *extra) -> tuple[Layout, dict]:
    out = tmp_path / f"layout{len(extra)}.json"
    assert main(["nest", str(placement), "-o", str(out), "--width", "1500", "--gap", "2",
                 "--time", "1.5", "--json", *extra]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    return Layout.load(out), summary


def test_plain_nests_the_printed_pieces_on_grain_without_the_print(placement, tmp_path, capsys):
    plain, s_plain = _nest(placement, tmp_path, capsys, "--plain")
    printed, s_printed = _nest(placement, tmp_path, capsys)
    assert s_plain["printed"] is False and plain.fabric is None
    assert s_printed["printed"] is True and printed.fabric is not None
    by_name = {p.name: p for p in printed.pieces}
    assert sorted(by_name) == sorted(p.name for p in plain.pieces)
    for p in plain.pieces:  # the same cut lines, not pieces remade for plain cloth
        assert p.polygon().area == pytest.approx(by_name[p.name].polygon().area, rel=1e-9)
    pl = Placement.load(placement)
    turns = turns_from_aligned(plain, pl)
    assert all(min(abs(t - 0), abs(t - 180), abs(t - 360)) < 1e-6 for t in turns)
    # free of the lattice: some piece sits off every whole lattice vector of the print
    off = [np.abs(p.transform[:, 2] - by_name[p.name].transform[:, 2]) % 50.0 for p in plain.pieces]
    assert any(np.all(np.minimum(o, 50 - o) > 1e-3) for o in off)


def test_plain_with_a_nap_keeps_every_piece_unturned(placement, tmp_path, capsys):
    layout, _ = _nest(placement, tmp_path, capsys, "--plain", "--nap")
    turns = turns_from_aligned(layout, Placement.load(placement))
    assert all(min(t, 360 - t) < 1e-6 for t in turns)


def test_plain_refuses_a_fabric_in_one_line(placement, tmp_path, capsys):
    fabric = tmp_path / "f.json"
    fabric.write_text(json.dumps({"group": "p1", "w1": [40, 0], "w2": [0, 40]}))
    code = main(["nest", str(placement), "-o", str(tmp_path / "x.json"), "--plain",
                 "--fabric", str(fabric)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "--plain" in err[0]
