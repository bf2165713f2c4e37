"""JSON pattern specifications: counts, units, curve geometry, stitch orientation."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from solver.garment import load_garment
from tests.solver.test_garment_obj import check_invariants

# panels and stitches from the SOURCE.md tables in shared/data/garments
GARMENTCODE = {
    "repo_specs/shirt_mean_specification.json": (8, 18),
    "repo_specs/dress_pencil_specification.json": (6, 23),
    "generated/tshirt/tshirt_specification.json": (8, 16),
    "generated/pants/pants_specification.json": (6, 24),
    "generated/skirt_many_panels/skirt_many_panels_specification.json": (6, 11),
    "generated/dress_pencil/dress_pencil_specification.json": (10, 44),
    "generated/dress_circle/dress_circle_specification.json": (12, 42),
}
GPG = {
    "tee.json": (6, 12),
    "pants_straight_sides.json": (4, 6),
    "skirt_4_panels.json": (4, 8),
    "jumpsuit_sleeveless.json": (6, 14),
    "dress_sleeveless.json": (4, 10),
}
BUNDLED = {
    "garmentcode/shirt_mean_specification.json": (8, 18),
    "garmentcode/tshirt_specification.json": (8, 16),
    "garmentcode/pants_specification.json": (6, 24),
    "garmentcode/skirt_many_panels_specification.json": (6, 11),
    "garment_pattern_generator/tee.json": (6, 12),
    "garment_pattern_generator/pants_straight_sides.json": (4, 6),
}


def check_spec(g, panels: int, stitches: int) -> None:
    """Pieces = panels, every stitch sewn, twins of equal count, 2D only."""
    assert g.kind == "spec" and g.xyz is None
    assert g.n_pieces == panels
    check_invariants(g)
    # each stitch gives at least one twin pair; stitched edges are sampled one to one, so
    # twin segments have nearly the same length unless the design gathers the seam
    assert len(g.seam_edges) >= stitches
    s = g.seam_edges
    l1 = np.linalg.norm(g.uv[s[:, 1]] - g.uv[s[:, 0]], axis=1)
    l2 = np.linalg.norm(g.uv[s[:, 3]] - g.uv[s[:, 2]], axis=1)
    assert np.median(l1 / l2) == pytest.approx(1.0, abs=0.02)
    # panels are laid out side by side, not on top of each other
    box = g.piece_bboxes()
    for i in range(panels):
        for j in range(i):
            assert box[i, 0] >= box[j, 2] or box[j, 0] >= box[i, 2] or (
                box[i, 1] >= box[j, 3] or box[j, 1] >= box[i, 3]
            )


@pytest.mark.parametrize("name", sorted(BUNDLED))
def test_bundled_specs(data_dir: Path, name: str) -> None:
    g = load_garment(data_dir / "garments" / name)
    check_spec(g, *BUNDLED[name])


def test_shared_specs(shared_data: Path) -> None:
    root = shared_data / "garments"
    for name, (panels, stitches) in GARMENTCODE.items():
        check_spec(load_garment(root / "garmentcode" / name), panels, stitches)
    for name, (panels, stitches) in GPG.items():
        check_spec(load_garment(root / "garment_pattern_generator" / name), panels, stitches)


def test_sampling_matches_garmentcode_boxmesh(data_dir: Path) -> None:
    """GarmentCode's own BoxMesh at 2 cm gives 204 seam / 107 open edges for these pants
    (SOURCE.md); sampling both edges of a stitch at the longer one's count reproduces it."""
    g = load_garment(data_dir / "garments" / "garmentcode" / "pants_specification.json",
                     resolution_mm=20)
    assert (len(g.seam_edges), g.boundary_3d_edges) == (204, 107)
    g = load_garment(
        data_dir / "garments" / "garmentcode" / "skirt_many_panels_specification.json",
        resolution_mm=20,
    )
    assert (len(g.seam_edges), g.boundary_3d_edges) == (147, 183)


def test_shared_sampling_matches_boxmesh_res1(shared_data: Path) -> None:
    root = shared_data / "garments" / "garmentcode" / "generated"
    for name, seams in (("tshirt", 320), ("dress_pencil", 677)):
        g = load_garment(root / name / f"{name}_specification.json", resolution_mm=10)
        assert len(g.seam_edges) == seams


