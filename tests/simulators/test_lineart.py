"""simulators.lineart: the exact symmetry of line drawings, and near-symmetric prints."""

from __future__ import annotations

import numpy as np
import pytest

from simulators.fabric import lattice_for
from simulators.lineart import layered_print, subgroup_ops, symmetry_of, tile
from solver.wallpaper import GROUP_NAMES, GROUPS, gauss_reduce


def _drawing(group: str, seed: int, ops: np.ndarray | None = None):
    rng = np.random.default_rng(seed)
    w1, w2 = lattice_for(group, 10.0, rotation=rng.uniform(0, 360), rng=rng)
    basis = np.column_stack([w1, w2])
    ops = GROUPS[group].ops if ops is None else ops
    lines = [rng.uniform(0, 1, (3, 2)) for _ in range(2)]
    orbit = [(p @ op[:, :2].T + op[:, 2]) @ basis.T for p in lines for op in ops]
    return tile(orbit, basis, (-60, -60, 60, 60)), basis


@pytest.mark.parametrize("group", GROUP_NAMES)
def test_symmetry_of_an_orbit_is_its_group_and_lattice(group):
    drawing, basis = _drawing(group, seed=GROUP_NAMES.index(group))
    found, lattice = symmetry_of(drawing)
    assert found == group
    u1, u2, _ = gauss_reduce(basis[:, 0], basis[:, 1])
    assert abs(np.linalg.det(lattice)) == pytest.approx(abs(u1[0] * u2[1] - u1[1] * u2[0]))
    # Every found lattice vector is a lattice vector of the print.
    frac = np.linalg.solve(basis, lattice)
    assert np.abs(frac - np.rint(frac)).max() < 1e-6


def test_labels_tell_strokes_apart():
    """Two strokes that are each other's mirror images, in different colours, are no
    mirror of the print."""
    drawing, _ = _drawing("pm", seed=3)
    assert symmetry_of(drawing)[0] == "pm"
    n = len(drawing)  # orbit order: line 0 (identity, mirror), line 1 (identity, mirror)
    assert symmetry_of(drawing, labels=[k % 2 for k in range(n)])[0] == "p1"


@pytest.mark.parametrize("group", ["p4m", "p6m", "cmm", "pgg"])
def test_subgroup_ops_are_closed_and_inside_the_group(group):
    ops = GROUPS[group].ops
    for seed in range(6):
        sub = subgroup_ops(group, np.random.default_rng(seed))
        assert np.allclose(sub[0][:, :2], np.eye(2))
        for a in sub:
            assert any(np.allclose(a[:, :2], b[:, :2]) and np.allclose(
                (a[:, 2] - b[:, 2]) % 1, 0, atol=1e-9) for b in ops)
            for b in sub:
                lin = a[:, :2] @ b[:, :2]
                t = (a[:, :2] @ b[:, 2] + a[:, 2]) % 1
                assert any(np.allclose(lin, c[:, :2]) and np.allclose(
                    (t - c[:, 2] + 0.5) % 1, 0.5, atol=1e-9) for c in sub)


def test_layered_print_truth_is_the_faint_layers_group():
    img, truth, basis = layered_print("p2", 40, (200, 150), seed=1,
                                      faint_ops=GROUPS["p1"].ops)
    assert img.shape == (150, 200, 3) and img.dtype == np.uint8
    assert truth == "p1"
    img, truth, _ = layered_print("p4m", 40, (200, 150), seed=1,
                                  faint_ops=GROUPS["p4m"].ops)
    assert truth == "p4m"
    assert np.ptp(img) > 60  # something is drawn
