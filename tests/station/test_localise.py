"""Each piece of a bite placed on the print under it (station.steps.bites.localise): a
print lying off the plan by a known shift and shear moves the piece with it."""

import numpy as np
import pytest

from simulators.classics import classic_print
from simulators.fabric import to_uint8
from solver.nest.bites import Bite, BitePlan
from solver.nest.instance import IDENTITY, affine
from solver.nest.layout import Layout, Placed
from station.steps.bites import LOCAL_MAP_TOLERANCE_MM, RollTrack, localise
from vision.advance import Advance
from vision.localmap import PrintReference

PLAID = classic_print("plaid", 80.0, origin=(13.0, 21.0))
OUTLINE = np.array([[200.0, 140.0], [560.0, 140.0], [560.0, 380.0], [200.0, 380.0]])


def window_photo(design_of, shape=(500, 760)):
    y, x = np.mgrid[0:shape[0], 0:shape[1]].astype(float)
    return to_uint8(PLAID.colour_at(*design_of(x, y), 1.0))


def test_a_piece_follows_the_print_it_lies_on():
    reference = PrintReference.from_photo(window_photo(lambda x, y: (x, y)),
                                          PLAID.truth.basis, PLAID.truth.origin)
    shift, shear = np.array([2.0, -1.5]), 0.008  # the print lies 2 mm on, sheared 0.46 deg

    def design_of(x, y):  # the print expected at p lies at p + shift + (shear p_y, 0)
        py = y - shift[1]
        return x - shift[0] - shear * py, py

    piece = Placed("a#1", "a", IDENTITY.copy(), False, OUTLINE.copy())
    plan = BitePlan(Layout(500.0, 760.0, 0.0, [piece]), [Bite(0, 0.0, 760.0, ("a#1",), 0.0)],
                    760.0, 760.0)
    track = localise(RollTrack(), plan.bites[0], window_photo(design_of), plan=plan,
                     reference=reference)
    cut = track.bite_layout(plan, plan.bites[0]).pieces[0].outline
    want = OUTLINE + shift + np.column_stack([shear * OUTLINE[:, 1], 0 * OUTLINE[:, 1]])
    assert np.abs(cut - want).max() < 0.3  # mm, at the piece's corners
    (note,) = track.local
    assert note["piece"] == "a#1" and note["bite"] == 0
    assert note["moved_mm"] == pytest.approx(np.hypot(2.0 + shear * 260.0, 1.5), abs=0.2)
    assert note["beyond_affine_mm"] < LOCAL_MAP_TOLERANCE_MM and not note["distorted"]
    # the roll moves on: the next bite's pieces get maps of their own
    moved = track.follow(Advance(700.0, 0.0, 0.0, 700.0, (380.0, 250.0), 0.0, 9))
    assert moved.piece_maps == {} and moved.local == []
    assert affine(moved.marker_to_window, OUTLINE) == pytest.approx(OUTLINE - [700.0, 0.0])


def test_a_piece_over_no_print_is_named_and_kept_where_the_track_says():
    reference = PrintReference.from_photo(window_photo(lambda x, y: (x, y)),
                                          PLAID.truth.basis, PLAID.truth.origin)
    noise = np.random.default_rng(5).integers(0, 255, (500, 760, 3), dtype=np.uint8)
    piece = Placed("a#1", "a", IDENTITY.copy(), False, OUTLINE.copy())
    plan = BitePlan(Layout(500.0, 760.0, 0.0, [piece]), [Bite(0, 0.0, 760.0, ("a#1",), 0.0)],
                    760.0, 760.0)
    track = localise(RollTrack(), plan.bites[0], noise, plan=plan, reference=reference)
    (note,) = track.local
    assert note["distorted"] and not note["mapped"] and note["moved_mm"] == 0.0
    assert track.piece_maps == {}
    assert track.bite_layout(plan, plan.bites[0]).pieces[0].outline == pytest.approx(OUTLINE)