def test_units_in_meter(data_dir: Path) -> None:
    # tee.json: units_in_meter 300, front panel 130 x 185 units = 0.43 x 0.62 m
    g = load_garment(data_dir / "garments" / "garment_pattern_generator" / "tee.json")
    assert g.units_in_file == "1/300 m"
    front = g.piece_names.index("front")
    box = g.piece_bboxes()[front]
    assert box[2] - box[0] == pytest.approx(130 / 0.3, rel=0.01)
    assert box[3] - box[1] == pytest.approx(185 / 0.3, rel=0.01)
    # cm file, overridden on the command line
    path = data_dir / "garments" / "garmentcode" / "skirt_many_panels_specification.json"
    cm = load_garment(path)
    mm = load_garment(path, units="mm", resolution_mm=2)
    assert cm.units_in_file == "cm" and mm.units_in_file == "mm"
    assert cm.piece_areas().sum() == pytest.approx(100 * mm.piece_areas().sum(), rel=1e-9)


def test_resolution_controls_mesh(data_dir: Path) -> None:
    path = data_dir / "garments" / "garmentcode" / "tshirt_specification.json"
    coarse = load_garment(path, resolution_mm=40)
    fine = load_garment(path, resolution_mm=10)
    assert len(fine.faces) > 8 * len(coarse.faces) > 0
    assert fine.piece_areas().sum() == pytest.approx(coarse.piece_areas().sum(), rel=1e-2)
    # mesh quality: Triangle with a 28 degree minimum angle away from the boundary
    e = fine.uv[fine.faces[:, [1, 2, 0]]] - fine.uv[fine.faces]
    lengths = np.linalg.norm(e, axis=2)
    assert np.percentile(lengths.max(axis=1), 99) < 10 * 1.5
    with pytest.raises(ValueError, match="resolution"):
        load_garment(path, resolution_mm=0)


def write_spec(path: Path, panels: dict, stitches: list, units_in_meter: float = 1000) -> Path:
    spec = {
        "pattern": {"panels": panels, "stitches": stitches},
        "properties": {"curvature_coords": "relative", "units_in_meter": units_in_meter},
    }
    path.write_text(json.dumps(spec))
    return path


def square(curvature=None, size=100.0) -> dict:
    """CCW square; edge 0 runs along the bottom from (0,0) to (size,0)."""
    v = [[0, 0], [size, 0], [size, size], [0, size]]
    edges = [{"endpoints": [k, (k + 1) % 4]} for k in range(4)]
    if curvature is not None:
        edges[0]["curvature"] = curvature
    return {"vertices": v, "edges": edges, "translation": [0, 0, 0], "rotation": [0, 0, 0]}


@pytest.mark.parametrize(
    ("curvature", "extra_area"),
    [
        (None, 0.0),
        # semicircle bulging to the right of travel (outward, below the square)
        ({"type": "circle", "params": [50.0, 0, 1]}, math.pi * 50**2 / 2),
        # bulging to the left (into the square)
        ({"type": "circle", "params": [50.0, 0, 0]}, -math.pi * 50**2 / 2),
        # quadratic, control point at relative height -0.5: parabola of height 25 outward
        ({"type": "quadratic", "params": [[0.5, -0.5]]}, 2 / 3 * 100 * 25),
        # Garment-Pattern-Generator form of the same curve
        ([0.5, -0.5], 2 / 3 * 100 * 25),
        # cubic with both controls at height -0.4 (and x at thirds): area = L*h/2
        ({"type": "cubic", "params": [[1 / 3, -0.4], [2 / 3, -0.4]]}, 100 * 40 / 2),
    ],
)
def test_curve_geometry(tmp_path: Path, curvature, extra_area: float) -> None:
    path = write_spec(tmp_path / "one.json", {"a": square(curvature)}, [])
    g = load_garment(path, resolution_mm=2)
    assert g.units_in_file == "mm"
    assert g.piece_areas()[0] == pytest.approx(100 * 100 + extra_area, rel=2e-3)
    assert len(g.seam_edges) == 0


