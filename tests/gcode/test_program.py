"""Programs parsed back: inside the work area, S never above the maximum, laser never on in
G0, every piece's outline and holes cut completely (offset back by the kerf they match the
piece within the chordal tolerance), and the checker refusing unsafe programs."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import shapely
from shapely.geometry import LineString, Polygon

from gcode.layout import layout_from_dict
from gcode.machine import default_machine, machine_from_dict
from gcode.program import (
    MAX_LINE,
    ProgramError,
    build_program,
    load_program,
    parse_pieces,
    validate,
)
from gcode.toolpath import build_toolpaths

sys.path.insert(0, str(Path(__file__).parent))  # gcode_helpers (importlib mode)
from gcode_helpers import make_layout, piece_polygons, trace  # noqa: E402

KNIFE = {"machine": {"name": "knife table", "tool": "knife", "work_area": [0, 0, 1200, 800],
                     "max_feed": 6000.0, "max_s": 1000.0, "laser_mode": False},
         "cut": {"feed": 2000.0, "kerf": 0.0}, "knife": {"z_up": 3.0, "z_down": -0.5}}


LAYOUT = make_layout()


def _cut_faces(moves, lines_range):
    lo, hi = lines_range
    segs = [LineString(m["pts"]) for m in moves
            if m["on"] and lo <= m["line"] <= hi and len(m["pts"]) >= 2]
    assert segs, "no cutting moves in the piece"
    merged = shapely.unary_union(segs)
    return list(shapely.polygonize(list(shapely.get_parts(merged))).geoms)


def _check_program(prog, machine, layout, moves):
    x0, y0, x1, y1 = machine.work_area
    allpts = np.vstack([m["pts"] for m in moves])
    assert (allpts[:, 0] >= x0 - 1e-6).all() and (allpts[:, 0] <= x1 + 1e-6).all()
    assert (allpts[:, 1] >= y0 - 1e-6).all() and (allpts[:, 1] <= y1 + 1e-6).all()
    assert all(m["s"] <= machine.max_s for m in moves)
    assert not any(m["on"] for m in moves if m["g"] == 0), "tool on during a rapid move"
    assert all(len(line) <= MAX_LINE for line in prog.lines)
    polys = piece_polygons(layout)
    kerf, tol = machine.cut.kerf, machine.cut.tolerance
    assert sorted(p.id for p in prog.pieces) == sorted(polys)
    for pr in prog.pieces:
        faces = _cut_faces(moves, (pr.first_line, pr.sync_line))
        region = shapely.unary_union(faces)
        outer = Polygon(region.exterior)
        back = outer.buffer(-kerf / 2, join_style="mitre", mitre_limit=4.0) if kerf else outer
        piece = polys[pr.id]
        d = back.exterior.hausdorff_distance(piece.exterior)
        assert d <= tol + 0.002, f"{pr.id}: outline cut off by {d:.4f} mm"
        for h in piece.interiors:
            hole = Polygon(h)
            face = min(faces, key=lambda f, hole=hole: f.symmetric_difference(hole).area)
            grown = face.buffer(kerf / 2, join_style="mitre", mitre_limit=4.0) if kerf else face
            d = grown.exterior.hausdorff_distance(hole.exterior)
            assert d <= tol + 0.002, f"{pr.id}: hole cut off by {d:.4f} mm"
        # the sync line is a dwell after the last cutting move of the piece
        assert prog.lines[pr.sync_line] == "G4 P0.01"
        assert max(m["line"] for m in moves if m["on"] and pr.first_line <= m["line"]
                   <= pr.last_line) < pr.sync_line


@pytest.mark.parametrize("origin", [(0.0, 0.0), (300.0, 250.0)])
def test_laser_program_parsed_back(origin):
    data = make_layout(origin)
    machine = default_machine()
    layout = layout_from_dict(data, "test")
    prog = build_program(build_toolpaths(layout, machine), machine)
    moves = trace(prog.lines)
    _check_program(prog, machine, data, moves)
    assert prog.lines[:3][-1].startswith("G21 G90")
    assert prog.lines[-4:] == ["M5", "M9", "G0 X0 Y0", "M2"]
    assert any(ln.startswith("M8") for ln in prog.lines)
    assert all(m["s"] in (0, machine.cut.power, machine.cut.mark_power) for m in moves)
    # arcs were fitted: curved pieces became a few arcs
    assert sum(ln.startswith(("G2 ", "G3 ")) for ln in prog.lines) >= 10
    assert prog.check.cut_length_mm > 0 and prog.check.estimated_seconds > 0


def test_knife_program_parsed_back():
    machine = machine_from_dict(KNIFE, "knife.toml")
    layout = layout_from_dict(LAYOUT, "test")
    prog = build_program(build_toolpaths(layout, machine), machine)
    moves = trace(prog.lines, knife_down=machine.knife.z_down)
    _check_program(prog, machine, LAYOUT, moves)
    assert not any(ln.startswith(("M3", "M4")) for ln in prog.lines)
    # every rapid XY move happens with the knife raised
    for m in moves:
        if m["g"] == 0 and len(m["pts"]) == 2 and np.ptp(m["pts"], axis=0).any():
            assert m["z0"] == machine.knife.z_up
    # corner handling: the square's four corners lift the knife (>= 4 strokes)
    sq = next(p for p in prog.pieces if p.id == "front#1")
    lifts = sum(ln == "G0 Z3" for ln in prog.lines[sq.first_line:sq.last_line])
    assert lifts >= 4 + 2  # 4 corners + 2 marks (+ notch)


def test_knife_tabs_leave_bridges():
    data = dict(KNIFE, cut={"feed": 2000.0, "kerf": 0.0, "tabs": 4, "tab_width": 5.0})
    machine = machine_from_dict(data, "knife.toml")
    layout = layout_from_dict(LAYOUT, "test")
    prog = build_program(build_toolpaths(layout, machine), machine)
    moves = trace(prog.lines, knife_down=machine.knife.z_down)
    polys = piece_polygons(LAYOUT)
    for pr in prog.pieces:
        piece = polys[pr.id]
        cut = shapely.unary_union([LineString(m["pts"]) for m in moves if m["on"]
                                   and pr.first_line <= m["line"] <= pr.last_line
                                   and len(m["pts"]) >= 2])
        on_outline = cut.intersection(piece.exterior.buffer(0.05)).length
        uncut = piece.exterior.length - on_outline
        assert uncut == pytest.approx(4 * 5.0, abs=1.0), pr.id


def test_lead_in_starts_in_the_waste():
    machine = default_machine().with_cut(lead_in=2.0)
    layout = layout_from_dict(LAYOUT, "test")
    prog = build_program(build_toolpaths(layout, machine), machine)
    moves = trace(prog.lines)
    polys = piece_polygons(LAYOUT)
    for pr in prog.pieces:
        on = [m for m in moves if m["on"] and pr.first_line <= m["line"] <= pr.sync_line]
        first_outline = on[-1]
        # the outline's first cutting move (after the last M4 of the piece) starts outside
        start_line = max(i for i in range(pr.first_line, pr.sync_line)
                         if prog.lines[i].startswith("M4"))
        first = next(m for m in on if m["line"] > start_line)
        p0 = first["pts"][0]
        assert not polys[pr.id].buffer(machine.cut.kerf / 2).contains(shapely.Point(p0))
        assert polys[pr.id].exterior.distance(shapely.Point(p0)) == pytest.approx(
            2.0 + machine.cut.kerf / 2, abs=0.3)
        assert first_outline["on"]


def test_inner_contours_before_outline():
    machine = default_machine()
    tps = build_toolpaths(layout_from_dict(LAYOUT, "test"), machine)
    for tp in tps:
        kinds = [c.kind for c in tp.contours]
        assert kinds[-1] == "outline" and kinds.count("outline") == 1
        rank = {"mark": 0, "hole": 1, "notch": 2, "outline": 3}
        assert [rank[k] for k in kinds] == sorted(rank[k] for k in kinds)
    disc = next(tp for tp in tps if tp.id == "disc#1")
    assert [c.kind for c in disc.contours] == ["mark", "hole", "notch", "outline"]


def test_comments_cannot_inject_and_pieces_survive_the_file(tmp_path):
    machine = default_machine()
    prog = build_program(build_toolpaths(layout_from_dict(LAYOUT, "t"), machine), machine)
    text = prog.text()
    for bad in "$%!?~":
        assert bad not in text
    assert all(ln.count("(") == ln.count(")") <= 1 for ln in prog.lines)
    path = tmp_path / "job.nc"
    prog.write(path)
    again = load_program(path, machine)
    assert [(p.number, p.id, p.first_line, p.sync_line, p.last_line) for p in again.pieces] == \
        [(p.number, p.id, p.first_line, p.sync_line, p.last_line) for p in prog.pieces]
    assert again.check.estimated_seconds == pytest.approx(prog.check.estimated_seconds)
    front = next(p for p in again.pieces if p.id == "front#1")
    assert "G0" in prog.lines[front.first_line]  # sanitised, still one comment line
    assert prog.lines[front.first_line].startswith("(piece ")


def test_only_some_pieces():
    machine = default_machine()
    layout = layout_from_dict(LAYOUT, "t")
    prog = build_program(build_toolpaths(layout, machine, only={"lobes#1"}), machine)
    assert [p.id for p in prog.pieces] == ["lobes#1"]
    with pytest.raises(ValueError, match="no piece with id"):
        build_toolpaths(layout, machine, only={"nope"})


def test_refuses_pieces_outside_the_work_area():
    """A marker past the table's end is refused as such before any G-code is made (the
    program's own work-area check, below, names a move and would blame the kerf)."""
    data = make_layout(origin=(1500.0, 0.0))
    machine = default_machine()
    with pytest.raises(ValueError, match=r"the marker runs from x=.* cuts x=0 to 1600 mm"
                       ) as exc:
        build_toolpaths(layout_from_dict(data, "far.json"), machine)
    assert str(exc.value).startswith("far.json: ") and "--length 100 " in str(exc.value)


