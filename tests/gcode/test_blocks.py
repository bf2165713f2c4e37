"""The typed program model (issue 33): blocks rendered only at the edge, one text parser
that reads back exactly what the builder wrote, the recovery markers written by the
builder and checked with everything else, and ports that declare their own time."""

from __future__ import annotations

import ast
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import serial

import simulators.grbl  # noqa: F401  (registers grblsim://)
from gcode.blocks import Motion, Sync, parse_lines
from gcode.layout import layout_from_dict
from gcode.machine import default_machine
from gcode.program import (
    PieceMarkers,
    ProgramError,
    build_program,
    load_program,
    validate,
)
from gcode.session import port_timing
from gcode.stream import Streamer
from gcode.toolpath import build_toolpaths

sys.path.insert(0, str(Path(__file__).parent))  # gcode_helpers (importlib mode)
from gcode_helpers import make_layout  # noqa: E402

GCODE = Path(__file__).resolve().parents[2] / "gcode"
MACHINE = default_machine()


@pytest.fixture(scope="module")
def toolpaths():
    return build_toolpaths(layout_from_dict(make_layout(), "t"), MACHINE)


@pytest.fixture(scope="module")
def index(toolpaths):
    """Store indexes in another order than the cut order."""
    return {tp.id: 10 + k for k, tp in enumerate(reversed(toolpaths))}


@pytest.fixture(scope="module")
def marked(toolpaths, index):
    return build_program(toolpaths, MACHINE, markers=PieceMarkers(7, index))


def _attrs(blocks):
    return [(b.words, b.comment, b.motion, b.beam, b.piece, b.sync) for b in blocks]


def test_the_parser_reads_back_what_the_builder_wrote(tmp_path, marked, toolpaths):
    """Written to a .nc file and loaded, the program is the same blocks (motion, beam,
    piece, sync role: markers, stroke and piece syncs) and the same check."""
    marked.write(tmp_path / "job.nc")
    again = load_program(tmp_path / "job.nc", MACHINE)
    assert again.lines == marked.lines
    assert _attrs(again.blocks) == _attrs(marked.blocks)
    assert [(p.number, p.id, p.first_line, p.sync_line, p.last_line) for p in again.pieces] \
        == [(p.number, p.id, p.first_line, p.sync_line, p.last_line) for p in marked.pieces]
    assert np.array_equal(again.check.path_line, marked.check.path_line)
    assert np.array_equal(again.check.line_power, marked.check.line_power)
    roles = [b.sync for b in marked.blocks]
    n = len(toolpaths)
    assert roles.count(Sync.PIECE) == n and roles.count(Sync.MARKER) == 2 * n
    assert roles.count(Sync.STROKE) == sum(len(c.strokes) for tp in toolpaths
                                           for c in tp.contours)


def test_markers_need_every_pieces_store_index(toolpaths):
    with pytest.raises(ValueError, match="no store index for piece"):
        build_program(toolpaths, MACHINE, markers=PieceMarkers(7, {}))


def test_markers_bracket_one_feed_move_and_are_checked(marked, index, toolpaths):
    """Phase 1 right before each piece's last feed move, phase 2 right after, naming the
    store's piece; the blocks with their answers proving the piece are sent alone."""
    for r in marked.pieces:
        body = marked.blocks[r.first_line:r.sync_line]
        ones = [k for k, b in enumerate(body) if b.sync == Sync.MARKER and b.values["Z"] == 1]
        assert len(ones) == 1
        one = ones[0]
        assert body[one].values["Y"] == index[r.id] + 1 and body[one].values["X"] == 7
        assert body[one + 1].is_move and body[one + 2].values["Z"] == 2
        assert not any(b.is_move for b in body[one + 2:])
        assert body[one].alone and body[one].motion == Motion.OTHER
    # the markers do not move the head: the path is the unmarked program's
    plain = build_program(toolpaths, MACHINE)
    assert np.array_equal(plain.check.path, marked.check.path)
    assert plain.check.estimated_seconds == pytest.approx(marked.check.estimated_seconds)


HEAD = ["G21 G90 G94 G17", "M5", "G0 X10 Y10", "M4 S500"]


