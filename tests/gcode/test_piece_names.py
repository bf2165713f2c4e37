"""A piece named with spaces, as a CAD names it ("REGULAR TEEFR"), is cut and journaled by
its whole name (issue 34: the G-code piece markers were split at the first space, and the
cut stopped with ``KeyError: 'REGULAR'``)."""

from __future__ import annotations

import sys
from pathlib import Path

from gcode.layout import layout_from_dict
from gcode.machine import default_machine
from gcode.program import PieceMarkers, build_program, program_from_lines
from gcode.resume import stroke_syncs
from gcode.toolpath import build_toolpaths

sys.path.insert(0, str(Path(__file__).parent))  # gcode_helpers (importlib mode)
from gcode_helpers import make_layout  # noqa: E402

MACHINE = default_machine()


def test_a_piece_name_with_spaces_is_one_piece_in_the_program_and_its_file() -> None:
    doc = make_layout()
    for k, p in enumerate(doc["pieces"]):
        p["id"], p["name"] = f"REGULAR TEEFR {k}", "REGULAR TEEFR"
    toolpaths = build_toolpaths(layout_from_dict(doc, "t"), MACHINE)
    index = {tp.id: k for k, tp in enumerate(toolpaths)}
    program = build_program(toolpaths, MACHINE, markers=PieceMarkers(3, index))
    ids = [f"REGULAR TEEFR {k}" for k in range(len(doc["pieces"]))]
    # the typed program, which the daemon cuts and journals by, keeps each whole id
    assert sorted(r.id for r in program.pieces) == ids
    assert sorted(stroke_syncs(program)) == ids  # the journal's lookup (index[pid])
    # read back from its text (a .nc file), each piece is still one piece, its id one
    # word and its name whole
    back = program_from_lines(program.lines)
    assert [(r.id, r.name) for r in back.pieces] == [
        (r.id.replace(" ", "_"), "REGULAR TEEFR") for r in program.pieces]
    assert [(r.first_line, r.sync_line, r.last_line) for r in back.pieces] == [
        (r.first_line, r.sync_line, r.last_line) for r in program.pieces]