HEAD = ["G21 G90 G94 G17", "M5", "G0 X10 Y10"]


@pytest.mark.parametrize("lines,match", [
    (HEAD + ["M4 S500", "G0 X20 Y20"], "laser on .* rapid"),
    (HEAD + ["M4 S1200", "G1 X20 Y20 F1000"], "S1200 outside"),
    (HEAD + ["M4 S500", "G1 X20 Y20 F20000"], "exceeds the machine's max_feed"),
    (HEAD + ["G1 X2000 Y20 F1000"], "outside the work area"),
    (HEAD + ["M4 S500", "G2 X10 Y990 I0 J490 F1000"], "outside the work area"),
    (HEAD + ["M4 S500", "G2 X30 Y11 I10 J0 F1000"], "radii differ"),
    (HEAD + ["$H"], "forbidden"),
    (HEAD + ["G1 X20 Y20 F1000 (hi!)"], "forbidden"),
    (HEAD + ["G1 X20 Y20 F1000 (" + "a" * 70 + ")"], "longer than"),
    (HEAD + ["M3 S100"], "M3 constant"),
    (HEAD + ["G91"], "incremental"),
    (HEAD + ["G1 Z5 F100"], "Z move in a laser program"),
    (HEAD + ["G28"], "not accepted"),
    (["G0 X10 Y10"], "before G21 and G90"),
    (["G21 G90", "G1 X10 Y10"], "before any F"),
    (HEAD + ["G1 X20 Y20 F1000 ZZ"], "cannot parse"),
])
def test_checker_refuses(lines, match):
    with pytest.raises(ProgramError, match=match) as exc:
        validate(lines, default_machine(), "bad.nc")
    assert str(exc.value).startswith("bad.nc:")
    lineno = int(str(exc.value).split(":")[1])
    assert repr(lines[lineno - 1]) in str(exc.value)


