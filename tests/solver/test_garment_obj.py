"""OBJ garment import: counts against the SOURCE.md tables, units, pairs, scale recovery."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from solver.garment import Garment, load_garment, save_obj
from solver.geometry import signed_areas

# (pieces, seam edges, 3D boundary edges) from the SOURCE.md tables in shared/data/garments
BERKELEY = {
    "tshirt/coarse/tshirt.obj": (6, 88, 60),
    "tshirt/isotropic/tshirt-iso.obj": (6, 221, 142),
    "tshirt/isotropic/tshirt-iso-m.obj": (6, 221, 142),
    "tshirt/isotropic/tshirt-iso-w.obj": (6, 221, 142),
    "shirt/isotropic/shirt-iso.obj": (14, 233, 144),
    "vest/isotropic/vest-iso.obj": (4, 97, 212),
    "tank-male/isotropic/tank-male-iso.obj": (4, 138, 154),
    "pants/coarse/pants.obj": (4, 56, 32),
    "pants/isotropic/pants-iso.obj": (4, 188, 81),
    "shorts/isotropic/shorts-iso.obj": (4, 104, 89),
    "skirt/coarse/skirt.obj": (6, 44, 47),
    "skirt/isotropic/skirt-iso.obj": (6, 182, 192),
    "dress2/isotropic/dress2-iso.obj": (2, 126, 151),
    "dress/coarse/dress3.obj": (11, 118, 72),
    "dress/draped/dress-draped-iso.obj": (11, 301, 198),
    "dress3/draped/dress3-iso-draped.obj": (11, 238, 176),
    "dress3/draped/dress3-iso-draped-m.obj": (11, 238, 176),
    "dress-victor/draped/dress-victor-iso-draped.obj": (2, 46, 222),
}
ARCSIM = {  # welded by value: dress3 has 9 duplicate vt lines (see its SOURCE.md)
    "tshirt.obj": (6, 88, 60),
    "pants3.obj": (4, 56, 32),
    "dress3.obj": (11, 118, 72),
    "jacket.obj": (6, 27, 50),
}
BOXMESH = {
    "tshirt/tshirt_boxmesh_res1.obj": (8, 320, 268),
    "pants/pants_boxmesh_res2.obj": (6, 204, 107),
    "skirt_many_panels/skirt_many_panels_boxmesh_res2.obj": (6, 147, 183),
    "dress_pencil/dress_pencil_boxmesh_res1.obj": (10, 677, 252),
    "dress_circle/dress_circle_boxmesh_res1.obj": (12, 655, 424),
}
BUNDLED = {
    "berkeley/pants-coarse.obj": (4, 56, 32),
    "berkeley/skirt-coarse.obj": (6, 44, 47),
    "berkeley/tshirt-coarse.obj": (6, 88, 60),
    "berkeley/shorts-iso.obj": (4, 104, 89),
    "garmentcode/pants_boxmesh_res2.obj": (6, 204, 107),
}


def check_invariants(g: Garment) -> None:
    """What every imported garment must satisfy, whatever its source."""
    v = g.n_vertices
    assert g.uv.shape == (v, 2) and np.isfinite(g.uv).all()
    assert g.faces.min() >= 0 and g.faces.max() < v
    if g.xyz is not None:
        assert g.xyz.shape == (v, 3)
    # pieces are the connected components, all CCW in the pattern
    assert g.piece_of_vertex.max() + 1 == g.n_pieces == len(g.piece_names)
    area = signed_areas(g.uv, g.faces)
    assert (g.piece_areas() > 0).all()
    assert (area > 0).mean() > 0.99
    # twins: a~a2 and b~b2 are the same 3D point, the two edges are distinct pattern edges
    s = g.seam_edges
    assert s.shape[1] == 4
    pov = g.point_of_vertex
    assert np.array_equal(pov[s[:, 0]], pov[s[:, 2]])
    assert np.array_equal(pov[s[:, 1]], pov[s[:, 3]])
    assert not np.any((s[:, 0] == s[:, 2]) & (s[:, 1] == s[:, 3]))
    if g.xyz is not None:
        assert np.allclose(g.xyz[s[:, 0]], g.xyz[s[:, 2]])
    # every seam edge is a pattern boundary edge, on both sides
    bhe = {tuple(e) for e in g.boundary_half_edges().tolist()}
    for a, b, a2, b2 in s[:50].tolist():
        assert (a, b) in bhe or (b, a) in bhe
        assert (a2, b2) in bhe or (b2, a2) in bhe
    # uv boundary = 2 * seams + 3D boundary (SOURCE.md identity)
    assert len(bhe) == 2 * len(s) + g.boundary_3d_edges
    # seam lines: one piece pair each, and they cover every seam edge
    assert len(g.seam_line_of_edge) == len(s)
    pa = g.piece_of_vertex[s[:, 0]]
    pb = g.piece_of_vertex[s[:, 2]]
    for k, line in enumerate(g.seam_lines):
        m = g.seam_line_of_edge == k
        assert m.any()
        pairs = set(zip(np.minimum(pa[m], pb[m]).tolist(), np.maximum(pa[m], pb[m]).tolist()))
        assert pairs == {(line.piece_a, line.piece_b)}
    assert np.array_equal(g.seam_weights(), np.ones(len(s)))


def check_counts(g: Garment, expected: tuple[int, int, int]) -> None:
    assert (g.n_pieces, len(g.seam_edges), g.boundary_3d_edges) == expected


@pytest.mark.parametrize("name", sorted(BUNDLED))
def test_bundled_obj_counts(data_dir: Path, name: str) -> None:
    units = "m" if name.startswith("berkeley/") else None  # BoxMesh files say cm
    g = load_garment(data_dir / "garments" / name, units=units)
    check_counts(g, BUNDLED[name])
    check_invariants(g)


def test_shared_berkeley_counts(shared_data: Path) -> None:
    root = shared_data / "garments" / "berkeley_garment_library" / "Garments"
    for name, expected in BERKELEY.items():
        g = load_garment(root / name, units="m")
        check_counts(g, expected)
        check_invariants(g)
        assert g.kind == ("obj-pair" if name.endswith(("-m.obj", "-w.obj")) else "obj")


def test_shared_arcsim_and_boxmesh_counts(shared_data: Path) -> None:
    root = shared_data / "garments"
    for name, expected in ARCSIM.items():
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            g = load_garment(root / "arcsim_meshes" / name, units="m")
        check_counts(g, expected)
        check_invariants(g)
        if name == "dress3.obj":
            assert any("welded 9 duplicate" in str(w.message) for w in caught)
    for name, expected in BOXMESH.items():
        g = load_garment(root / "garmentcode" / "generated" / name)
        assert g.units_in_file == "cm"
        check_counts(g, expected)
        check_invariants(g)


def test_units_scale_the_pattern(data_dir: Path) -> None:
    path = data_dir / "garments" / "berkeley" / "pants-coarse.obj"
    g_m = load_garment(path, units="m")
    g_mm = load_garment(path)  # the file states no units: millimetres
    assert g_mm.units_in_file == "mm" and g_m.units_in_file == "m"
    assert np.allclose(g_m.uv, 1000 * g_mm.uv)
    assert np.allclose(g_m.xyz, 1000 * g_mm.xyz)
    g_in = load_garment(path, units="in")
    assert np.allclose(g_in.uv, 25.4 * g_mm.uv)
    # pants are about a metre long: the pattern must say so in mm
    height = np.ptp(g_m.uv[:, 1])
    assert 700 < height < 1500
    with pytest.raises(ValueError, match="unknown units"):
        load_garment(path, units="furlong")


def test_boxmesh_header_declares_cm(data_dir: Path) -> None:
    g = load_garment(data_dir / "garments" / "garmentcode" / "pants_boxmesh_res2.obj")
    assert g.units_in_file == "cm"
    # away from seams 3D and 2D edge lengths agree exactly (SOURCE.md), so xyz/uv share units
    e = g.faces[:, :2]
    ratio = np.linalg.norm(g.xyz[e[:, 0]] - g.xyz[e[:, 1]], axis=1) / np.linalg.norm(
        g.uv[e[:, 0]] - g.uv[e[:, 1]], axis=1
    )
    assert np.median(ratio) == pytest.approx(1.0, abs=1e-3)
    assert 300 < np.ptp(g.uv[:, 1]) < 1500  # panel heights in mm


def test_isotropic_3d_matches_pattern(data_dir: Path) -> None:
    g = load_garment(data_dir / "garments" / "berkeley" / "shorts-iso.obj", units="m")
    e = g.faces[:, :2]
    l3 = np.linalg.norm(g.xyz[e[:, 0]] - g.xyz[e[:, 1]], axis=1)
    l2 = np.linalg.norm(g.uv[e[:, 0]] - g.uv[e[:, 1]], axis=1)
    assert np.median(l3 / l2) == pytest.approx(1.0, abs=0.03)
    assert g.scale_recovered is None


def test_scale_recovered_from_normalised_vt(data_dir: Path, tmp_path: Path) -> None:
    src = data_dir / "garments" / "berkeley" / "shorts-iso.obj"
    g = load_garment(src, units="m")
    lo = g.uv.min(axis=0)
    extent = float(np.ptp(g.uv, axis=0).max())
    norm = g.with_uv((g.uv - lo) / extent)  # vt normalised to the unit square
    norm.xyz = g.xyz / 1000.0  # 3D stays in metres
    out = tmp_path / "shorts-normalised.obj"
    save_obj(norm, out)
    text = out.read_text().replace("# units: mm\n", "")
    out.write_text(text)
    h = load_garment(out, units="m")
    assert h.scale_recovered == pytest.approx(extent / 1000.0, rel=0.02)
    assert np.allclose(h.uv, g.uv - lo, atol=0.02 * extent)


def test_pair_from_split_combined_file(data_dir: Path, tmp_path: Path) -> None:
    """Split a combined file into -m/-w (one v per pattern vertex): seams come back from -w."""
    g = load_garment(data_dir / "garments" / "berkeley" / "tshirt-coarse.obj", units="m")
    f = "\n".join("f {} {} {}".format(*r) for r in (g.faces + 1).tolist()) + "\n"
    m = "\n".join("v {:.9g} {:.9g} 0".format(*r) for r in (g.uv / 1000).tolist())
    w = "\n".join("v {!r} {!r} {!r}".format(*r) for r in (g.xyz / 1000).tolist())
    (tmp_path / "tee-m.obj").write_text(m + "\n" + f)
    (tmp_path / "tee-w.obj").write_text(w + "\n" + f)
    for name in ("tee-m.obj", "tee-w.obj"):
        h = load_garment(tmp_path / name, units="m")
        assert h.kind == "obj-pair"
        check_counts(h, (6, 88, 60))
        check_invariants(h)
        assert np.allclose(h.uv, g.uv, atol=1e-6)
    # explicit world= gives the same
    h = load_garment(tmp_path / "tee-m.obj", units="m", world=tmp_path / "tee-w.obj")
    assert len(h.seam_edges) == 88
    # the pattern file alone is a flat pattern without seams
    (tmp_path / "alone-m.obj").write_text(m + "\n" + f)
    alone = load_garment(tmp_path / "alone-m.obj", units="m")
    assert alone.xyz is None and alone.n_pieces == 6 and len(alone.seam_edges) == 0


def test_seam_lines_of_pants(data_dir: Path) -> None:
    g = load_garment(data_dir / "garments" / "berkeley" / "pants-coarse.obj", units="m")
    # pants: 4 panels; every seam line joins two pieces or one piece with itself
    assert len(g.seam_lines) == 6
    assert sum(np.sum(g.seam_line_of_edge == k) for k in range(6)) == 56
    names = [s.name for s in g.seam_lines]
    assert len(set(names)) == len(names)


def test_fast_and_line_readers_agree(data_dir: Path, tmp_path: Path) -> None:
    """The byte-level reader and the line reader (irregular files) give the same garment."""
    src = (data_dir / "garments" / "berkeley" / "tshirt-coarse.obj").read_text()
    fast = load_garment(data_dir / "garments" / "berkeley" / "tshirt-coarse.obj", units="m")
    # CRLF line ends stay on the byte-level reader; a v line with a 4th (w) component is
    # legal OBJ but irregular, which sends the file to the line reader
    (tmp_path / "crlf.obj").write_text(src.replace("\n", "\r\n"))
    lines = src.splitlines()
    k = next(i for i, ln in enumerate(lines) if ln.startswith("v "))
    lines[k] += " 1.0"  # v x y z w: legal OBJ, not the regular layout
    (tmp_path / "vw.obj").write_text("\n".join(lines) + "\n")
    for name in ("crlf.obj", "vw.obj"):
        g = load_garment(tmp_path / name, units="m")
        assert np.array_equal(g.uv, fast.uv) and np.array_equal(g.faces, fast.faces)
        assert np.array_equal(g.seam_edges, fast.seam_edges)
