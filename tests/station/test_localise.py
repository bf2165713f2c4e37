"""Each piece of a bite placed on the print under it (station.steps.bites.localise): a
print lying off the plan by a known shift and shear moves the piece with it; placed
rigidly (the default) a piece keeps its shape on a stretched print, and what the print's
stretch leaves at its sew line is reported as its seam error."""

import numpy as np
import pytest
from scipy.spatial.distance import pdist

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
                     reference=reference)  # the default follows the print
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


def test_a_piece_keeps_its_shape_on_a_stretched_print_and_names_what_is_left():
    reference = PrintReference.from_photo(window_photo(lambda x, y: (x, y)),
                                          PLAID.truth.basis, PLAID.truth.origin)
    centre, shift, stretch = np.array([380.0, 260.0]), np.array([1.5, -1.0]), 1.01

    def design_of(x, y):  # the print expected at p lies at c + 1.01 (p - c)_x + shift
        return centre[0] + (x - shift[0] - centre[0]) / stretch, y - shift[1]

    sew = OUTLINE + [[10.0, 10.0], [-10.0, 10.0], [-10.0, -10.0], [10.0, -10.0]]
    # a right piece, mirrored in the marker: it must stay mirrored
    flip = np.array([[-1.0, 0.0, 760.0], [0.0, 1.0, 0.0]])
    piece = Placed("a#1", "a", flip, True, OUTLINE.copy(), sew_line=sew)
    plan = BitePlan(Layout(500.0, 760.0, 0.0, [piece]), [Bite(0, 0.0, 760.0, ("a#1",), 0.0)],
                    760.0, 760.0)
    photo = window_photo(design_of)
    cut = {}
    for follow in ("rigid", "affine"):
        track = localise(RollTrack(), plan.bites[0], photo, plan=plan, reference=reference,
                         follow=follow)
        cut[follow], (cut[follow + " note"],) = (
            track.bite_layout(plan, plan.bites[0]).pieces[0], track.local)
    rigid, affine_cut = cut["rigid"], cut["affine"]
    for before, after in ((OUTLINE, rigid.outline), (sew, rigid.sew_line)):
        assert pdist(after) == pytest.approx(pdist(before), abs=1e-6)  # lengths kept
    assert rigid.mirrored and np.linalg.det(rigid.transform[:, :2]) < 0
    # it lies where the print's centre went: the stretch splits either side
    assert rigid.sew_line.mean(axis=0) == pytest.approx(sew.mean(axis=0) + shift, abs=0.3)
    # the affine choice follows the print, stretched 1 % with it
    want = np.column_stack([centre[0] + stretch * (OUTLINE[:, 0] - centre[0]),
                            OUTLINE[:, 1]]) + shift
    assert np.abs(affine_cut.outline - want).max() < 0.3
    # the residual reported is what the rigid cut leaves of the affine one at the sew line
    measured = np.hypot(*(affine_cut.sew_line - rigid.sew_line).T).max()
    note = cut["rigid note"]
    assert note["rigid_residual_mm"] == pytest.approx(measured, abs=1e-3)
    assert measured == pytest.approx(0.01 * 170.0, abs=0.2)  # half the sew line's width
    assert note["seam_error_expected_mm"] == pytest.approx(
        measured + note["beyond_affine_mm"], abs=2e-3)
    assert note["distorted"] and note["follow"] == "rigid"  # 1.7 mm: over the tolerance
    assert not cut["affine note"]["distorted"]
    assert cut["affine note"]["seam_error_expected_mm"] == cut["affine note"][
        "beyond_affine_mm"]