def test_checker_accepts_and_estimates():
    lines = HEAD + ["M4 S500", "G1 X110 Y10 F6000", "G3 X10 Y10 I-50 J0", "M5", "G4 P0.5"]
    chk = validate(lines, default_machine())
    assert chk.cut_length_mm == pytest.approx(100 + np.pi * 50, rel=1e-6)
    assert chk.travel_length_mm == 0.0  # position unknown before the first G0
    # 100 mm at 100 mm/s with 1500 mm/s^2: 1 s plus the acceleration ramps
    assert chk.seconds[4] == pytest.approx(1.0 + 100 / 1500, rel=1e-6)
    assert chk.seconds[-1] == 0.5
    assert chk.bounds[3] == pytest.approx(60.0)  # the arc's top, not only its end points


def test_parse_pieces_faults():
    with pytest.raises(ProgramError, match="no G4 sync"):
        parse_pieces(["(piece 1 begin a a)", "G0 X1 Y1", "(piece 1 end)"], "x.nc")
    with pytest.raises(ProgramError, match="no end marker"):
        parse_pieces(["(piece 1 begin a a)", "G4 P0.01"], "x.nc")


@pytest.mark.parametrize("kind", ["slit", "v"])
def test_notches_run_into_the_piece(kind):
    """Each notch starts (or ends) on the cut line and reaches notch_depth into the piece,
    whichever sense the layout gave its direction."""
    machine = default_machine().with_cut(notch=kind, notch_depth=3.0, notch_width=2.0)
    tps = build_toolpaths(layout_from_dict(LAYOUT, "t"), machine)
    polys = piece_polygons(LAYOUT)
    n_notches = 0
    for tp in tps:
        piece = polys[tp.id]
        for c in tp.contours:
            if c.kind != "notch":
                continue
            n_notches += 1
            pts = c.points
            assert len(pts) == (2 if kind == "slit" else 3)
            if kind == "slit":
                apex, mouth = (pts[0], pts[1]) if piece.contains(shapely.Point(pts[0])) \
                    else (pts[1], pts[0])
            else:
                apex, mouth = pts[1], (pts[0] + pts[2]) / 2
                assert np.hypot(*(pts[0] - pts[2])) == pytest.approx(2.0, abs=1e-6)
            # notch_depth into the piece from the outline, opening on the kerf line outside
            assert piece.contains(shapely.Point(apex))
            assert not piece.contains(shapely.Point(mouth))
            assert np.hypot(*(apex - mouth)) == pytest.approx(3.0 + machine.cut.kerf / 2)
            assert piece.exterior.distance(shapely.Point(mouth)) <= machine.cut.kerf / 2 + 1e-9
    assert n_notches == 4


