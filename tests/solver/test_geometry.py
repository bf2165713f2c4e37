"""solver.geometry and solver.garment.mesh: cases checked by hand, and invariants."""

from __future__ import annotations

import numpy as np

from solver.garment.mesh import boundary_half_edges, connected_components, loop_edge_keys
from solver.geometry import (
    closest_on_polygon,
    polygon_area,
    resample_closed,
    resample_polyline,
    rotate,
    rotate_back,
    rotation_affine,
    rotation_matrices,
    rotation_matrix,
    signed_areas,
)

SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])  # counter-clockwise


def test_a_quarter_turn_takes_x_to_y_and_every_form_agrees():
    np.testing.assert_allclose(rotation_matrix(np.pi / 2) @ [1.0, 0.0], [0.0, 1.0], atol=1e-15)
    np.testing.assert_allclose(rotation_affine(90.0), [[0, -1, 0], [1, 0, 0]], atol=1e-15)
    angles = np.random.default_rng(0).uniform(-7, 7, (5, 3))
    x = np.random.default_rng(1).normal(size=(5, 3, 2))
    r = rotation_matrices(angles)
    assert r.shape == (5, 3, 2, 2)
    np.testing.assert_allclose(r @ np.swapaxes(r, -1, -2), np.broadcast_to(np.eye(2), r.shape),
                               atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(r), 1.0)
    np.testing.assert_allclose(rotate(angles, x), np.einsum("...ij,...j->...i", r, x),
                               atol=1e-14)
    np.testing.assert_allclose(rotate_back(angles, rotate(angles, x)), x, atol=1e-14)


def test_areas_are_positive_counter_clockwise_and_flip_with_the_orientation():
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    np.testing.assert_allclose(signed_areas(SQUARE, faces), [0.5, 0.5])
    np.testing.assert_allclose(signed_areas(SQUARE, faces[:, [0, 2, 1]]), [-0.5, -0.5])
    assert polygon_area(SQUARE) == 1.0
    assert polygon_area(SQUARE[::-1]) == -1.0


def test_resampling_keeps_the_ends_and_spaces_points_equally():
    line = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 1.0]])  # 4 mm long
    out = resample_polyline(line, 8)
    assert len(out) == 9
    np.testing.assert_array_equal(out[[0, -1]], line[[0, -1]])
    np.testing.assert_allclose(np.linalg.norm(np.diff(out, axis=0), axis=1), 0.5)
    ring = resample_closed(SQUARE, 8)
    np.testing.assert_allclose(ring[:3], [[0, 0], [0.5, 0], [1, 0]])
    closed = np.vstack([ring, ring[:1]])
    np.testing.assert_allclose(np.linalg.norm(np.diff(closed, axis=0), axis=1), 0.5)


def test_the_closest_point_of_a_polygon_is_the_foot_on_its_nearest_edge():
    points = np.array([[0.5, -2.0], [3.0, 0.5], [2.0, 2.0], [0.2, 0.4]])
    expect = [[0.5, 0.0], [1.0, 0.5], [1.0, 1.0], [0.0, 0.4]]
    np.testing.assert_allclose(closest_on_polygon(points, SQUARE), expect)
    many = np.random.default_rng(2).normal(size=(300, 2)) * 3
    np.testing.assert_array_equal(closest_on_polygon(many, SQUARE, chunk=7),
                                  closest_on_polygon(many, SQUARE))


def test_mesh_topology_of_two_squares():
    faces = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    he = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    count, label = connected_components(8, he)
    assert count == 2 and label.tolist() == [0, 0, 0, 0, 1, 1, 1, 1]
    assert sorted(map(tuple, boundary_half_edges(he, 8)[:4].tolist())) == [
        (0, 1), (1, 2), (2, 3), (3, 0)]
    assert loop_edge_keys([np.array([0, 1, 2, 3])], 8).tolist() == [1, 10, 19, 24]
