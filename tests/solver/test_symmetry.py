"""Mirror pairs and centre seams (solver.garment.symmetry) on patterns whose pairs are known."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from solver.garment import load_garment
from solver.garment.symmetry import (
    FLIP,
    MIRROR_TOLERANCE,
    centre_seams,
    mirror_pairs,
    read_pairs_file,
)
from station.cli import main

REPO = Path(__file__).resolve().parents[2]
DATA = REPO / "tests" / "data" / "garments"

# Known left/right pairs, by piece name (JSON) or by index (Berkeley OBJ, read off the
# 3D drape: the two pieces lie on either side of the body's sagittal plane).
KNOWN = {
    "garmentcode/tshirt_specification.json": [
        ("right_btorso", "left_btorso"), ("right_ftorso", "left_ftorso"),
        ("right_sleeve_b", "left_sleeve_b"), ("right_sleeve_f", "left_sleeve_f")],
    "garmentcode/shirt_mean_specification.json": [
        ("right_btorso", "left_btorso"), ("right_ftorso", "left_ftorso"),
        ("right_sleeve_b", "left_sleeve_b"), ("right_sleeve_f", "left_sleeve_f")],
    "garmentcode/pants_specification.json": [("pant_b_r", "pant_b_l"), ("pant_f_r", "pant_f_l")],
    "garment_pattern_generator/tee.json": [("lfsleeve", "rfsleeve"), ("lbsleeve", "rbsleeve")],
    "garment_pattern_generator/pants_straight_sides.json": [
        ("Lback", "Rback"), ("Lfront", "Rfront")],
}


def _pairs_by_name(g, pairs) -> set[frozenset[str]]:
    return {frozenset((g.piece_names[p.first], g.piece_names[p.second])) for p in pairs}


@pytest.mark.parametrize("name", sorted(KNOWN))
def test_pairs_of_json_patterns_are_the_named_pairs(name: str) -> None:
    g = load_garment(DATA / name)
    assert _pairs_by_name(g, mirror_pairs(g)) == {frozenset(p) for p in KNOWN[name]}


def test_berkeley_tshirt_pairs_and_centre_seams() -> None:
    g = load_garment(REPO / "examples" / "tshirt-iso.obj", units="m")
    pairs = mirror_pairs(g)
    # sleeves 0 and 3, backs 1 and 2, fronts 4 and 5
    assert {(p.first, p.second) for p in pairs} == {(0, 3), (1, 2), (4, 5)}
    centre = {frozenset((g.seam_lines[k].piece_a, g.seam_lines[k].piece_b))
              for k in centre_seams(g, pairs)}
    assert centre == {frozenset((1, 2)), frozenset((4, 5))}  # centre back and centre front
    # The pairs are mirror images in 3D too: the drape's two halves sit on either side of
    # one plane, so their centroids differ mainly along one axis, the same for all pairs.
    offsets = np.array([g.xyz[g.piece_of_vertex == p.first].mean(0)
                        - g.xyz[g.piece_of_vertex == p.second].mean(0) for p in pairs[1:]])
    axis = np.argmax(np.abs(offsets).sum(0))
    assert np.all(np.abs(offsets[:, axis]) > 3 * np.abs(np.delete(offsets, axis, 1)).max(1))


def test_mirror_map_lands_on_the_partner_outline() -> None:
    g = load_garment(DATA / "berkeley" / "tshirt-coarse.obj", units="m")
    for p in mirror_pairs(g):
        a, b = g.piece_outline(p.first), g.piece_outline(p.second)
        moved = p.map_first_to_second(a)
        # every mapped outline vertex lies near the partner's outline (within a few RMS)
        d = np.min(np.linalg.norm(moved[:, None] - b[None], axis=2), axis=1)
        assert np.median(d) < 4 * p.rms_mm + 10.0
        assert np.linalg.det(p.rotation @ FLIP) < 0  # a reflection, not a rotation
        assert p.relative_rms <= MIRROR_TOLERANCE


def test_a_reshaped_half_is_no_longer_a_pair() -> None:
    g = load_garment(DATA / "garmentcode" / "pants_specification.json")
    names = g.piece_names
    i = names.index("pant_f_l")
    base = {frozenset(p) for p in _pairs_by_name(g, mirror_pairs(g))}
    assert frozenset(("pant_f_r", "pant_f_l")) in base
    # stretch one front leg by 6 % across: its outline differs from its partner by far more
    # than 1 % of its size
    uv = g.uv.copy()
    on = g.piece_of_vertex == i
    centre = uv[on].mean(0)
    uv[on, 0] = centre[0] + 1.06 * (uv[on, 0] - centre[0])
    found = _pairs_by_name(g, mirror_pairs(g.with_uv(uv)))
    assert frozenset(("pant_f_r", "pant_f_l")) not in found
    assert frozenset(("pant_b_r", "pant_b_l")) in found


def test_declared_and_vetoed_pairs(tmp_path: Path) -> None:
    g = load_garment(DATA / "garment_pattern_generator" / "tee.json")
    f = tmp_path / "pairs.json"
    f.write_text(json.dumps({"pairs": [["front", "back"]],
                             "not_pairs": [["lfsleeve", "rfsleeve"]]}))
    declared, vetoed = read_pairs_file(f, g)
    found = _pairs_by_name(g, mirror_pairs(g, declared=declared, vetoed=vetoed))
    assert frozenset(("front", "back")) in found
    assert frozenset(("lfsleeve", "rfsleeve")) not in found
    assert all(len(p) == 2 for p in found) and len(set().union(*found)) == 2 * len(found)
    f.write_text(json.dumps({"pairs": [["front", "nosuchpiece"]]}))
    with pytest.raises(ValueError, match=r"pairs.json: no piece 'nosuchpiece'"):
        read_pairs_file(f, g)


def test_inspect_json_lists_pairs_and_centre_seams(tmp_path: Path, capsys) -> None:
    """`station inspect`, run in this process as the executable runs it (no interpreter
    start per command)."""
    garment = REPO / "examples" / "tshirt-iso.obj"
    assert main(["inspect", str(garment), "--units", "m", "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert sorted(map(tuple, s["mirror_pairs"])) == [(0, 3), (1, 2), (4, 5)]
    names = {s["seam_line_list"][k]["name"] for k in s["centre_seams"]}
    assert names == {"piece1~piece2", "piece4~piece5"}
    bad = tmp_path / "p.json"
    bad.write_text("[1, 2]")
    assert main(["inspect", str(garment), "--units", "m", "--pairs", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(bad) in err


def test_shared_berkeley_pairs_are_mirrored_across_the_body(shared_data: Path) -> None:
    """On every Berkeley garment with a drape, each pair found sits on both sides of the
    body: its two pieces' 3D centroids mirror each other across the garment's median plane."""
    root = shared_data / "garments" / "berkeley_garment_library" / "Garments"
    files = [f for f in sorted(root.rglob("*.obj")) if not f.stem.endswith(("-m", "-w"))]
    assert files
    for f in files:
        g = load_garment(f, units="m")
        pairs = mirror_pairs(g)
        if not pairs or g.xyz is None:
            continue
        centre = g.xyz.mean(0)
        for p in pairs:
            ca = g.xyz[g.piece_of_vertex == p.first].mean(0) - centre
            cb = g.xyz[g.piece_of_vertex == p.second].mean(0) - centre
            # mirrored across some plane through the body: |ca| ~ |cb|, and ca + cb lies
            # much closer to the plane than ca - cb is long
            assert abs(np.linalg.norm(ca) - np.linalg.norm(cb)) < 0.1 * np.linalg.norm(ca - cb) \
                + 20.0, (f.name, p.first, p.second)
