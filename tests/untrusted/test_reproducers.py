"""Every malformed input of issue 17, through the `station` command: one line naming the
file, exit status 2, no traceback, within seconds."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest

from station.cli import main

DATA = Path(__file__).resolve().parents[1] / "data"
TSHIRT = DATA / "garments" / "berkeley" / "tshirt-coarse.obj"
SPEC = DATA / "garments" / "garmentcode" / "tshirt_specification.json"
JAKOBS = DATA / "nesting" / "jakobs1.json"
FABRIC = {"group": "p4m", "w1": [40, 0], "w2": [0, 40], "origin": [0, 0], "units": "mm"}


def run(capsys, *argv: str) -> tuple[int, str]:
    capsys.readouterr()
    t0 = time.monotonic()
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err.strip()
    assert time.monotonic() - t0 < 20, "a bad input must fail fast"
    return code, err


def refused(capsys, bad: Path, *argv, match: str) -> str:
    code, err = run(capsys, *argv)
    last = err.splitlines()[-1] if err else ""
    assert code == 2, err
    assert "Traceback" not in err
    assert len(last) < 600 and f"{bad.name}:" in last, last  # FILE: or FILE:LINE:
    assert match in last, last
    return last


def write_json(path: Path, value) -> Path:
    path.write_text(value if isinstance(value, str) else json.dumps(value))
    return path


def spec_scaled(tmp_path: Path, name: str, factor: float = 1.0, **props) -> Path:
    spec = json.loads(SPEC.read_text())
    for panel in spec["pattern"]["panels"].values():
        panel["vertices"] = [[x * factor, y * factor] for x, y in panel["vertices"]]
    spec.setdefault("properties", {}).update(props)
    return write_json(tmp_path / name, spec)


@pytest.fixture
def fabric(tmp_path) -> Path:
    return write_json(tmp_path / "fabric.json", FABRIC)


def test_obj_coordinates_near_1e308(tmp_path, capsys):
    lines = TSHIRT.read_text().splitlines()
    i = next(k for k, line in enumerate(lines) if line.startswith("v "))
    lines[i] = "v 1e308 -1e308 1e308"
    bad = tmp_path / "big.obj"
    bad.write_text("\n".join(lines) + "\n")
    refused(capsys, bad, "inspect", bad, "--units", "m", match="at most 10000 mm across")


def test_obj_last_face_index_cut_short(tmp_path, capsys):
    lines = [ln for ln in TSHIRT.read_text().splitlines() if not ln.startswith("t ")]
    assert lines[-1].startswith("f ")
    bad = tmp_path / "cut.obj"
    bad.write_text("\n".join(lines)[:-1])  # the last index loses its last digit
    refused(capsys, bad, "inspect", bad, "--units", "m", match="truncated")


def test_obj_face_index_beyond_int64(tmp_path, capsys):
    bad = tmp_path / "index.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                   "f 1/1 2/2 100000000000000000000/3\n")
    last = refused(capsys, bad, "inspect", bad, match="beyond the 64-bit range")
    assert "9223372036854775807" not in last


@pytest.mark.parametrize("content", ["[1, 2]", '"p4m"', "3"])
def test_fabric_that_is_not_an_object(tmp_path, capsys, content):
    bad = write_json(tmp_path / "fabric.json", content)
    refused(capsys, bad, "align", TSHIRT, "--units", "m", "--fabric", bad, "-o",
            tmp_path / "p.json", match="must be an object")


@pytest.mark.parametrize("suffix,content", [
    (".json", "[" * 100_000 + "]" * 100_000),
    (".json", '{"a":' * 50_000 + "1" + "}" * 50_000),
])
def test_deeply_nested_json(tmp_path, capsys, suffix, content):
    bad = write_json(tmp_path / f"deep{suffix}", content)
    refused(capsys, bad, "gcode", bad, "-o", tmp_path / "x.nc", match="levels deep")
    refused(capsys, bad, "nest", bad, "-o", tmp_path / "l.json", "--width", "100",
            match="levels deep")


def test_deeply_nested_toml(tmp_path, capsys, fabric):
    bad = tmp_path / "deep.toml"
    bad.write_text("a = " + "[" * 100_000 + "]" * 100_000 + "\n")
    layout = write_json(tmp_path / "layout.json", {"version": 1, "units": "mm", "pieces": []})
    refused(capsys, bad, "gcode", layout, "--machine", bad, "-o", tmp_path / "x.nc",
            match="levels deep")
    refused(capsys, bad, "jobs", "--config", bad, match="levels deep")


def test_pattern_panel_of_a_billion_mm(tmp_path, capsys):
    bad = spec_scaled(tmp_path, "huge.json", 1e7)
    refused(capsys, bad, "inspect", bad, match="a garment is at most 10000 mm")


def test_pattern_units_in_meter_1e_minus_12(tmp_path, capsys):
    bad = spec_scaled(tmp_path, "units.json", units_in_meter=1e-12)
    refused(capsys, bad, "inspect", bad, match="wrong units_in_meter")


def test_pattern_meshed_beyond_the_face_limit(tmp_path):
    """No command takes the meshing resolution, so the loader is asked directly."""
    from solver.garment import load_garment

    spec = spec_scaled(tmp_path, "fine.json")
    t0 = time.monotonic()
    with pytest.raises(ValueError, match="fine.json: meshing at 0.01 mm would make"):
        load_garment(spec, resolution_mm=0.01)
    assert time.monotonic() - t0 < 5


def test_piece_that_cannot_fit_the_strip(tmp_path, capsys):
    inst = json.loads(JAKOBS.read_text())
    inst["items"][0]["shape"]["data"] = [[0, 0], [1000, 0], [0, 1000]]
    bad = write_json(tmp_path / "nofit.json", inst)
    refused(capsys, bad, "nest", bad, "-o", tmp_path / "l.json", "--time", "1",
            match="cannot be nested")


def test_lattice_of_a_hundredth_of_a_mm(tmp_path, capsys):
    bad = write_json(tmp_path / "fine.json", {**FABRIC, "w1": [0.01, 0], "w2": [0, 0.01]})
    refused(capsys, bad, "nest", JAKOBS, "--fabric", bad, "-o", tmp_path / "l.json",
            match="repeats every 1 to 2000 mm")


def test_lattice_of_1e300_is_not_called_parallel(tmp_path, capsys):
    bad = write_json(tmp_path / "vast.json", {**FABRIC, "w1": [1e300, 0], "w2": [0, 1e300]})
    last = refused(capsys, bad, "align", TSHIRT, "--units", "m", "--fabric", bad, "-o",
                   tmp_path / "p.json", match="repeats every 1 to 2000 mm")
    assert "parallel" not in last


@pytest.mark.parametrize("mutate,match", [
    (lambda d: d.update(strip_height="wide"), "strip_height must be a number"),
    (lambda d: d.update(items=5), "items must be a list"),
    (lambda d: d["items"][0].update(demand="two"), "demand must be an integer"),
    (lambda d: d["items"][0].update(demand=10**12), "demand = 1000000000000 is out of range"),
    (lambda d: d["items"][0]["shape"].update(data=[[0, 0], ["x", 1], [1, 1]]), "not a number"),
    (lambda d: d["items"][0].update(allowed_orientations="all"), "must be a list"),
])
def test_strip_packing_instance_with_wrong_types(tmp_path, capsys, mutate, match):
    inst = json.loads(JAKOBS.read_text())
    mutate(inst)
    bad = write_json(tmp_path / "inst.json", inst)
    refused(capsys, bad, "nest", bad, "-o", tmp_path / "l.json", "--time", "1", match=match)


def test_keepouts_with_nan(tmp_path, capsys):
    bad = write_json(tmp_path / "keep.json", '{"keepouts": [[[0, 0], [NaN, 0], [1, 1]]]}')
    refused(capsys, bad, "nest", JAKOBS, "--keepout", bad, "-o", tmp_path / "l.json",
            match="keepouts[0][1][0] = nan")


@pytest.mark.parametrize("key", ["holes", "marks", "notches"])
def test_layout_field_that_is_a_number(tmp_path, capsys, key):
    piece = {"id": "a", "outline": [[10, 10], [60, 10], [60, 60]], key: 7}
    bad = write_json(tmp_path / "layout.json",
                     {"version": 1, "units": "mm", "width": 100, "length": 100,
                      "pieces": [piece]})
    refused(capsys, bad, "gcode", bad, "-o", tmp_path / "x.nc",
            match=f"pieces[0].{key} must be a list")


def test_program_whose_first_move_is_g1(tmp_path, capsys):
    bad = tmp_path / "g1.nc"
    bad.write_text("G21 G90\nG1 X10 Y10 F1000\n")
    refused(capsys, bad, "simulate-stream", bad, "--port", "grblsim://?speed=1000",
            match="feed move before the head's X and Y are known")


def test_empty_program_is_not_completed(tmp_path, capsys):
    bad = tmp_path / "empty.nc"
    bad.write_text("(nothing)\n")
    refused(capsys, bad, "simulate-stream", bad, "--port", "grblsim://?speed=1000",
            match="no G-code")


def test_piece_comment_carries_no_realtime_byte(tmp_path, capsys):
    bad = tmp_path / "bang.nc"
    bad.write_text("G21 G90 G94\nG0 X10 Y10\n(piece 1 begin a sleeve!)\nG4 P0.01\n"
                   "(piece 1 end)\nM2\n")
    refused(capsys, bad, "simulate-stream", bad, "--port", "grblsim://?speed=1000",
            match="forbidden character")


def test_placement_with_every_piece_at_index_0(tmp_path, capsys):
    pieces = [{"index": 0, "name": f"p{i}", "angle_deg": 0, "translation_mm": [0, 0]}
              for i in range(3)]
    bad = write_json(tmp_path / "placement.json",
                     {"version": 1, "fabric": FABRIC, "garment": str(TSHIRT),
                      "garment_units": "m", "pieces": pieces})
    refused(capsys, bad, "nest", bad, "-o", tmp_path / "l.json", "--width", "1500",
            match="exactly once")


def test_folder_where_a_file_is_expected(tmp_path, capsys):
    folder = tmp_path / "fabric.json"
    folder.mkdir()
    refused(capsys, folder, "align", TSHIRT, "--units", "m", "--fabric", folder, "-o",
            tmp_path / "p.json", match="is a folder")
    refused(capsys, folder, "inspect", folder, match="folder")


def test_utf8_decode_error_names_the_file(tmp_path, capsys):
    bad = tmp_path / "fabric.json"
    bad.write_bytes(b'{"group": "\xff\xfe"}')
    refused(capsys, bad, "align", TSHIRT, "--units", "m", "--fabric", bad, "-o",
            tmp_path / "p.json", match="not UTF-8 text (byte 0xff at offset 11)")


@pytest.mark.parametrize("toml,match", [
    ("[nest]\nseconds = inf\n", "nest.seconds"),
    ("[nest]\nseconds = nan\n", "nest.seconds"),
    ("[cut]\npasses = 100000000\n", "cut.passes must be at most 100"),
    ("[align]\nseed = 99999999999999999999\n", "out of the 64-bit range"),
    ('[control]\ngroup = "no-such-group-anywhere"\n', "control.group"),
    ('[control]\nsocket = "' + "s" * 120 + '.sock"\n', "control.socket"),
])
def test_station_toml_refuses(tmp_path, capsys, toml, match):
    bad = tmp_path / "station.toml"
    bad.write_text(toml)
    refused(capsys, bad, "jobs", "--config", bad, match=match)


def test_machine_profile_with_passes_1e8(tmp_path, capsys):
    bad = tmp_path / "machine.toml"
    bad.write_text("[cut]\npasses = 100000000\n")
    layout = write_json(tmp_path / "layout.json",
                        {"version": 1, "units": "mm", "width": 100, "length": 100,
                         "pieces": [{"id": "a", "outline": [[10, 10], [60, 10], [60, 60]]}]})
    refused(capsys, bad, "gcode", layout, "--machine", bad, "-o", tmp_path / "x.nc",
            match="passes")


# ---- faults found by a second fuzzing round: well-formed files with absurd content


def spec_edited(tmp_path: Path, name: str, edit) -> Path:
    """The test t-shirt specification with ``edit(first_panel)`` applied."""
    spec = json.loads(SPEC.read_text())
    edit(next(iter(spec["pattern"]["panels"].values())))
    return write_json(tmp_path / name, spec)


@pytest.mark.parametrize("vertices,match", [
    ([[10.0 * i, 0.0] for i in range(7)], "not a simple polygon"),  # Triangle's SIGSEGV
    ([[5.0, 5.0]] * 7, "fewer than 3 distinct points"),
    ([[0, 0], [20, 20], [20, 0], [0, 20], [10, 30], [5, 40], [0, 35]], "self-intersection"),
])
def test_pattern_panel_that_is_not_a_simple_polygon(tmp_path, capsys, vertices, match):
    bad = spec_edited(tmp_path, "flat.json", lambda p: p.update(vertices=vertices))
    refused(capsys, bad, "inspect", bad, match=match)


@pytest.mark.parametrize("edge", [1.5, True, "1", None])
def test_stitch_edge_that_is_not_a_whole_number(tmp_path, capsys, edge):
    """1.5 and true were read as edge 1: a seam sewn to an edge nobody named."""
    spec = json.loads(SPEC.read_text())
    spec["pattern"]["stitches"][0][0]["edge"] = edge
    bad = write_json(tmp_path / "stitch.json", spec)
    refused(capsys, bad, "inspect", bad, match="stitch 0 edge must be an integer")


@pytest.mark.parametrize("curvature", [
    {"type": "cubic", "params": [[1e6, 1e6], [-1e6, 1e6]]},  # MemoryError after 17 s
    {"type": "circle", "params": [1e9, 1, 1]},  # a 2.3 GiB sample array
    [0.5, 1e5],  # hung
])
def test_pattern_curve_far_beyond_its_vertices(tmp_path, capsys, curvature):
    bad = spec_edited(tmp_path, "bulge.json",
                      lambda p: p["edges"][2].update(curvature=curvature))
    refused(capsys, bad, "inspect", bad, match="a garment is at most 10000 mm")


@pytest.mark.parametrize("outline,width", [
    ([[100_000, 100_000], [100_010, 100_000], [100_000, 100_010]], 500),  # IndexError, exit 70
    ([[-100, -100], [-50, -100], [-50, -50]], 500),
    ([[10, 10], [60, 10], [60, 60]], 1e-9),
])
def test_layout_piece_off_the_fabric(tmp_path, capsys, outline, width):
    bad = write_json(tmp_path / "layout.json",
                     {"version": 1, "units": "mm", "width": width, "length": 500,
                      "pieces": [{"id": "a", "outline": outline}]})
    refused(capsys, bad, "gcode", bad, "-o", tmp_path / "x.nc", match="leaves the fabric")


def test_layout_hole_outside_its_piece(tmp_path, capsys):
    """The toolpath dropped such a hole without a word."""
    bad = write_json(tmp_path / "layout.json",
                     {"version": 1, "units": "mm", "width": 500, "length": 500,
                      "pieces": [{"id": "a", "outline": [[10, 10], [60, 10], [60, 60]],
                                  "holes": [[[200, 200], [210, 200], [210, 210]]]}]})
    refused(capsys, bad, "gcode", bad, "-o", tmp_path / "x.nc",
            match="pieces[0].holes[0] is not inside the piece's outline")


@pytest.mark.parametrize("weights,match", [
    ({"²": 1}, "no seam line '²'"),  # int('²') raised, naming no file
    ({"9" * 5000: 1}, "no seam line"),  # int() refused 5000 digits, naming no file
    ({"0": -1}, "weight of '0' = -1 is out of range"),
    ({"0": 1e300}, "out of range"),
])
def test_seam_weights_name_their_file(tmp_path, capsys, fabric, weights, match):
    bad = write_json(tmp_path / "w.json", weights)
    refused(capsys, bad, "align", TSHIRT, "--units", "m", "--fabric", fabric, "--weights",
            bad, "--restarts", "1", "-o", tmp_path / "p.json", match=match)


def test_allowances_name_their_file(tmp_path, capsys):
    bad = write_json(tmp_path / "a.json", {"open#0": -1})
    refused(capsys, bad, "nest", JAKOBS, "--allowance", bad, "-o", tmp_path / "l.json",
            "--time", "1", match="allowance of 'open#0' = -1 is out of range")


def test_keepout_of_one_repeated_point(tmp_path, capsys):
    """Named no file before: 'a piece outline needs at least 3 points, got 2'."""
    bad = write_json(tmp_path / "keep.json", {"keepouts": [[[1, 1], [1, 1], [1, 1]]]})
    refused(capsys, bad, "nest", JAKOBS, "--keepout", bad, "-o", tmp_path / "l.json",
            match="keepouts[0] crosses itself or has no area")


@pytest.mark.parametrize("square", [1e6, 1e5])
def test_keepout_far_larger_than_the_roll(tmp_path, capsys, square):
    """A 58 TiB raster (MemoryError) before; now the roll has no room left beside it."""
    keep = write_json(tmp_path / "keep.json", {"keepouts": [[[-square, -square], [square, -square],
                                                             [square, square], [-square, square]]]})
    code, err = run(capsys, "nest", JAKOBS, "--keepout", keep, "-o", tmp_path / "l.json",
                    "--time", "1")
    last = err.splitlines()[-1]
    assert code == 2 and "do not fit on the fabric" in last and "keep-out" in last, last


def test_machine_name_longer_than_a_grbl_line(tmp_path, capsys):
    """Refused only while writing before ('generated line longer than 79 characters'),
    naming no file."""
    bad = tmp_path / "machine.toml"
    bad.write_text('[machine]\nname = "' + "x" * 100 + '"\n')
    layout = write_json(tmp_path / "layout.json",
                        {"version": 1, "units": "mm", "width": 100, "length": 100,
                         "pieces": [{"id": "a", "outline": [[10, 10], [60, 10], [60, 60]]}]})
    refused(capsys, bad, "gcode", layout, "--machine", bad, "-o", tmp_path / "x.nc",
            match="at most 40 characters")
