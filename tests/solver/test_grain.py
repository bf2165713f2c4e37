"""Grain lines: each piece's grain from the file, the operator, the drape or a warned guess,
and placements that keep every piece on the fabric's grain."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from solver.align import align
from solver.align.grain import GrainRule
from solver.garment import build_garment, load_garment
from solver.garment.grain import detect_up, drape_grain, parse_grain_lines, parse_up
from solver.wallpaper import Wallpaper

DATA = Path(__file__).resolve().parents[1] / "data" / "garments"
BERKELEY = sorted((DATA / "berkeley").glob("*.obj"))
PLAID = Wallpaper("pmm", (60.0, 0.0), (0.0, 80.0))
# The vertical of each bundled drape, read off its openings (waist, hem, neck loops lie
# across it): the coarse skirt is modelled lying along y, the others stand along z.
VERTICAL = {"skirt-coarse.obj": "y"}


def _face_jacobians(g) -> tuple[np.ndarray, np.ndarray]:
    """(F,3,2) pattern -> 3D Jacobian and (F,) pattern area of every face (test's own)."""
    f = g.faces
    e2 = np.stack([g.uv[f[:, 1]] - g.uv[f[:, 0]], g.uv[f[:, 2]] - g.uv[f[:, 0]]], axis=2)
    e3 = np.stack([g.xyz[f[:, 1]] - g.xyz[f[:, 0]], g.xyz[f[:, 2]] - g.xyz[f[:, 0]]], axis=2)
    return e3 @ np.linalg.inv(e2), 0.5 * np.abs(np.linalg.det(e2))


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    c = float(a @ b / np.linalg.norm(a) / np.linalg.norm(b))
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def check_body_grain_vertical(g, up: np.ndarray) -> int:
    """Every body piece's grain, carried to 3D by the piece's mean Jacobian, points up:
    within 5 degrees of the vertical beyond the piece's own tilt (a piece whose surface
    leans cannot hold a vertical line). Returns how many body pieces were checked."""
    deg, limb = drape_grain(g, up)
    jac, area = _face_jacobians(g)
    pf = g.piece_of_face()
    checked = 0
    for i in np.flatnonzero(~limb):
        m = pf == i
        mean = np.einsum("f,fij->ij", area[m], jac[m]) / area[m].sum()
        d = np.array([np.cos(np.radians(deg[i])), np.sin(np.radians(deg[i]))])
        normal = np.cross(mean[:, 0], mean[:, 1])
        normal /= np.linalg.norm(normal)
        tilt = float(np.degrees(np.arcsin(min(1.0, abs(float(normal @ up))))))
        assert _angle(mean @ d, up) <= tilt + 5.0, (g.source, i, deg[i], tilt)
        checked += 1
    return checked


@pytest.mark.parametrize("path", BERKELEY, ids=lambda p: p.name)
def test_bundled_berkeley_body_grain_runs_along_the_vertical(path):
    g = load_garment(path, units="m")
    up = parse_up(VERTICAL.get(path.name, "z"))
    assert np.array_equal(detect_up(g.xyz), up)
    assert check_body_grain_vertical(g, up) >= 2
    assert all(gr.source == "drape" for gr in g.grains())


def test_shared_berkeley_body_grain_runs_along_the_vertical(shared_data):
    root = shared_data / "garments" / "berkeley_garment_library" / "Garments"
    files = [p for p in sorted(root.rglob("*.obj")) if not p.stem.endswith(("-m", "-w"))]
    assert files
    for path in files:
        g = load_garment(path, units="m")
        check_body_grain_vertical(g, detect_up(g.xyz))


def test_tshirt_sleeves_take_their_grain_along_the_arm():
    """The t-shirt's sleeves (pieces 2 and 3, tubes out to the sides) are limbs: their
    grain runs along the arm's axis, horizontal here, not up the body."""
    g = load_garment(DATA / "berkeley" / "tshirt-coarse.obj", units="m")
    up = parse_up("z")
    deg, limb = drape_grain(g, up)
    assert np.flatnonzero(limb).tolist() == [2, 3]
    jac, area = _face_jacobians(g)
    pf = g.piece_of_face()
    for i in (2, 3):
        m = pf == i
        mean = np.einsum("f,fij->ij", area[m], jac[m]) / area[m].sum()
        d = np.array([np.cos(np.radians(deg[i])), np.sin(np.radians(deg[i]))])
        assert _angle(mean @ d, up) > 45.0  # along the (outstretched) arm
        tip = g.xyz[g.piece_of_vertex == i].mean(0) - g.xyz.mean(0)
        assert _angle(mean @ d, -tip) < 90.0  # towards the shoulder, as a cap points


def test_pants_grain_is_the_patterns_long_axis():
    """The Berkeley pants pieces are drawn upright (955 mm tall): grain within 5 deg of
    +90 deg (towards the waist)."""
    g = load_garment(DATA / "berkeley" / "pants-coarse.obj", units="m")
    deg = np.array([gr.deg for gr in g.grains()])
    assert np.all(np.abs(deg - 90.0) < 5.0), deg


def _rectangle(width: float, height: float, turn_deg: float, grainline=None):
    c, s = np.cos(np.radians(turn_deg)), np.sin(np.radians(turn_deg))
    pts = np.array([[0, 0], [width, 0], [width, height], [0, height]], float)
    uv = pts @ np.array([[c, s], [-s, c]])
    return build_garment(uv, np.array([[0, 1, 2], [0, 2, 3]]), np.arange(4), xyz=None,
                         source="rect", kind="spec", grainlines=grainline)


def test_flat_pattern_grain_is_guessed_along_the_longest_axis_with_a_warning():
    g = _rectangle(100.0, 300.0, 30.0)  # long axis at 90 + 30 degrees
    with pytest.warns(UserWarning, match="guessed"):
        grains = g.grains()
    assert grains[0].source == "outline" and grains[0].guessed
    assert grains[0].deg == pytest.approx(120.0, abs=1e-6)


def test_file_grain_wins_then_operator_then_guess():
    line = {0: ((0.0, 0.0), (10.0, 10.0))}
    g = _rectangle(100.0, 300.0, 0.0, grainline=line)
    assert g.with_grain(lines={"0": 10.0}).grains()[0].source == "file"
    assert g.grains()[0].deg == pytest.approx(45.0)
    plain = _rectangle(100.0, 300.0, 0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the operator's grain is no guess: no warning
        got = plain.with_grain(lines={"piece0": 12.5}, bias=["0"]).grains()[0]
    assert (got.deg, got.source, got.bias) == (12.5, "operator", True)
    with pytest.raises(ValueError, match="no piece"):
        plain.with_grain(lines={"sleeve": 0.0})
    with pytest.raises(ValueError, match="PIECE=DEGREES"):
        parse_grain_lines(["front"])
    with pytest.raises(ValueError, match="up axis"):
        parse_up("w")


def _turns(placement, garment, fabric_grain_deg: float = 0.0) -> np.ndarray:
    """Each piece's grain turn relative to the fabric's grain, degrees in [0, 360)."""
    gamma = np.array([gr["grain_deg"] for gr in placement.grains])
    assert np.allclose(gamma, [gr.deg for gr in garment.grains()])
    return (np.degrees(placement.angles) + fabric_grain_deg - gamma) % 360.0


def _off(turns: np.ndarray, allowed) -> np.ndarray:
    d = (turns[:, None] - np.asarray(allowed)[None, :] + 180.0) % 360.0 - 180.0
    return np.abs(d).min(axis=1)


@pytest.mark.parametrize("name", ["tshirt-coarse.obj", "pants-coarse.obj"])
def test_default_placement_is_on_grain(name):
    g = load_garment(DATA / "berkeley" / name, units="m")
    p = align(g, PLAID, restarts=3)
    assert p.grain_rule == {"tolerance_deg": 1.0, "nap": False, "fabric_grain_deg": 0.0}
    assert np.all(_off(_turns(p, g), [0.0, 180.0]) <= 1.0)  # exactly, after rounding
    assert p.report["off_grain_max_deg"] <= 1.0
    free = align(g, PLAID, restarts=3, grain_tol_deg=None)
    assert free.report["off_grain_max_deg"] > 1.0  # the rule is what keeps the grain


def test_nap_bias_and_fabric_grain():
    g = load_garment(DATA / "berkeley" / "tshirt-coarse.obj", units="m")
    g = g.with_grain(bias=["piece2"])
    p = align(g, PLAID, restarts=3, nap=True, fabric_grain_deg=90.0, grain_tol_deg=0.5)
    turns = _turns(p, g, 90.0)
    straight = np.array([not gr.bias for gr in g.grains()])
    assert np.all(_off(turns[straight], [0.0]) <= 0.5 + 1e-6)
    assert np.all(_off(turns[~straight], [45.0, 315.0]) <= 0.5 + 1e-6)
    rule = GrainRule.from_garment(g, 0.5, nap=True, fabric_grain_deg=90.0)
    assert np.all(rule.violation(p.angles) <= 1e-9)


def test_nesting_keeps_the_placement_grain_rule(tmp_path):
    from solver.nest.sources import pieces_from_placement

    g = load_garment(DATA / "berkeley" / "pants-coarse.obj", units="m")
    for kwargs, want in (({}, (0.0, 180.0)), ({"nap": True}, (0.0,)),
                         ({"grain_tol_deg": None}, None)):
        p = align(g, PLAID, restarts=2, **kwargs)
        p.garment, p.garment_units = str(DATA / "berkeley" / "pants-coarse.obj"), "m"
        p.save(tmp_path / "P.json")
        pieces, _ = pieces_from_placement(tmp_path / "P.json")
        assert all(pc.orientations == want for pc in pieces)


SPECS = ["garmentcode/tshirt_specification.json", "garmentcode/shirt_mean_specification.json",
         "garmentcode/pants_specification.json",
         "garmentcode/skirt_many_panels_specification.json",
         "garment_pattern_generator/tee.json",
         "garment_pattern_generator/pants_straight_sides.json"]


@pytest.mark.parametrize("name", SPECS)
def test_a_specification_takes_its_grain_from_where_it_places_its_panels(name):
    """A specification places each panel around the body (y up): body panels take the
    grain that runs up the body there, limbs the grain along the limb, without a guess.
    (Guessed from the longest axis, skirt panels wider than long lay across the grain
    and torso panels 5-10 degrees off it.)"""
    g = load_garment(DATA / name)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no "guessed" warning
        grains = g.grains()
    assert {gr.source for gr in grains} == {"drape"}
    _, limb = drape_grain(g)
    up = np.array([0.0, 1.0, 0.0])
    for i, gr in enumerate(grains):
        d = np.array([np.cos(np.radians(gr.deg)), np.sin(np.radians(gr.deg))])
        image = g.panel_frames[i][:, :2] @ d
        if limb[i]:  # sleeves: along the arm, far from the body's vertical
            assert min(_angle(image, up), _angle(-image, up)) > 30.0, (name, g.piece_names[i])
        else:
            assert min(_angle(image, up), _angle(-image, up)) <= 5.0, (name, g.piece_names[i])
    sleeves = {g.piece_names[i] for i in np.flatnonzero(limb)}
    assert sleeves == {n for n in g.piece_names if "sleeve" in n}


def test_shared_specifications_run_their_body_grain_up_the_body(shared_data):
    root = shared_data / "garments"
    files = (sorted((root / "garmentcode").rglob("*_specification.json"))
             + sorted((root / "garment_pattern_generator").glob("*.json")))
    assert files
    for path in files:
        g = load_garment(path)
        deg, limb = drape_grain(g)
        for i in np.flatnonzero(~limb):
            d = np.array([np.cos(np.radians(deg[i])), np.sin(np.radians(deg[i]))])
            image = g.panel_frames[i][:, :2] @ d
            assert abs(image[1]) >= np.cos(np.radians(5.0)) * np.linalg.norm(image), (
                path.name, g.piece_names[i])
