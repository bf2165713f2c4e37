"""Property tests of the 17 plane groups and the closest-equivalent-point query."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from solver.wallpaper import GROUP_NAMES, GROUPS, Wallpaper, gauss_reduce

# The list: equivalent points per primitive cell, in ITA order.
EXPECTED_COUNTS = dict(zip(GROUP_NAMES, (1, 2, 2, 2, 2, 4, 4, 4, 4, 4, 8, 8, 3, 6, 6, 6, 12)))
EXPECTED_ORDER = dict(zip(GROUP_NAMES, (1, 2, 1, 1, 1, 2, 2, 2, 2, 4, 4, 4, 3, 3, 3, 6, 6)))


def rot(a: float) -> np.ndarray:
    return np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])


def random_lattice(group: str, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A random valid (w1, w2) for the group's lattice type, randomly turned."""
    lattice = GROUPS[group].lattice
    a = rng.uniform(20, 80)
    b = rng.uniform(20, 80)
    angle = {
        "oblique": rng.uniform(50, 130),
        "rectangular": 90.0,
        "rhombic": rng.uniform(40, 140),
        "square": 90.0,
        "hexagonal": 120.0,
    }[lattice]
    if lattice in ("rhombic", "square", "hexagonal"):
        b = a
    r = rot(rng.uniform(0, 2 * math.pi))
    w1 = r @ np.array([a, 0.0])
    w2 = r @ (b * np.array([math.cos(math.radians(angle)), math.sin(math.radians(angle))]))
    return w1, w2


def make(group: str, seed: int, non_reduced: bool = False) -> Wallpaper:
    rng = np.random.default_rng(seed)
    w1, w2 = random_lattice(group, rng)
    if non_reduced:
        w2 = w2 + 3 * w1
        w1 = w1 - 2 * w2
    return Wallpaper(group, w1, w2, rng.uniform(-50, 50, 2))


def brute_force_mismatch(wp: Wallpaper, p: np.ndarray, q: np.ndarray, span: int) -> np.ndarray:
    """Closest equivalent by enumerating every op and a wide block of translations."""
    k = np.arange(-span, span + 1)
    shifts = np.stack(np.meshgrid(k, k), -1).reshape(-1, 2) @ wp.basis.T
    eq = wp.equivalent_points(q)  # (N, n, 2)
    # Round in the given basis only (naive), then search the whole block around it.
    eq = eq - np.round(wp.to_fractional(eq) - wp.to_fractional(p)[:, None]) @ wp.basis.T
    cand = eq[:, :, None, :] + shifts[None, None] - p[:, None, None, :]
    cand = cand.reshape(len(p), -1, 2)
    best = np.argmin(np.einsum("pki,pki->pk", cand, cand), axis=1)
    return cand[np.arange(len(p)), best]


def test_table_matches_international_tables_counts_and_orders():
    assert tuple(GROUPS) == GROUP_NAMES
    for name, info in GROUPS.items():
        assert info.n_equivalent == EXPECTED_COUNTS[name], name
        assert info.rotation_order == EXPECTED_ORDER[name], name
        np.testing.assert_allclose(info.ops[0], np.column_stack([np.eye(2), [0, 0]]))
    mirrors = {n for n, i in GROUPS.items() if i.has_mirror}
    glides = {n for n, i in GROUPS.items() if i.has_glide}
    assert mirrors == {"pm", "cm", "pmm", "pmg", "cmm", "p4m", "p4g", "p3m1", "p31m", "p6m"}
    assert glides == {"pg", "cm", "pmg", "pgg", "cmm", "p4m", "p4g", "p3m1", "p31m", "p6m"}


