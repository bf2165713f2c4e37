"""Local maps of a distorted print (vision.localmap): a known affine distortion of a
synthetic plaid is recovered from the photograph alone."""

import numpy as np
import pytest

from simulators.classics import classic_print
from simulators.fabric import to_uint8
from vision.localmap import PrintReference, fit_local_map, local_shifts, tile_centres

IDENTITY = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def photograph(plaid, shape, design_of):
    """The plaid as seen in a window of ``shape`` (rows, cols) at 1 mm/px, each pixel
    showing the design point ``design_of(x, y)``."""
    y, x = np.mgrid[0:shape[0], 0:shape[1]].astype(float)
    return to_uint8(plaid.colour_at(*design_of(x, y), 1.0))


@pytest.fixture(scope="module")
def plaid_and_reference():
    plaid = classic_print("plaid", 80.0, origin=(13.0, 21.0))
    flat = photograph(plaid, (400, 640), lambda x, y: (x, y))
    truth = plaid.truth
    return plaid, PrintReference.from_photo(flat, truth.basis, truth.origin)


def test_recovers_a_known_affine_distortion(plaid_and_reference):
    plaid, reference = plaid_and_reference
    # the print expected at p lies at p + lin p + shift: stretched 0.3 %, sheared 0.6 deg
    lin = np.array([[0.003, 0.0105], [0.0, -0.002]])
    shift = np.array([2.4, -1.7])
    forward = np.column_stack([np.eye(2) + lin, shift])
    back = np.linalg.inv(np.eye(2) + lin)

    def design_of(x, y):
        px, py = x - shift[0], y - shift[1]
        return back[0, 0] * px + back[0, 1] * py, back[1, 0] * px + back[1, 1] * py

    photo = photograph(plaid, (600, 900), design_of)
    box = np.array([[150.0, 120.0], [700.0, 480.0]])
    centres = tile_centres(box, photo.shape[:2])
    shifts = local_shifts(photo, reference, IDENTITY, centres)
    local = fit_local_map(centres.astype(float), shifts)
    corners = np.array([[150.0, 120.0], [700.0, 120.0], [700.0, 480.0], [150.0, 480.0]])
    got = corners @ local.correction[:, :2].T + local.correction[:, 2]
    want = corners @ forward[:, :2].T + forward[:, 2]
    assert np.abs(got - want).max() < 0.25  # mm, at the piece's corners
    assert local.beyond_mm < 0.5 and local.tiles >= 9
    assert local.strain == pytest.approx(0.0065, abs=0.002)


def test_a_bowed_print_is_named_beyond_one_affine_map(plaid_and_reference):
    plaid, reference = plaid_and_reference
    bow = 6.0  # mm at mid-height: a parabola no affine map follows

    def design_of(x, y):
        return x - bow * (1.0 - ((y - 300.0) / 300.0) ** 2), y

    photo = photograph(plaid, (600, 700), design_of)
    centres = tile_centres(np.array([[64.0, 64.0], [636.0, 536.0]]), photo.shape[:2])
    local = fit_local_map(centres.astype(float), local_shifts(photo, reference, IDENTITY,
                                                              centres))
    assert 1.5 < local.beyond_mm < bow
