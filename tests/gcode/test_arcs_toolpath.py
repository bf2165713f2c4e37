"""Arc fitting within the chordal tolerance, and travel-limiting order of pieces."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree
from shapely.geometry import LineString, Point

from gcode.arcs import CCW, CW, LINE, FittedPath, fit_arcs, path_length, sample_path
from gcode.toolpath import order_pieces, two_opt


def _dense(poly: np.ndarray, step: float) -> np.ndarray:
    seg = np.hypot(*np.diff(poly, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    t = np.linspace(0.0, s[-1], int(s[-1] / step) + 2)
    return np.c_[np.interp(t, s, poly[:, 0]), np.interp(t, s, poly[:, 1])]


def _max_dev(fitted: FittedPath, poly: np.ndarray, step: float = 0.005) -> float:
    """Two-sided distance between the fitted path and the polyline, both sampled densely
    (KD-trees; exact up to half the sampling step)."""
    a = _dense(sample_path(fitted, step), step)
    b = _dense(poly, step)
    return max(cKDTree(b).query(a)[0].max(), cKDTree(a).query(b)[0].max()) - step / 2


def test_circle_becomes_two_arcs_with_equal_radii():
    ring = np.asarray(Point(300, 200).buffer(50, quad_segs=128).exterior.coords)
    area2 = np.sum(ring[:-1, 0] * ring[1:, 1] - ring[1:, 0] * ring[:-1, 1])
    for r, kind in ((ring, CCW if area2 > 0 else CW), (ring[::-1], CW if area2 > 0 else CCW)):
        f = fit_arcs(r, 0.05)
        assert len(f) <= 4 and set(f.kind) <= {kind, LINE} and (f.kind == kind).sum() >= 2
        assert (f.kind == LINE).sum() <= 1
    starts = np.vstack([f.start, f.end[:-1]])[f.kind != LINE]
    r0 = np.hypot(*(starts - f.center[f.kind != LINE]).T)
    r1 = np.hypot(*(f.end[f.kind != LINE] - f.center[f.kind != LINE]).T)
    assert np.allclose(r0, r1, atol=1e-9)  # GRBL error:33 needs them equal
    assert np.allclose(r0, 50, atol=0.05)
    assert path_length(f) == pytest.approx(LineString(ring).length, rel=1e-3)


def test_square_stays_lines_and_collinear_points_merge():
    sq = np.array([[0, 0], [10, 0], [10, 10], [0, 10], [0, 0]], float)
    dense = np.vstack([np.linspace(sq[i], sq[i + 1], 25, endpoint=False) for i in range(4)]
                      + [sq[:1]])
    f = fit_arcs(dense, 0.01)
    assert list(f.kind) == [LINE] * 4
    assert np.allclose(f.end, sq[1:])


def test_noisy_wave_within_tolerance():
    rng = np.random.default_rng(0)
    x = np.linspace(0, 150, 1500)
    p = np.c_[x, 20 * np.sin(x / 30) + 0.01 * rng.standard_normal(len(x))]
    for tol in (0.02, 0.05, 0.2):
        f = fit_arcs(p, tol)
        assert _max_dev(f, p) <= tol + 1e-3
        if tol > 0.04:  # above the noise (max ~0.04 mm) the curve's own shape shows
            assert len(f) < len(p) / 20
            assert (f.kind != LINE).sum() >= len(f) // 2  # mostly arcs
    # looser tolerance, fewer primitives
    assert len(fit_arcs(p, 0.2)) < len(fit_arcs(p, 0.02))


def test_s_curve_turns_both_ways():
    t = np.linspace(0, np.pi, 200)
    a = np.c_[np.cos(np.pi - t) * 20 + 20, np.sin(t) * 20]  # upper half circle, CW
    b = np.c_[60 + np.cos(np.pi - t) * 20, -np.sin(t) * 20]  # lower half circle, CCW
    p = np.vstack([a, b[1:]])
    f = fit_arcs(p, 0.02)
    assert {CW, CCW} <= set(f.kind)
    assert _max_dev(f, p) <= 0.021


def test_berkeley_outlines_fit_within_tolerance(data_dir):
    from solver.garment import load_garment

    g = load_garment(data_dir / "garments" / "berkeley" / "shorts-iso.obj", units="m")
    for i in range(g.n_pieces):
        ring = g.piece_outline(i)
        closed = np.vstack([ring, ring[:1]])
        f = fit_arcs(closed, 0.1)
        assert _max_dev(f, closed, step=0.01) <= 0.1 + 1e-3
        assert len(f) < len(ring)
        assert np.allclose(f.end[-1], closed[-1])


def _tour_length(order, pts, start):
    p = np.vstack([start, pts[order]])
    return np.hypot(*np.diff(p, axis=0).T).sum()


def test_two_opt_untangles_a_line():
    rng = np.random.default_rng(1)
    xs = rng.permutation(20).astype(float)
    pts = np.c_[xs, np.zeros(20)]
    d = np.hypot(pts[:, None, 0] - pts[None, :, 0], pts[:, None, 1] - pts[None, :, 1])
    d0 = np.hypot(*(pts - [-1.0, 0.0]).T)
    order = two_opt(np.arange(20), d, d0)
    assert _tour_length(order, pts, [-1.0, 0.0]) == pytest.approx(20.0)


def test_piece_order_beats_the_layout_order():
    rng = np.random.default_rng(2)
    centres = rng.uniform([0, 0], [1500, 900], size=(30, 2))
    samples = [c + 20 * np.c_[np.cos(a), np.sin(a)]
               for c, a in zip(centres, [np.linspace(0, 6, 12)] * 30, strict=True)]
    start = np.zeros(2)
    order = order_pieces(samples, start)
    assert sorted(order) == list(range(30))
    given = _tour_length(np.arange(30), centres, start)
    ours = _tour_length(order, centres, start)
    assert ours < 0.5 * given
    # and no worse than plain nearest neighbour
    left, pos, nn = set(range(30)), start, []
    while left:
        k = min(left, key=lambda j: np.hypot(*(centres[j] - pos)))
        nn.append(k)
        left.remove(k)
        pos = centres[k]
    assert ours <= _tour_length(np.array(nn), centres, start) + 1e-6
