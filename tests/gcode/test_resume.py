"""Resuming a piece where it stopped: progress follows the head forward along the
strokes only, and the resumed piece starts the stated overlap before that point."""

from __future__ import annotations

import numpy as np

from gcode.machine import default_machine
from gcode.resume import (
    OVERLAP_MM,
    PieceStrokes,
    advance,
    load_strokes,
    resumed_toolpath,
    save_strokes,
)
from gcode.toolpath import PieceToolpath

SQUARE = np.array([[0, 0], [100, 0], [100, 100], [0, 100], [0, 0]], float)
NOTCH_A = np.array([[50, -3], [50, 3]], float)  # cut first
NOTCH_B = np.array([[20, 97], [20, 103]], float)  # crossed by a rapid from A to the square?


def strokes() -> PieceStrokes:
    return PieceStrokes(["notch", "notch", "outline"], [NOTCH_A, NOTCH_B, SQUARE])


def test_progress_follows_the_head_forward_only():
    s = strokes()
    assert s.total_mm == 6 + 6 + 400
    assert advance(s, 0.0, np.array([50.0, 1.0])) == 4.0  # 4 mm into notch A
    # on the square's right edge, 50 mm up: 12 + 100 + 50
    assert advance(s, 12.0, np.array([100.0, 50.0])) == 162.0
    # the square's corner (0, 0) is both its start and its end: forward from 200 mm it
    # is the end, never back to the start
    assert advance(s, 300.0, np.array([0.0, 0.0])) == 412.0
    assert advance(s, 300.0, np.array([0.0, 2.0])) == 410.0
    # a head off the path, or at a point already passed, changes nothing
    assert advance(s, 162.0, np.array([50.0, 50.0])) == 162.0
    assert advance(s, 162.0, np.array([50.0, 0.0])) == 162.0
    assert advance(s, 162.0, None) == 162.0


def test_a_rapid_over_a_later_stroke_does_not_count_within_the_stroke_in_progress():
    s = strokes()
    over_square = np.array([60.0, 0.0])  # a rapid from notch A crossing the square's edge
    assert advance(s, 6.0, over_square) == 72.0  # any stroke: would skip notch B
    assert advance(s, 6.0, over_square, stroke=1) == 6.0  # notch B is the one in progress
    assert advance(s, 12.0, over_square, stroke=2) == 72.0


def test_the_resumed_piece_starts_the_overlap_back_and_keeps_every_later_stroke(tmp_path):
    machine = default_machine()
    tp = PieceToolpath(0, "p", "front")
    resumed, first_stroke = resumed_toolpath(tp, strokes(), 162.0, machine)
    assert first_stroke == 2
    kinds = [c.kind for c in resumed.contours]
    assert kinds == ["outline"]  # both notches were cut
    first = resumed.contours[0].points
    np.testing.assert_allclose(first[0], [100.0, 50.0 - OVERLAP_MM])
    np.testing.assert_allclose(first[-1], [0.0, 0.0])
    assert abs(float(np.hypot(*np.diff(first, axis=0).T).sum()) - (250 + OVERLAP_MM)) < 1e-9
    # from within notch A: its rest, then notch B and the square in full, kinds kept
    again, first_stroke = resumed_toolpath(tp, strokes(), 5.0, machine)
    assert first_stroke == 0
    assert [c.kind for c in again.contours] == ["notch", "notch", "outline"]
    np.testing.assert_allclose(again.contours[0].points[0], [50.0, -1.0])
    # saved and loaded as they were, for this job only
    save_strokes(tmp_path / "s.json", 7, {3: strokes()}, stopped=(3, np.array([1.0, 2.0])))
    back, stopped = load_strokes(tmp_path / "s.json", 7)
    assert back[3].kinds == strokes().kinds and back[3].total_mm == strokes().total_mm
    assert stopped[0] == 3 and stopped[1].tolist() == [1.0, 2.0]
    assert load_strokes(tmp_path / "s.json", 8) == ({}, None)


def test_every_stroke_is_followed_by_its_sync():
    from gcode.program import STROKE_SYNC, SYNC, build_program
    from gcode.resume import stroke_syncs

    machine = default_machine()
    on_table = PieceStrokes(strokes().kinds, [p + 10.0 for p in strokes().points])
    tp, _ = resumed_toolpath(PieceToolpath(0, "p", "front"), on_table, 0.0, machine)
    program = build_program([tp], machine)
    syncs = stroke_syncs(program)["p"]
    assert len(syncs) == 3  # one after each of the three strokes
    piece = program.pieces[0]
    assert program.lines[piece.sync_line] == SYNC
    assert program.lines[piece.sync_line - 1] == STROKE_SYNC