def test_no_lead_in_without_a_gap():
    """With touching pieces a lead-in would cut the neighbour: none, and a warning."""
    data = dict(make_layout(), gap=0)
    machine = default_machine().with_cut(lead_in=2.0)
    prog = build_program(build_toolpaths(layout_from_dict(data, "t"), machine), machine)
    assert len(prog.warnings) == 3 and all("no lead-in" in w for w in prog.warnings)
    polys = piece_polygons(data)
    moves = trace(prog.lines)
    for pr in prog.pieces:
        last_m4 = max(i for i in range(pr.first_line, pr.sync_line)
                      if prog.lines[i].startswith("M4"))
        x, y = next(m for m in moves if m["line"] > last_m4)["pts"][0]
        # the outline starts on its own cut line (kerf/2 outside, more at a mitred corner),
        # not 2 mm further out
        d = polys[pr.id].exterior.distance(shapely.Point(x, y))
        assert machine.cut.kerf / 2 - 0.01 <= d <= machine.cut.kerf / 2 * 2 ** 0.5 + 0.01


@pytest.mark.parametrize("feed,ok", [(100, False), (299, False), (300, True), (3000, True)])
def test_beam_on_moves_below_min_cut_feed_are_refused(feed, ok):
    """Issue 16: `F1` with the beam on passed the checker; a slow beam burns through."""
    lines = ["G21 G90 G94 G17", "M5", "G0 X10 Y10", "M4 S700", f"G1 X50 Y10 F{feed}", "M5",
             f"G1 X60 Y10 F{min(feed, 10)}"]  # beam off: any feed is fine
    m = default_machine()
    assert m.min_cut_feed == 300
    if ok:
        chk = validate(lines, m)
        assert chk.cut_feeds == (float(feed),) and chk.cut_powers == (700.0,)
        assert chk.line_power.tolist() == [0, 0, 0, 0, 700, 0, 0]
        assert chk.line_motion.tolist() == [-1, -1, 0, -1, 1, -1, 1]
    else:
        with pytest.raises(ProgramError, match=r":5: beam on at F\d+, below the machine's "
                                               "min_cut_feed 300"):
            validate(lines, m)
