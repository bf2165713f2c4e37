"""The nest step (issue 35): a marker longer than the table window is planned in bites
rather than refused; one that fits is nested in the window as before."""

from __future__ import annotations

from solver.nest import NestProblem, Piece
from solver.nest.layout import Layout
from station.steps.bites import load_bites, save_bites
from station.steps.nest import nest_in_window_or_bites
from station.steps.table import TableWindow

WINDOW = TableWindow(0.0, 0.0, 400.0, 300.0)


def _squares(n: int) -> NestProblem:
    pieces = [Piece(f"s{i}", [[0, 0], [90, 0], [90, 90], [0, 90]]) for i in range(n)]
    return NestProblem(pieces, width=WINDOW.width, length=WINDOW.length, gap=4.0)


def test_a_marker_that_fits_the_window_has_no_bites():
    layout, bites = nest_in_window_or_bites(_squares(4), WINDOW, 1.0)
    assert bites is None and layout.length <= WINDOW.length


def test_a_marker_longer_than_the_window_is_cut_in_bites(tmp_path):
    layout, bites = nest_in_window_or_bites(_squares(24), WINDOW, 2.0)  # 1.6x the window
    assert bites is not None and len(bites.bites) >= 2
    assert layout is bites.layout and layout.length > WINDOW.length
    where = bites.bite_of()
    assert sorted(where) == sorted(p.id for p in layout.pieces)  # each piece in one bite
    for bite in bites.bites:  # no piece straddles its bite's window
        for p in (q for q in layout.pieces if q.id in bite.pieces):
            xs = p.outline[:, 0]
            assert bite.start_mm - 1e-6 <= xs.min() and xs.max() <= bite.start_mm + \
                bites.window_mm + 1e-6
    layout.save(tmp_path / "layout.json")
    save_bites(bites, tmp_path / "bites.json")
    again = load_bites(Layout.load(tmp_path / "layout.json"), tmp_path / "bites.json")
    assert again.bite_of() == where and again.window_mm == bites.window_mm