@pytest.mark.parametrize("group", GROUP_NAMES)
def test_operations_are_isometries_forming_a_group(group):
    wp = make(group, 1)
    ops = wp.cartesian_ops()
    for h in ops:
        np.testing.assert_allclose(h[:2, :2].T @ h[:2, :2], np.eye(2), atol=1e-12)
    # Closure: every product of two ops is an op up to a lattice translation.
    frac = GROUPS[group].ops
    for a in frac:
        for b in frac:
            m = a[:, :2] @ b[:, :2]
            t = a[:, :2] @ b[:, 2] + a[:, 2]
            hits = [
                np.allclose(m, c[:, :2]) and np.allclose((t - c[:, 2]) - np.round(t - c[:, 2]), 0)
                for c in frac
            ]
            assert sum(hits) == 1


@pytest.mark.parametrize("group", GROUP_NAMES)
@pytest.mark.parametrize("non_reduced", [False, True])
def test_each_operation_maps_equivalent_points_onto_themselves(group, non_reduced):
    if non_reduced and GROUPS[group].lattice not in ("oblique", "hexagonal", "square"):
        pytest.skip("rectangular and rhombic groups fix their axes by the given basis")
    wp = make(group, 2, non_reduced)
    p = np.random.default_rng(3).uniform(-100, 100, (20, 2))
    eq = wp.equivalent_points(p)  # (N, n, 2)
    for h in wp.cartesian_ops():
        mapped = eq @ h[:2, :2].T + h[:2, 2]
        # Every mapped point coincides, modulo the lattice, with one of the set.
        d = wp.lattice_residual(mapped[:, :, None, :] - eq[:, None, :, :])
        dist = np.hypot(d[..., 0], d[..., 1])
        assert np.all(dist.min(axis=2) < 1e-9)
        assert np.all((dist < 1e-9).sum(axis=2) == 1)  # a permutation of the set


@pytest.mark.parametrize("group", GROUP_NAMES)
@pytest.mark.parametrize("non_reduced", [False, True])
def test_mismatch_properties_and_brute_force(group, non_reduced):
    if non_reduced and GROUPS[group].lattice not in ("oblique", "hexagonal", "square"):
        pytest.skip("rectangular and rhombic groups fix their axes by the given basis")
    wp = make(group, 4, non_reduced)
    rng = np.random.default_rng(5)
    p = rng.uniform(-150, 150, (200, 2))
    q = rng.uniform(-150, 150, (200, 2))
    d_pq = wp.mismatch(p, q)
    d_qp = wp.mismatch(q, p)
    np.testing.assert_allclose(np.hypot(*d_pq.T), np.hypot(*d_qp.T), atol=1e-9)
    # The vector really ends on an equivalent point of q.
    end = p + d_pq
    np.testing.assert_allclose(wp.mismatch(end, q), 0.0, atol=1e-9)
    # Invariance under the group applied to q, plus an arbitrary lattice translation.
    for h in wp.cartesian_ops():
        q2 = q @ h[:2, :2].T + h[:2, 2] + 7 * wp.w1 - 4 * wp.w2
        np.testing.assert_allclose(
            np.hypot(*wp.mismatch(p, q2).T), np.hypot(*d_pq.T), atol=1e-9
        )
    # Brute force in the given (possibly non-reduced) basis over a wide block.
    span = 14 if non_reduced else 6
    bf = brute_force_mismatch(wp, p, q, span)
    np.testing.assert_allclose(np.hypot(*d_pq.T), np.hypot(*bf.T), atol=1e-9)


@pytest.mark.parametrize("group", GROUP_NAMES)
def test_batched_closest_broadcasts_and_names_the_operation(group):
    """`closest` on (B, n, 2) batches, with far points and a turned lattice: the distance
    equals brute force and the returned operation plus a lattice vector gives p + d."""
    rng = np.random.default_rng(7)
    wp = make(group, 4, False).moved(0.3, (5.0, -2.0))
    p = rng.normal(0, 300, (3, 200, 2))
    q = rng.normal(0, 300, (200, 2))  # broadcast against every row of p
    d, op = wp.closest(p, q)
    assert d.shape == (3, 200, 2) and op.shape == (3, 200)
    bf = brute_force_mismatch(wp, p.reshape(-1, 2), np.tile(q, (3, 1)), 6)
    np.testing.assert_allclose(np.hypot(*d.reshape(-1, 2).T), np.hypot(*bf.T), atol=1e-9)
    g = wp.cartesian_ops()[op]
    image = np.einsum("bnij,nj->bni", g[..., :2, :2], q) + g[..., :2, 2]
    res = wp.to_fractional(p + d) - wp.to_fractional(image)
    np.testing.assert_allclose(res, np.round(res), atol=1e-9)
    assert op.max() < wp.n_equivalent and (wp.n_equivalent == 1 or op.max() > 0)


