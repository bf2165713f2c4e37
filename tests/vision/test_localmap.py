"""Local maps of a distorted print (vision.localmap): a known affine distortion of a
synthetic plaid is recovered from the photograph alone; the rigid placement nearest a
local map is the weighted least-squares one."""

import numpy as np
import pytest

from simulators.classics import classic_print
from simulators.fabric import to_uint8
from vision.localmap import (
    PrintReference,
    fit_local_map,
    local_shifts,
    nearest_rigid,
    tile_centres,
)

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


def rotation(deg):
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, -s], [s, c]])


def test_the_nearest_rigid_map_is_the_weighted_least_squares_one():
    rng = np.random.default_rng(3)
    points, weights = rng.uniform(0, 500, (40, 2)), rng.uniform(0.1, 3.0, 40)
    rigid_map = np.column_stack([rotation(0.7), [3.0, -2.0]])
    got, residual = nearest_rigid(rigid_map, points, weights)  # already rigid: itself
    assert got == pytest.approx(rigid_map, abs=1e-12) and residual.max() < 1e-9
    stretched = np.column_stack([rotation(0.7) @ [[1.01, 0.004], [0.0, 0.995]], [3.0, -2.0]])
    got, residual = nearest_rigid(stretched, points, weights)
    lin = got[:, :2]
    assert lin.T @ lin == pytest.approx(np.eye(2), abs=1e-12) and np.linalg.det(lin) > 0
    target = points @ stretched[:, :2].T + stretched[:, 2]
    assert residual == pytest.approx(np.hypot(*(target - points @ lin.T - got[:, 2]).T))

    def cost(deg, shift):
        moved = points @ rotation(deg).T + shift
        return weights @ np.sum((moved - target) ** 2, axis=1)

    angle = np.degrees(np.arctan2(lin[1, 0], lin[0, 0]))
    best = cost(angle, got[:, 2])
    for d_deg, d_shift in ((0.01, 0), (-0.01, 0), (0, [0.05, 0]), (0, [0, -0.05])):
        assert cost(angle + d_deg, got[:, 2] + d_shift) > best
    # the weights count: a side weighted heavily is followed closely, at the other's cost
    heavy = np.where(points[:, 0] < 250, 100.0, 0.01)
    _, leaning = nearest_rigid(stretched, points, heavy)
    assert leaning[points[:, 0] < 250].max() < residual[points[:, 0] < 250].max()
    with pytest.raises(ValueError, match="weights"):
        nearest_rigid(stretched, points, weights[:-1])