def test_stitch_orientation(tmp_path: Path) -> None:
    """Default: edge 1's end meets edge 2's start; right_wrong: start meets start."""
    a, b = square(), square()
    for right_wrong in (False, True):
        st = [{"panel": "a", "edge": 1}, {"panel": "b", "edge": 3}]
        if right_wrong:
            st.append("right_wrong")
        path = write_spec(tmp_path / f"two{right_wrong}.json", {"a": a, "b": b}, [st])
        g = load_garment(path, resolution_mm=10)
        assert len(g.seam_edges) == 10 and len(g.seam_lines) == 1
        assert (g.seam_lines[0].piece_a, g.seam_lines[0].piece_b) == (0, 1)
        s = g.seam_edges
        # panel b was laid out to the right of a: undo that shift to compare frames
        shift = g.piece_bboxes()[1, 0]
        pa = g.uv[s[:, 0]]
        pb = g.uv[s[:, 2]] - [shift, 0]
        # a's edge 1 runs up x=100 (y 0->100); b's edge 3 runs down x=0 (y 100->0)
        assert np.allclose(pa[:, 0], 100) and np.allclose(pb[:, 0], 0)
        if right_wrong:  # same direction: a at height y meets b at height 100 - y
            assert np.allclose(pb[:, 1], 100 - pa[:, 1])
        else:  # a's end (y=100) meets b's start (y=100): same heights
            assert np.allclose(pb[:, 1], pa[:, 1])


def test_self_stitch_and_uneven_lengths(tmp_path: Path) -> None:
    """A tube (a piece sewn to itself) and a gathered seam (edges of different length)."""
    tube = square()
    wide = square(size=200.0)
    stitches = [
        [{"panel": "tube", "edge": 1}, {"panel": "tube", "edge": 3}],
        [{"panel": "tube", "edge": 2}, {"panel": "wide", "edge": 0}],
    ]
    path = write_spec(tmp_path / "tube.json", {"tube": tube, "wide": wide}, stitches)
    g = load_garment(path, resolution_mm=10)
    lines = {(s.piece_a, s.piece_b): s for s in g.seam_lines}
    assert set(lines) == {(0, 0), (0, 1)}
    counts = np.bincount(g.seam_line_of_edge)
    # the gathered seam takes the longer edge's count (20) on both sides
    k = [i for i, s in enumerate(g.seam_lines) if (s.piece_a, s.piece_b) == (0, 1)][0]
    assert counts[k] == 20
    check_invariants(g)


def outline_gap_pair(outline: np.ndarray) -> tuple[int, int]:
    """The two outline vertices two steps apart that are closest (the legs of a dart)."""
    d = np.linalg.norm(outline - np.roll(outline, -2, axis=0), axis=1)
    i = int(np.argmin(d))
    return i, (i + 2) % len(outline)


def reshaped_like(g, cross: bool):
    """A non-rigid deformation of real data, as reshaping makes: twin seam segments of
    unequal length, segments longer than the sampling resolution, optionally a dart whose
    legs cross (the outline crosses itself)."""
    uv = g.uv + 4.0 * np.sin(g.uv[:, ::-1] / 23.0)
    if cross:
        loop = g.piece_loops(0)[0]
        i, j = outline_gap_pair(uv[loop])
        uv[loop[i]] += 2.0 * (uv[loop[j]] - uv[loop[i]])  # one leg past the other
    return g.with_uv(uv)


@pytest.mark.parametrize(("name", "cross"), [
    ("garmentcode/pants_specification.json", True),
    ("garment_pattern_generator/tee.json", False),
])
def test_save_spec_reads_back_the_pattern_it_wrote(
    data_dir: Path, tmp_path: Path, name: str, cross: bool
) -> None:
    """Issue 4: the JSON re-imports to the same outlines within 1e-6 mm, same seams."""
    from shapely import LinearRing

    from solver.garment import save_spec
    from solver.garment.spec import DEFAULT_RESOLUTION_MM

    g = load_garment(data_dir / "garments" / name)
    new = reshaped_like(g, cross)
    s = new.seam_edges
    l1 = np.linalg.norm(new.uv[s[:, 1]] - new.uv[s[:, 0]], axis=1)
    l2 = np.linalg.norm(new.uv[s[:, 3]] - new.uv[s[:, 2]], axis=1)
    assert np.abs(l1 - l2).max() > 0.5 and max(l1.max(), l2.max()) > DEFAULT_RESOLUTION_MM
    assert LinearRing(new.piece_outline(0)).is_simple != cross
    out = tmp_path / "reshaped.json"
    if cross:
        with pytest.warns(UserWarning, match=f"outline of {g.piece_names[0]} crosses itself"):
            save_spec(new, out)
    else:
        save_spec(new, out)
    back = load_garment(out)  # default resolution: the written mesh is used as it is
    assert back.piece_names == new.piece_names
    for i in range(new.n_pieces):
        a, b = new.piece_outline(i), back.piece_outline(i)
        start = int(np.argmin(np.linalg.norm(b - a[0], axis=1)))
        assert a.shape == b.shape and np.abs(np.roll(b, -start, axis=0) - a).max() < 1e-6
    # the very mesh comes back (numbering included), so measures on it agree exactly
    assert np.abs(back.uv - new.uv).max() < 1e-6 and np.array_equal(back.faces, new.faces)
    assert np.array_equal(back.seam_edges, new.seam_edges)
    assert [(x.piece_a, x.piece_b) for x in back.seam_lines] == [
        (x.piece_a, x.piece_b) for x in g.seam_lines]
    check_invariants(back)


