"""The measures a pattern maker reads a reshape by: outline roughness and seam ease."""

from __future__ import annotations

import numpy as np
import pytest

from solver.garment import build_garment
from solver.reshape.ease import ease_targets
from solver.reshape.energy import twin_lengths
from solver.reshape.quality import (
    outline_roughness,
    seam_ease_changes,
    seam_side_lengths,
    sewn_drift,
)


def _sewn_squares(cells: int = 50) -> object:
    """Two 100 mm squares, the right side of the first sewn to the left side of the
    second, each cut into ``cells`` x ``cells`` squares (2 mm outline edges at 50)."""
    n = cells + 1
    xs = np.linspace(0.0, 100.0, n)
    gx, gy = np.meshgrid(xs, xs, indexing="ij")
    grid = np.column_stack([gx.ravel(), gy.ravel()])
    idx = np.arange(n * n).reshape(n, n)
    quads = np.column_stack([idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(),
                             idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()])
    tri = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    point = np.arange(2 * n * n)
    point[n * n + idx[0]] = idx[-1]
    return build_garment(np.concatenate([grid, grid + [150.0, 0.0]]),
                         np.concatenate([tri, tri + n * n]), point, xyz=None,
                         source="sewn-squares", kind="test")


@pytest.fixture(scope="module")
def squares():
    return _sewn_squares()


def test_a_rigid_move_and_a_slow_wave_are_smooth(squares):
    g = squares
    assert np.abs(outline_roughness(g, g.uv + [3.0, -7.0])).max() < 1e-9
    # one sine period along the whole 400 mm outline: a 10 mm average leaves
    # A (1 - sinc) ~ A (pi w / P)^2 / 6 = 1 % of it
    loop = g.piece_loops(0)[0]
    p = g.uv[loop]
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
    uv = g.uv.copy()
    uv[loop, 0] += 5.0 * np.sin(2.0 * np.pi * s / 400.0)
    rough = outline_roughness(g, uv)
    assert 0.0 < rough.max() < 0.011 * 5.0


def test_a_zig_zag_is_unexplained_whole(squares):
    """Alternate outline vertices 2 mm apart pushed +-a: the 10 mm window about a vertex
    holds four whole segments (mean 0) and two half segments from +-a to 0 (a/2 mm
    each), so it averages a/10 and 0.9 a of each push is unexplained."""
    g = squares
    loop = g.piece_loops(0)[0]
    uv = g.uv.copy()
    a = 0.4
    uv[loop, 1] += a * np.where(np.arange(len(loop)) % 2 == 0, 1.0, -1.0)
    rough = outline_roughness(g, uv)
    on_loop = rough[:len(loop)]
    assert on_loop == pytest.approx(np.full(len(loop), 0.9 * a), abs=1e-9)
    assert np.abs(rough[len(loop):]).max() < 1e-12  # the other piece did not move


def test_roughness_refuses_another_mesh(squares):
    with pytest.raises(ValueError, match="shape"):
        outline_roughness(squares, squares.uv[:-1])


def test_ease_changes_name_both_sides(squares):
    g = squares
    a, b = seam_side_lengths(g, g.uv)
    assert a == pytest.approx([100.0]) and b == pytest.approx([100.0])
    uv = g.uv.copy()
    right = (g.piece_of_vertex == 0) & (g.uv[:, 0] > 99.0)
    uv[right, 1] *= 1.02  # the first side stretched by 2 mm
    (seam,) = seam_ease_changes(g, uv)
    assert seam["side_change_mm"] == pytest.approx([2.0, 0.0])
    assert seam["ease_change_mm"] == pytest.approx(2.0)
    both = uv.copy()
    left = (g.piece_of_vertex == 1) & (g.uv[:, 0] < 151.0)
    both[left, 1] *= 1.02  # ... and the second by as much: it sews as before
    assert seam_ease_changes(g, both)[0]["ease_change_mm"] == pytest.approx(0.0, abs=1e-9)


def test_a_seam_gives_at_most_half_a_millimetre_of_its_ease(squares):
    """A 2 mm ease keeps 1.5 mm, spread over the pairs as drafted; 0.3 mm of difference
    (less than it may give) is pulled to equal lengths, as the paper asks."""
    g = squares
    for stretch, kept in ((1.02, 1.5), (1.003, 0.0)):
        uv = g.uv.copy()
        right = (g.piece_of_vertex == 0) & (g.uv[:, 0] > 99.0)
        uv[right, 1] *= stretch
        stretched = g.with_uv(uv)
        pairs, (line,) = ease_targets(stretched, 0.5)
        drafted = twin_lengths(uv, g.seam_edges)
        assert abs(line) == pytest.approx(kept, abs=1e-9)
        assert pairs == pytest.approx(drafted * kept / abs(drafted.sum()), abs=1e-12)


def test_sewn_drift_sees_what_the_ease_hides(squares):
    """The first side's lower half stretched by 1 mm and its upper half shrunk by 1 mm:
    the seam's ease is unchanged, but a notch at its middle slid 1 mm from its partner."""
    g = squares
    uv = g.uv.copy()
    side = np.flatnonzero((g.piece_of_vertex == 0) & (g.uv[:, 0] > 99.0))
    y = g.uv[side, 1]
    uv[side, 1] = np.where(y <= 50.0, y * 51.0 / 50.0, 51.0 + (y - 50.0) * 49.0 / 50.0)
    (seam,) = seam_ease_changes(g, uv)
    assert seam["ease_change_mm"] == pytest.approx(0.0, abs=1e-9)
    assert seam["sewn_drift_mm"] == pytest.approx(1.0, abs=1e-9)
    assert sewn_drift(g, g.uv + [5.0, 2.0]) == pytest.approx([0.0], abs=1e-12)