@pytest.mark.parametrize("group", GROUP_NAMES)
def test_mismatch_is_zero_exactly_for_equivalent_points(group):
    wp = make(group, 6)
    rng = np.random.default_rng(7)
    p = rng.uniform(-100, 100, (50, 2))
    eq = wp.equivalent_points(p)
    k = rng.integers(-3, 4, (50, 2))
    for j in range(wp.n_equivalent):
        q = eq[:, j] + k @ wp.basis.T
        np.testing.assert_allclose(wp.mismatch(p, q), 0.0, atol=1e-9)
    # Points nudged off every equivalent position are not equivalent.
    cell = math.sqrt(abs(np.linalg.det(wp.basis)))
    q = eq[:, 0] + rng.normal(size=(50, 2)) * 1e-3 * cell
    assert np.all(wp.mismatch_distance(p, q) > 1e-7)


def test_mismatch_across_cell_boundaries_square():
    wp = Wallpaper("p1", (10, 0), (0, 10))
    p = np.array([[9.99, 5.0], [0.01, 0.01]])
    q = np.array([[10.01, 5.0], [19.99, 29.99]])
    np.testing.assert_allclose(wp.mismatch(p, q), [[0.02, 0.0], [-0.02, -0.02]], atol=1e-12)


def test_mirror_of_pm_along_w2():
    wp = Wallpaper("pm", (10, 0), (0, 20), origin=(1, 0))
    # The mirror line is x = 1 (through the origin, along w2): (1+a, y) ~ (1-a, y).
    assert wp.mismatch_distance([[1.3, 4.0]], [[0.7, 4.0]])[0] < 1e-12
    assert wp.mismatch_distance([[1.3, 4.0]], [[1.3, -4.0]])[0] > 1.0


@pytest.mark.parametrize(
    ("group", "w1", "w2", "fault"),
    [
        ("p4", (10, 0), (0, 11), "differ"),
        ("p4m", (10, 0), (3, 10), "angle"),
        ("pmm", (10, 0), (3, 10), "angle"),
        ("p6", (10, 0), (0, 10), "120"),
        ("cm", (10, 0), (3, 20), "differ"),
        ("p1", (10, 0), (20, 0), "parallel"),
    ],
)
def test_invalid_lattices_are_rejected_with_a_reason(group, w1, w2, fault):
    with pytest.raises(ValueError, match=fault):
        Wallpaper(group, w1, w2)


def test_unknown_group_and_nan():
    with pytest.raises(ValueError, match="unknown wallpaper group"):
        Wallpaper("p5", (1, 0), (0, 1))
    with pytest.raises(ValueError, match="finite"):
        Wallpaper("p1", (np.nan, 0), (0, 1))


def test_non_reduced_hexagonal_basis_is_recognised():
    a = np.array([30.0, 0.0])
    b = 30.0 * np.array([-0.5, math.sqrt(3) / 2])
    wp = Wallpaper("p6m", a, b + 4 * a)
    cell_area = abs(np.linalg.det(np.column_stack([a, b])))
    assert abs(np.linalg.det(wp.basis)) == pytest.approx(cell_area)
    assert np.hypot(*wp.w1) == pytest.approx(30.0)
    assert math.degrees(math.acos(wp.w1 @ wp.w2 / 900.0)) == pytest.approx(120.0)


