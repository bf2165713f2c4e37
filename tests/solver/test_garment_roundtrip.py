"""Export and re-import: save_obj keeps the pattern to 1e-6 mm, save_spec keeps outlines/seams."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from solver.garment import Garment, load_garment, save_obj, save_spec
from tests.solver.test_garment_obj import check_invariants

GARMENTS = [
    ("berkeley/tshirt-coarse.obj", "m"),
    ("berkeley/shorts-iso.obj", "m"),
    ("garmentcode/pants_boxmesh_res2.obj", None),
    ("garmentcode/tshirt_specification.json", None),
    ("garment_pattern_generator/tee.json", None),
]


def same_loop(a: np.ndarray, b: np.ndarray, tol: float) -> bool:
    """Equal closed polygons up to the starting vertex."""
    if a.shape != b.shape:
        return False
    start = int(np.argmin(np.linalg.norm(b - a[0], axis=1)))
    return bool(np.abs(np.roll(b, -start, axis=0) - a).max() <= tol)


def same_seams(g: Garment, h: Garment, tol: float = 1e-6) -> None:
    """Same twin pairs, compared by the positions of their endpoints (within tol mm)."""
    from scipy.spatial import cKDTree

    assert len(g.seam_edges) == len(h.seam_edges)
    p = g.uv[g.seam_edges].reshape(len(g.seam_edges), -1)  # (E,8): a, b, a2, b2
    q = h.uv[h.seam_edges]
    # the same twin pair may be written from either side and in either direction
    variants = np.concatenate([q[:, order].reshape(len(q), -1) for order in
                               ([0, 1, 2, 3], [1, 0, 3, 2], [2, 3, 0, 1], [3, 2, 1, 0])])
    dist, idx = cKDTree(variants).query(p)
    assert dist.max() <= tol
    assert len(np.unique(idx % len(q))) == len(q)  # one to one


@pytest.mark.parametrize(("name", "units"), GARMENTS)
def test_save_obj_round_trip(data_dir: Path, tmp_path: Path, name: str, units) -> None:
    g = load_garment(data_dir / "garments" / name, units=units)
    out = tmp_path / "out.obj"
    save_obj(g, out)
    h = load_garment(out)
    assert h.units_in_file == "mm"
    assert h.uv.shape == g.uv.shape
    assert np.abs(h.uv - g.uv).max() < 1e-6
    assert np.array_equal(h.faces, g.faces)
    if g.kind == "obj":  # both sides inferred the same way: identical rows
        assert np.array_equal(h.seam_edges, g.seam_edges)
    same_seams(g, h)
    assert h.piece_names == g.piece_names
    assert sorted((s.piece_a, s.piece_b) for s in h.seam_lines) == sorted(
        (s.piece_a, s.piece_b) for s in g.seam_lines
    )
    if g.xyz is None:
        assert h.xyz is None  # 2D-only stays 2D-only
    else:
        assert np.abs(h.xyz - g.xyz).max() < 1e-6
    check_invariants(h)


@pytest.mark.parametrize(("name", "units"), GARMENTS)
def test_save_spec_round_trip(data_dir: Path, tmp_path: Path, name: str, units) -> None:
    g = load_garment(data_dir / "garments" / name, units=units)
    out = tmp_path / "out.json"
    save_spec(g, out)
    spec = json.loads(out.read_text())
    assert set(spec["pattern"]["panels"]) == set(g.piece_names)
    assert len(spec["pattern"]["stitches"]) == len(g.seam_edges)
    # a resolution longer than every edge re-imports the outlines vertex for vertex
    h = load_garment(out, resolution_mm=1e6)
    assert h.kind == "spec" and h.n_pieces == g.n_pieces
    for i in range(g.n_pieces):
        assert same_loop(g.piece_outline(i), h.piece_outline(i), 1e-9)
    assert len(h.seam_edges) == len(g.seam_edges)
    same_seams(g, h)
    assert len(h.seam_lines) == len(g.seam_lines)
    check_invariants(h)


def test_grainlines_and_notches_survive_save_spec(data_dir: Path, tmp_path: Path) -> None:
    g = load_garment(data_dir / "garments" / "berkeley" / "pants-coarse.obj", units="m")
    assert g.grainlines == {} and g.notches == {}  # OBJ carries neither
    box = g.piece_bboxes()
    g.grainlines = {i: ((box[i, 0] + 10, box[i, 1] + 10), (box[i, 0] + 10, box[i, 3] - 10))
                    for i in (0, 2)}
    g.notches = {1: [tuple(g.piece_outline(1)[3]), tuple(g.piece_outline(1)[7])]}
    save_spec(g, tmp_path / "marks.json")
    h = load_garment(tmp_path / "marks.json", resolution_mm=1e6)
    assert set(h.grainlines) == {0, 2} and set(h.notches) == {1}
    for i in (0, 2):
        assert np.allclose(h.grainlines[i], g.grainlines[i], atol=1e-9)
    assert np.allclose(h.notches[1], g.notches[1], atol=1e-9)
    # a panel with a bad grain line is one clear error
    spec = json.loads((tmp_path / "marks.json").read_text())
    spec["pattern"]["panels"][h.piece_names[0]]["grainline"] = [[0, 0]]
    (tmp_path / "bad.json").write_text(json.dumps(spec))
    with pytest.raises(ValueError, match="grainline is not two 2D points"):
        load_garment(tmp_path / "bad.json")


def test_2d_only_obj_keeps_overlapping_pieces_apart(data_dir: Path, tmp_path: Path) -> None:
    """Pieces drawn on top of each other (panel frames) must not get welded on re-import."""
    g = load_garment(data_dir / "garments" / "garmentcode" / "skirt_many_panels_specification.json")
    first = g.piece_bboxes()[:, :2][g.piece_of_vertex]
    stacked = g.with_uv(g.uv - first)  # every piece moved to the origin: outlines overlap
    save_obj(stacked, tmp_path / "stacked.obj")
    h = load_garment(tmp_path / "stacked.obj")
    assert h.xyz is None and h.n_pieces == g.n_pieces
    assert np.abs(h.uv - stacked.uv).max() < 1e-6
    # positions are ambiguous here (identical panels lie on top of each other), but the
    # vertex order survives, so compare twin pairs by index, up to side and direction
    def canon(x: Garment) -> set:
        return {min((a, b, c, d), (b, a, d, c), (c, d, a, b), (d, c, b, a))
                for a, b, c, d in x.seam_edges.tolist()}

    assert canon(h) == canon(stacked) and len(h.seam_edges) == len(stacked.seam_edges)


def test_with_uv_and_weights(data_dir: Path) -> None:
    g = load_garment(data_dir / "garments" / "berkeley" / "pants-coarse.obj", units="m")
    moved = g.with_uv(g.uv * 2)
    assert np.allclose(moved.piece_outline(0), 2 * g.piece_outline(0))
    assert np.allclose(g.piece_areas() * 4, moved.piece_areas())
    assert moved.uv is not g.uv and np.array_equal(moved.seam_edges, g.seam_edges)
    with pytest.raises(ValueError, match="shape"):
        g.with_uv(g.uv[:5])
    name = g.seam_lines[2].name
    w = g.with_seam_weights({0: 3.0, name: 0.5})
    weights = w.seam_weights()
    assert np.all(weights[g.seam_line_of_edge == 0] == 3.0)
    assert np.all(weights[g.seam_line_of_edge == 2] == 0.5)
    assert np.all(weights[g.seam_line_of_edge == 1] == 1.0)
    assert np.all(g.seam_weights() == 1.0)  # the original is untouched
    with pytest.raises(ValueError, match="no seam line"):
        g.with_seam_weights({"nope": 1.0})
    c = g.copy()
    c.uv[0] = 99.0
    assert g.uv[0, 0] != 99.0


def test_outlines_are_ccw_boundaries(data_dir: Path) -> None:
    g = load_garment(data_dir / "garments" / "berkeley" / "shorts-iso.obj", units="m")
    for i in range(g.n_pieces):
        p = g.piece_outline(i)
        x, y = p[:, 0], p[:, 1]
        signed = 0.5 * (np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))
        # the outline encloses the whole piece (no holes in these pieces)
        assert signed == pytest.approx(g.piece_areas()[i], rel=1e-9)
        assert g.piece_holes(i) == []


def test_inspect_command(data_dir: Path, capsys: pytest.CaptureFixture) -> None:
    from station.cli import main

    path = data_dir / "garments" / "berkeley" / "pants-coarse.obj"
    assert main(["inspect", str(path), "--units", "m", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert (out["pieces"], out["seam_lines"], out["seam_edges"]) == (4, 6, 56)
    assert out["units_in_file"] == "m"
    assert sum(line["seam_edges"] for line in out["seam_line_list"]) == 56
    heights = [p["height_mm"] for p in out["piece_list"]]
    assert all(900 < h < 1000 for h in heights)  # pants legs about 95 cm long
    assert main(["inspect", str(path), "--units", "m"]) == 0
    assert "56 seam edges" in capsys.readouterr().out
    spec = data_dir / "garments" / "garmentcode" / "pants_specification.json"
    assert main(["inspect", str(spec), "--resolution-mm", "20", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert (out["pieces"], out["seam_edges"], out["units_in_file"]) == (6, 204, "cm")
    # Berkeley files are in metres but do not say so: inspect warns when read as mm
    assert main(["inspect", str(path), "--json"]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["units_in_file"] == "mm"
    assert "spans only 1.64 mm; if the file is in metres pass --units m" in captured.err
    assert main(["inspect", str(path) + ".missing"]) == 2
    assert capsys.readouterr().err.startswith("station inspect: error:")