def test_spec_without_mesh_still_samples_and_triangulates(data_dir: Path, tmp_path: Path) -> None:
    """A specification without meshes (older save_spec files, hand edits) is sampled as
    before: unequal twins share the longer one's count, outlines kept vertex for vertex
    when the resolution is coarser than every segment."""
    from solver.garment import save_spec

    g = load_garment(data_dir / "garments" / "garment_pattern_generator" / "tee.json")
    new = reshaped_like(g, cross=False)
    save_spec(new, tmp_path / "with.json")
    spec = json.loads((tmp_path / "with.json").read_text())
    for panel in spec["pattern"]["panels"].values():
        del panel["mesh"]
    (tmp_path / "without.json").write_text(json.dumps(spec))
    fine = load_garment(tmp_path / "without.json")  # 20 mm: long segments are split
    assert len(fine.seam_edges) > len(new.seam_edges)
    assert sorted((x.piece_a, x.piece_b) for x in fine.seam_lines) == sorted(
        (x.piece_a, x.piece_b) for x in g.seam_lines)
    coarse = load_garment(tmp_path / "without.json", resolution_mm=1e6)
    assert len(coarse.seam_edges) == len(new.seam_edges)
    for i in range(new.n_pieces):
        assert len(coarse.piece_outline(i)) == len(new.piece_outline(i))
    check_invariants(fine)


@pytest.mark.parametrize(("breakage", "message"), [
    ("corner", "mesh triangle corner .* is not a vertex"),
    ("curve", "has a mesh, so edge 0 must be the straight edge"),
    ("hole", "edge .* is not on the boundary of its mesh"),
    ("keys", "mesh needs 'interior' 2D points and 'triangles'"),
    ("shape", "mesh triangles are not rows of 3 integers"),
])
def test_bad_panel_mesh_is_one_clear_error(
    data_dir: Path, tmp_path: Path, breakage: str, message: str
) -> None:
    from solver.garment import save_spec
    from solver.garment.errors import GarmentError

    g = load_garment(data_dir / "garments" / "garment_pattern_generator"
                     / "pants_straight_sides.json")
    save_spec(g, tmp_path / "ok.json")
    spec = json.loads((tmp_path / "ok.json").read_text())
    panel = spec["pattern"]["panels"][g.piece_names[0]]
    n = len(panel["vertices"])
    tri = np.asarray(panel["mesh"]["triangles"])
    if breakage == "corner":
        panel["mesh"]["triangles"][0][0] = n + len(panel["mesh"]["interior"])
    elif breakage == "curve":
        panel["edges"][0]["curvature"] = [0.5, 0.2]
    elif breakage == "hole":  # drop a triangle on the outline: its edge leaves the boundary
        on_edge = ((tri < n).sum(axis=1) >= 2).argmax()
        del panel["mesh"]["triangles"][int(on_edge)]
    elif breakage == "keys":
        del panel["mesh"]["interior"]
    else:
        panel["mesh"]["triangles"] = [[0, 1]]
    (tmp_path / "bad.json").write_text(json.dumps(spec))
    with pytest.raises(GarmentError, match=message) as err:
        load_garment(tmp_path / "bad.json")
    assert str(tmp_path / "bad.json") in str(err.value) and g.piece_names[0] in str(err.value)