def test_gauss_reduce_is_unimodular_and_short():
    u1, u2, u = gauss_reduce(np.array([1.0, 0.2]), np.array([7.1, 1.5]))
    assert abs(round(np.linalg.det(u))) == 1
    assert np.hypot(*u1) <= np.hypot(*u2)
    assert abs(u1 @ u2) <= u1 @ u1 / 2 + 1e-12


def test_snapped_forces_a_measured_lattice_onto_its_group():
    wp = Wallpaper.snapped("p4m", (40.1, 0.2), (-0.1, 39.8))
    assert np.hypot(*wp.w1) == pytest.approx(np.hypot(*wp.w2))
    assert wp.w1 @ wp.w2 == pytest.approx(0.0, abs=1e-9)
    hexa = Wallpaper.snapped("p3", (30.0, 0.1), (-15.2, 26.0))
    cos = hexa.w1 @ hexa.w2 / (np.hypot(*hexa.w1) * np.hypot(*hexa.w2))
    assert cos == pytest.approx(-0.5)


def test_fabric_json_round_trip_and_units(tmp_path):
    path = tmp_path / "fabric.json"
    path.write_text(json.dumps({"group": "p4m", "w1": [4, 0], "w2": [0, 4],
                                "origin": [1, 1], "units": "cm"}))
    wp = Wallpaper.load(path)
    np.testing.assert_allclose(wp.w1, [40, 0])
    np.testing.assert_allclose(wp.origin, [10, 10])
    again = Wallpaper.from_dict(wp.to_dict())
    np.testing.assert_allclose(again.basis, wp.basis)
    path.write_text('{"group": "p4m", "w1": [4, 0]}')
    with pytest.raises(ValueError, match="lacks w2"):
        Wallpaper.load(path)


def test_moved_print_keeps_mismatch_of_moved_points():
    wp = make("p4g", 8)
    moved = wp.moved(0.7, (12.0, -3.0))
    r = rot(0.7)
    rng = np.random.default_rng(9)
    p, q = rng.uniform(-80, 80, (2, 30, 2))
    d0 = wp.mismatch_distance(p, q)
    d1 = moved.mismatch_distance(p @ r.T + (12, -3), q @ r.T + (12, -3))
    np.testing.assert_allclose(d0, d1, atol=1e-9)


@pytest.mark.parametrize("group", GROUP_NAMES)
def test_closest_symmetry_rebuilds_the_mismatch_and_covering_radius_bounds_it(group):
    wp = make(group, 6, non_reduced=GROUPS[group].lattice in ("oblique", "square"))
    rng = np.random.default_rng(7)
    p = rng.uniform(-150, 150, (2000, 2))
    q = rng.uniform(-150, 150, (2000, 2))
    op, lattice = wp.closest_symmetry(p, q)
    h = wp.cartesian_ops()[op]
    image = np.einsum("nij,nj->ni", h[:, :2, :2], q) + h[:, :2, 2] + lattice
    np.testing.assert_allclose(image - p, wp.mismatch(p, q), atol=1e-9)
    # the lattice vector is whole: integer coordinates in the given basis
    frac = lattice @ np.linalg.inv(wp.basis).T
    np.testing.assert_allclose(frac, np.round(frac), atol=1e-9)
    # no mismatch exceeds the covering radius; with p1 (one point per cell) the worst
    # random pair comes close to it
    dist = np.hypot(*wp.mismatch(p, q).T)
    assert dist.max() <= wp.covering_radius + 1e-9
    if group == "p1":
        assert dist.max() > 0.9 * wp.covering_radius


def test_covering_radius_of_square_and_hexagonal_lattices():
    assert Wallpaper("p4", (50, 0), (0, 50)).covering_radius == pytest.approx(25 * math.sqrt(2))
    hexagonal = Wallpaper("p6", (50, 0), (-25, 25 * math.sqrt(3)))
    assert hexagonal.covering_radius == pytest.approx(50 / math.sqrt(3))
