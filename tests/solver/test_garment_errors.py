"""Bad garment input: one-line errors naming the file and the fault; harmless oddities repaired."""

from __future__ import annotations

import json
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest

from solver.garment import GarmentError, load_garment


def expect_error(path: Path, match: str, **kw) -> GarmentError:
    with pytest.raises(GarmentError, match=match) as info:
        load_garment(path, **kw)
    msg = str(info.value)
    assert msg.startswith(f"{path}: ") and "\n" not in msg
    assert isinstance(info.value, ValueError)
    return info.value


@pytest.fixture
def pants(data_dir: Path) -> str:
    return (data_dir / "garments" / "berkeley" / "pants-coarse.obj").read_text()


@pytest.fixture
def spec(data_dir: Path) -> dict:
    path = data_dir / "garments" / "garmentcode" / "skirt_many_panels_specification.json"
    return json.loads(path.read_text())


# --------------------------------------------------------------------------- OBJ faults


def test_obj_empty(tmp_path: Path) -> None:
    (tmp_path / "empty.obj").write_text("")
    expect_error(tmp_path / "empty.obj", "empty file")
    (tmp_path / "comments.obj").write_text("# nothing here\n")
    expect_error(tmp_path / "comments.obj", "no vertices")


def test_obj_truncated(tmp_path: Path, pants: str) -> None:
    lines = pants.splitlines()
    # cut inside the vertex block: no faces at all
    (tmp_path / "cut-v.obj").write_text("\n".join(lines[:100]))
    expect_error(tmp_path / "cut-v.obj", "no faces")
    # cut in the middle of the last face line
    last_f = max(i for i, ln in enumerate(lines) if ln.startswith("f "))
    cut = "\n".join(lines[:last_f]) + "\n" + lines[last_f][:9]
    (tmp_path / "cut-f.obj").write_text(cut)
    expect_error(tmp_path / "cut-f.obj", "incomplete|truncated")
    # cut in the middle of a vertex line
    first_vt = min(i for i, ln in enumerate(lines) if ln.startswith("vt "))
    text = "\n".join(lines[: first_vt - 1]) + "\nv 0.1 0.2\n" + "\n".join(lines[first_vt:])
    (tmp_path / "cut-line.obj").write_text(text)
    expect_error(tmp_path / "cut-line.obj", "fewer than 3 numbers")


def test_obj_nan(tmp_path: Path, pants: str) -> None:
    text = pants.replace("v ", "v nan ", 1)
    (tmp_path / "nan.obj").write_text(text)
    expect_error(tmp_path / "nan.obj", "not finite")
    text = pants.replace("vt ", "vt NaN 0 #", 1)
    (tmp_path / "nan-vt.obj").write_text(text)
    expect_error(tmp_path / "nan-vt.obj", "texture vertex 1 is not finite")


def test_obj_face_points_at_missing_vertex(tmp_path: Path, pants: str) -> None:
    (tmp_path / "missing.obj").write_text(pants + "f 1/1 2/2 999/3\n")
    expect_error(tmp_path / "missing.obj", "points at missing vertex 999")
    (tmp_path / "missing-vt.obj").write_text(pants + "f 1/1 2/2 3/99999\n")
    expect_error(tmp_path / "missing-vt.obj", "points at missing texture vertex 99999")