@pytest.mark.parametrize("lines,match", [
    (HEAD + ["G10 L2 P6 X7 Y1 Z2", "G1 X20 Y10 F1000"], "phase 2 without its phase 1"),
    (HEAD + ["G10 L2 P6 X7 Y1 Z1", "G1 X20 Y10 F1000", "G1 X30 Y10", "G10 L2 P6 X7 Y1 Z2"],
     "phase 2 without its phase 1 one feed move before"),
    (HEAD + ["G10 L2 P6 X7 Y1 Z1", "G1 X20 Y10 F1000", "G10 L2 P6 X7 Y2 Z2"],
     "phase 2 without"),
    (HEAD + ["G10 L2 P6 X7 Y1 Z1", "G1 X20 Y10 F1000"], "phase 1 without its phase 2"),
    (HEAD + ["G10 L20 P1 X0 Y0"], "only as the station's piece marker"),
    (HEAD + ["G10 L2 P1 X7 Y1 Z1"], "only as the station's piece marker"),
    (HEAD + ["G10 L2 P6 X7.5 Y1 Z1"], "only as the station's piece marker"),
    (HEAD + ["G1 X20 Y10 L2 F1000"], r"word\(s\) \['L'\] not accepted"),
])
def test_the_checker_refuses_markers_out_of_place(lines, match):
    with pytest.raises(ProgramError, match=match):
        validate(lines, MACHINE, "bad.nc")


def test_a_marker_pair_around_one_move_passes_and_moves_nothing():
    chk = validate(HEAD + ["G10 L2 P6 X7 Y1 Z1", "G1 X20 Y10 F1000", "G10 L2 P6 X7 Y1 Z2",
                           "G1 X30 Y10"], MACHINE)
    assert chk.line_motion.tolist() == [-1, -1, 0, -1, -1, 1, -1, 1]
    assert chk.cut_length_mm == pytest.approx(20.0)


def test_settle_reads_modal_motion_and_beam():
    blocks = parse_lines(["G21 G90", "G0 X1 Y1", "X2", "M4 S0", "G1 X3 F600", "S300",
                          "X4", "G4 P0", "M5", "X5"])
    assert [b.motion for b in blocks] == [Motion.OTHER, Motion.RAPID, Motion.RAPID,
                                          Motion.OTHER, Motion.LINE, Motion.OTHER,
                                          Motion.LINE, Motion.DWELL, Motion.OTHER,
                                          Motion.LINE]
    assert [b.beam for b in blocks] == [False] * 5 + [True, True, True, False, False]
    assert blocks[7].sync == Sync.STROKE
    assert replace(blocks[4], raw=None).text == "G1 X3 F600"


class _DeclaredPort:
    """A port that says how its machine's time runs (as grblsim:// does)."""

    timeout = 0.02
    baudrate = 9600  # not the wire's: the declared line_baud wins
    time_scale = 25.0
    line_baud = None

    def machine_clock(self) -> float:
        return 1234.5


class _PlainPort:
    """A real serial port declares nothing: wall clock, $I asked, its baud rate."""

    timeout = 0.02
    baudrate = 115200


def test_ports_declare_their_time():
    t = port_timing(_PlainPort())
    assert (t.time_scale, t.clock, t.baud) == (None, None, 115200.0)
    st = Streamer(_PlainPort())
    assert st.time_scale == 1.0 and st._ask_time_scale and st.line_baud == 115200.0
    assert abs(st._clock() - time.monotonic()) < 1.0
    st = Streamer(_DeclaredPort())
    assert st.time_scale == 25.0 and not st._ask_time_scale and st.line_baud is None
    assert st._clock() == 1234.5
    assert Streamer(_DeclaredPort(), time_scale=3.0).time_scale == 3.0  # given wins


def test_the_grblsim_port_declares_its_machine_time():
    with serial.serial_for_url("grblsim://?speed=7&baud=57600", timeout=0.02) as port:
        t = port_timing(port)
        assert t.time_scale == 7.0 and t.baud == pytest.approx(57600.0)
        assert t.clock() == port.emulator.sim_time
    with serial.serial_for_url("grblsim://?speed=3", timeout=0.02) as port:
        assert port_timing(port).baud is None  # bytes arrive at once: no wire to pace


def test_gcode_never_asks_what_kind_of_port_it_has():
    """No module of gcode reads an ``emulator`` attribute, nor imports another package of
    the station (the one-way rule: gcode uses nothing of the others)."""
    others = {"solver", "vision", "station", "simulators"}
    for path in GCODE.glob("*.py"):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute):
                assert node.attr != "emulator", f"{path.name}:{node.lineno}"
            if isinstance(node, ast.Constant) and isinstance(node.value, str):
                assert node.value != "emulator", f"{path.name}:{node.lineno}"
            if isinstance(node, ast.ImportFrom) and node.module:
                assert node.module.split(".")[0] not in others, f"{path.name}:{node.lineno}"
            if isinstance(node, ast.Import):
                assert not {a.name.split(".")[0] for a in node.names} & others, path.name