def test_obj_pair_faces_differ(tmp_path: Path) -> None:
    m = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n"
    w = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 3 4\n"
    (tmp_path / "g-m.obj").write_text(m)
    (tmp_path / "g-w.obj").write_text(w)
    with pytest.raises(GarmentError, match="different faces .first at face 2") as info:
        load_garment(tmp_path / "g-m.obj")
    assert "\n" not in str(info.value) and str(tmp_path / "g-w.obj") in str(info.value)
    (tmp_path / "g-w.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(GarmentError, match="different vertex counts"):
        load_garment(tmp_path / "g-m.obj")
    # a draped mesh given as the pattern
    (tmp_path / "drape.obj").write_text(m.replace("v 0 1 0", "v 0 1 0.5"))
    (tmp_path / "g-w.obj").write_text(m)
    expect_error(tmp_path / "drape.obj", "pattern file has non-zero z", world=tmp_path / "g-w.obj")


def test_obj_edge_used_by_three_pieces(tmp_path: Path) -> None:
    """Three flaps sewn to one 3D edge: no garment does that."""
    text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\n"
    text += "vt 0 0\nvt 1 0\nvt 0 1\nvt 10 0\nvt 11 0\nvt 10 1\nvt 20 0\nvt 21 0\nvt 20 1\n"
    text += "f 1/1 2/2 3/3\nf 1/4 2/5 4/6\nf 1/7 2/8 5/9\n"
    (tmp_path / "three.obj").write_text(text)
    expect_error(tmp_path / "three.obj", "used by 3 pattern edges .pieces 0, 1, 2.")


def test_obj_pattern_edge_used_by_three_faces(tmp_path: Path) -> None:
    text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 1 1 0\n"
    text += "vt 0 0\nvt 1 0\nvt 0 1\nvt 0 -1\nvt 1 1\n"
    text += "f 1/1 2/2 3/3\nf 2/2 1/1 4/4\nf 1/1 2/2 5/5\n"
    (tmp_path / "fan.obj").write_text(text)
    expect_error(tmp_path / "fan.obj", "pattern edge 1-2 is used by 3 faces", units="mm")


def test_obj_quads_are_split_and_mixed_truncation_caught(tmp_path: Path) -> None:
    quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
    (tmp_path / "quad.obj").write_text(quad + "f 1/1 2/2 3/3 4/4\n")
    g = load_garment(tmp_path / "quad.obj", units="mm")
    assert len(g.faces) == 2 and g.piece_areas()[0] == pytest.approx(1.0)
    # a quad and a two-corner line have as many numbers as two triangles
    (tmp_path / "mixed.obj").write_text(quad + "f 1/1 2/2 3/3 4/4\nf 1/1 3/3\n")
    expect_error(tmp_path / "mixed.obj", "face line 2 is incomplete")


def test_obj_without_pattern(tmp_path: Path) -> None:
    (tmp_path / "mesh.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 1\nf 1 2 3\n")
    expect_error(tmp_path / "mesh.obj", "no texture coordinates")


def test_unknown_format_and_missing_file(tmp_path: Path) -> None:
    (tmp_path / "g.ply").write_text("ply\n")  # .dxf is a garment format since issue 34
    expect_error(tmp_path / "g.ply", "unknown garment format")
    with pytest.raises(FileNotFoundError):
        load_garment(tmp_path / "absent.obj")


# --------------------------------------------------------------------------- JSON faults


def test_json_empty_and_truncated(tmp_path: Path, data_dir: Path) -> None:
    (tmp_path / "empty.json").write_text("")
    expect_error(tmp_path / "empty.json", "empty file")
    src = (data_dir / "garments" / "garmentcode" / "pants_specification.json").read_text()
    (tmp_path / "cut.json").write_text(src[: len(src) // 2])
    expect_error(tmp_path / "cut.json", "not valid JSON .truncated")
    (tmp_path / "other.json").write_text('{"hello": 1}')
    expect_error(tmp_path / "other.json", "no 'pattern' object")


def test_json_nan(tmp_path: Path, spec: dict) -> None:
    name = next(iter(spec["pattern"]["panels"]))
    spec["pattern"]["panels"][name]["vertices"][1][0] = float("nan")
    (tmp_path / "nan.json").write_text(json.dumps(spec))  # json writes NaN literally
    expect_error(tmp_path / "nan.json", f"panels.{name}.vertices.1..0. = nan: only finite")


def test_json_bad_units(tmp_path: Path, spec: dict) -> None:
    for bad in (0, -100, "cm"):
        spec["properties"]["units_in_meter"] = bad
        (tmp_path / "units.json").write_text(json.dumps(spec))
        expect_error(tmp_path / "units.json", "bad units_in_meter")


def test_json_stitch_names_missing_panel(tmp_path: Path, spec: dict) -> None:
    spec["pattern"]["stitches"][3][1]["panel"] = "no_such_panel"
    (tmp_path / "stitch.json").write_text(json.dumps(spec))
    expect_error(tmp_path / "stitch.json", "stitch 3 names missing panel 'no_such_panel'")
    spec["pattern"]["stitches"][3][1] = {"panel": spec["pattern"]["stitches"][3][0]["panel"],
                                        "edge": 99}
    (tmp_path / "edge.json").write_text(json.dumps(spec))
    expect_error(tmp_path / "edge.json", "stitch 3 names missing edge 99")


def test_json_edge_sewn_twice_and_open_loop(tmp_path: Path, spec: dict) -> None:
    stitches = spec["pattern"]["stitches"]
    stitches.append([stitches[0][0], stitches[1][1]])
    (tmp_path / "twice.json").write_text(json.dumps(spec))
    expect_error(tmp_path / "twice.json", "can be sewn only once")
    stitches.pop()
    name = next(iter(spec["pattern"]["panels"]))
    spec["pattern"]["panels"][name]["edges"][0]["endpoints"][1] += 1
    (tmp_path / "open.json").write_text(json.dumps(spec))
    expect_error(tmp_path / "open.json", "do not form a loop")


# --------------------------------------------------------------------------- repairs


def caught_warnings(path: Path, **kw) -> tuple[object, list[str]]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        g = load_garment(path, **kw)
    return g, [str(w.message) for w in caught]


def test_duplicate_vertices_are_merged(tmp_path: Path, pants: str) -> None:
    """A repeated v line (same position) would hide a seam; it is merged, with a count."""
    lines = pants.splitlines()
    n_v = sum(ln.startswith("v ") for ln in lines)
    dup = [ln for ln in lines if ln.startswith("v ")][4]
    # point every face corner that used v 5 at a new, identical v line instead (half of them)
    out, seen = [], 0
    for ln in lines:
        if ln.startswith("f "):
            corners = ln.split()[1:]
            new = []
            for c in corners:
                vi, ti = c.split("/")
                if vi == "5":
                    seen += 1
                    if seen % 2:
                        vi = str(n_v + 1)
                new.append(f"{vi}/{ti}")
            ln = "f " + " ".join(new)
        out.append(ln)
    text = "\n".join(out) + "\n" + dup + "\n"
    (tmp_path / "dup.obj").write_text(text)
    g, msgs = caught_warnings(tmp_path / "dup.obj", units="m")
    assert any("merged 1 duplicate vertices" in m for m in msgs)
    assert (g.n_pieces, len(g.seam_edges)) == (4, 56)


def test_duplicate_texture_vertices_are_welded(tmp_path: Path) -> None:
    # shared-vt convention with the second triangle's corner written as a repeated vt line
    text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
    text += "vt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\nvt 1 0\n"
    text += "f 1/1 2/2 3/3\nf 2/5 4/4 3/3\n"
    (tmp_path / "dupvt.obj").write_text(text)
    g, msgs = caught_warnings(tmp_path / "dupvt.obj")
    assert any("welded 1 duplicate texture vertices" in m for m in msgs)
    assert g.n_vertices == 4 and g.n_pieces == 1


def test_degenerate_slivers_are_removed(tmp_path: Path, pants: str) -> None:
    # a zero-area face (repeated corner) and a collinear one on existing vertices
    text = pants + "f 1/1 1/1 2/2\nf 1/1 2/2 1/1\n"
    (tmp_path / "sliver.obj").write_text(text)
    g, msgs = caught_warnings(tmp_path / "sliver.obj", units="m")
    assert any("removed 2 degenerate (zero-area) faces" in m for m in msgs)
    assert (g.n_pieces, len(g.seam_edges), len(g.faces)) == (4, 56, 188)


def test_unused_vertices_are_dropped(tmp_path: Path, data_dir: Path) -> None:
    src = data_dir / "garments" / "berkeley" / "pants-coarse.obj"
    shutil.copy(src, tmp_path / "p.obj")
    with open(tmp_path / "p.obj", "a") as fh:
        fh.write("v 5 5 5\nvt 9 9\n")
    g, msgs = caught_warnings(tmp_path / "p.obj", units="m")
    # pattern vertices come from face corners: stray v/vt lines change nothing
    assert msgs == []
    assert g.n_vertices == 170 and np.isfinite(g.uv).all()


def test_a_bare_keyword_line_is_refused_not_skipped(tmp_path):
    """A line cut right after its keyword (``v`` alone) was skipped: 8 pieces, not 6."""
    src = (Path(__file__).resolve().parents[1] / "data" / "garments" / "berkeley" /
           "tshirt-coarse.obj").read_bytes()
    path = tmp_path / "damaged.obj"
    path.write_bytes(src.replace(b"\nf ", b"\nv\nf ", 1))
    with pytest.raises(ValueError, match=r"line \d+ is a bare 'v' with no numbers"):
        load_garment(path, units="m")
