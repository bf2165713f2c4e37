"""Every term of Eq. (10) against central finite differences, on a real garment patch."""

from __future__ import annotations

import numpy as np
import pytest

from solver.garment import load_garment
from solver.reshape.energy import (
    barrier_energy,
    conformal_energy,
    conformal_matrix,
    dirichlet_laplacian,
    length_penalty,
    max_flip_free_step,
    prox_energy,
    signed_areas,
    stiffened_conformal_matrix,
    twin_lengths,
)


@pytest.fixture(scope="module")
def pants(data_dir_module):
    return load_garment(data_dir_module / "garments" / "berkeley" / "pants-coarse.obj", units="m")


@pytest.fixture(scope="module")
def data_dir_module():
    from pathlib import Path

    return Path(__file__).resolve().parents[1] / "data"


def _fd_check(fun, uv, rng, n_dirs=6, h=1e-4):
    """Directional derivatives of fun against its analytic gradient."""
    e0, g = fun(uv)
    assert np.isfinite(e0)
    for _ in range(n_dirs):
        d = rng.normal(size=uv.shape)
        num = (fun(uv + h * d)[0] - fun(uv - h * d)[0]) / (2 * h)
        ana = float(np.sum(g * d))
        assert num == pytest.approx(ana, rel=1e-5, abs=1e-7 * (1 + abs(e0)))


def _perturbed(g, rng, scale=2.0):
    return g.uv + rng.normal(scale=scale, size=g.uv.shape)


def test_prox_gradient(pants):
    rng = np.random.default_rng(1)
    v = pants.seam_edges[:, :2].ravel()
    target = pants.uv[v] + rng.normal(size=(len(v), 2))
    w = rng.uniform(0.5, 2, len(v))
    _fd_check(lambda u: prox_energy(u, v, target, w), _perturbed(pants, rng), rng)


def test_stiffened_conformal_energy_resists_scaling_but_not_rigid_motion(pants):
    rng = np.random.default_rng(9)
    k = stiffened_conformal_matrix(pants.uv, pants.faces, 0.05)
    _fd_check(lambda u: conformal_energy(u, k, pants.uv), _perturbed(pants, rng), rng)
    c, s = np.cos(0.4), np.sin(0.4)
    turned = pants.uv @ np.array([[c, -s], [s, c]]).T + [5.0, -3.0]
    grown = 1.1 * pants.uv
    q = conformal_matrix(pants.uv, pants.faces)
    assert conformal_energy(pants.uv, k, pants.uv)[0] == 0.0
    assert conformal_energy(grown, q)[0] == pytest.approx(0, abs=1e-6)  # LSCM lets it grow
    # the Dirichlet part is 0.05 x 1/2 sum A |grad d|^2 = 0.05 x 0.1^2 x total area
    area = signed_areas(pants.uv, pants.faces).sum()
    assert conformal_energy(grown, k, pants.uv)[0] == pytest.approx(0.05 * 0.01 * area,
                                                                    rel=1e-9)
    # a rigid turn costs the Dirichlet part 0.05 x |R - I|^2 / 2 x area, nothing more
    rigid = 0.05 * 0.5 * 2 * ((c - 1) ** 2 + s**2) * area
    assert conformal_energy(turned, k, pants.uv)[0] == pytest.approx(rigid, rel=1e-9)


def test_conformal_gradient_and_similarity_invariance(pants):
    rng = np.random.default_rng(2)
    q = conformal_matrix(pants.uv, pants.faces)
    _fd_check(lambda u: conformal_energy(u, q), _perturbed(pants, rng), rng)
    # zero for the input and for any similarity of it (per-face conformal)
    c, s = np.cos(0.7) * 1.3, np.sin(0.7) * 1.3
    moved = pants.uv @ np.array([[c, -s], [s, c]]).T + [5.0, -3.0]
    assert conformal_energy(pants.uv, q)[0] == pytest.approx(0, abs=1e-6)
    assert conformal_energy(moved, q)[0] == pytest.approx(0, abs=1e-6)
    # a shear is not conformal
    sheared = pants.uv @ np.array([[1.0, 0.2], [0.0, 1.0]]).T
    assert conformal_energy(sheared, q)[0] > 1.0
    # E_conf = E_D - A: the Dirichlet Laplacian bounds it from above
    lap = dirichlet_laplacian(pants.uv, pants.faces)
    e_d = 0.5 * float(np.sum(sheared * (lap @ sheared)))
    area = signed_areas(sheared, pants.faces).sum()
    assert conformal_energy(sheared, q)[0] == pytest.approx(e_d - area, rel=1e-9)


def test_barrier_gradient_and_flip_is_infinite(pants):
    rng = np.random.default_rng(3)
    area0 = signed_areas(pants.uv, pants.faces)
    thr = 0.9 * area0  # many faces active after a perturbation
    uv = _perturbed(pants, rng, scale=1.0)
    e, _ = barrier_energy(uv, pants.faces, thr)
    assert 0 < e < np.inf
    _fd_check(lambda u: barrier_energy(u, pants.faces, thr), uv, rng, h=1e-6)
    flipped = pants.uv.copy()
    f = pants.faces[0]
    flipped[f[0]] = flipped[f[1]] + (flipped[f[1]] - flipped[f[0]])  # fold one corner over
    flipped[f[2]] = pants.uv[f[2]]
    assert barrier_energy(flipped, pants.faces, thr)[0] == np.inf


def test_length_penalty_gradient(pants):
    rng = np.random.default_rng(4)
    e = pants.seam_edges
    l0 = np.linalg.norm(pants.uv[e[:, 1]] - pants.uv[e[:, 0]], axis=1)
    w = rng.uniform(0.5, 2, len(e))
    _fd_check(lambda u: length_penalty(u, e, w, l0, 0.25), _perturbed(pants, rng), rng)
    ease = rng.uniform(-1.0, 1.0, len(e))  # twins that keep a length difference
    _fd_check(lambda u: length_penalty(u, e, w, l0, 0.25, ease), _perturbed(pants, rng), rng)


def test_length_penalty_with_ease_is_zero_on_the_input_and_charges_a_changed_ease(pants):
    e = pants.seam_edges
    w, l0 = np.ones(len(e)), np.ones(len(e))
    ease = twin_lengths(pants.uv, e)
    assert np.abs(ease).max() > 1.0  # the coarse pants' twins differ in length
    assert length_penalty(pants.uv, e, w, l0, 1.0, ease)[0] == pytest.approx(0.0, abs=1e-18)
    # both sides scaled by 5 %: the squared form (c_e) keeps the ratio, the ease form
    # charges the 5 % change of every difference: 2 * 0.05 * ease per pair
    scaled = pants.uv * 1.05
    expected = 0.5 * np.sum((2.0 * 0.05 * ease) ** 2)
    assert length_penalty(scaled, e, w, l0, 1.0, ease)[0] == pytest.approx(expected, rel=1e-9)


def test_max_flip_free_step_is_first_zero_area(pants):
    rng = np.random.default_rng(5)
    d = rng.normal(scale=50.0, size=pants.uv.shape)
    t = max_flip_free_step(pants.uv, pants.faces, d)
    assert 0 < t < np.inf
    assert signed_areas(pants.uv + 0.999 * t * d, pants.faces).min() > 0
    assert signed_areas(pants.uv + 1.001 * t * d, pants.faces).min() < 0


def test_outline_bending_charges_notches_not_smooth_moves(pants):
    from solver.reshape.energy import outline_bending_matrix

    loops = [lp for i in range(pants.n_pieces) for lp in pants.piece_loops(i)]
    k = outline_bending_matrix(pants.uv, loops, smooth_mm=6.0, unit_mm=10.0)
    rng = np.random.default_rng(4)
    _fd_check(lambda u: conformal_energy(u, k, pants.uv), _perturbed(pants, rng), rng)
    # moving a piece bends nothing (turning it costs a little at its corners, where the
    # outline's own second difference is not zero)
    assert conformal_energy(pants.uv + [4.0, 1.0], k, pants.uv)[0] == pytest.approx(0, abs=1e-9)
    # one outline vertex pushed out 2 mm (a notch) costs far more than the same 2 mm
    # spread smoothly along the loop
    loop = loops[0]
    notch = pants.uv.copy()
    notch[loop[5]] += [2.0, 0.0]
    smooth = pants.uv.copy()
    steps = np.abs(np.arange(len(loop)) - 5)
    steps = np.minimum(steps, len(loop) - steps)  # around the closed loop
    smooth[loop] += 2.0 * np.exp(-0.5 * (steps / 6.0) ** 2)[:, None] * [1.0, 0.0]
    assert conformal_energy(notch, k, pants.uv)[0] > 10 * conformal_energy(smooth, k, pants.uv)[0]
    # the scale may differ per vertex: a longer one there makes the same notch dearer
    scale = np.full(pants.n_vertices, 6.0)
    same = outline_bending_matrix(pants.uv, loops, smooth_mm=scale, unit_mm=10.0)
    assert abs(same - k).max() == 0
    scale[loop[4:7]] = 12.0
    corner = outline_bending_matrix(pants.uv, loops, smooth_mm=scale, unit_mm=10.0)
    dear = conformal_energy(notch, corner, pants.uv)[0]
    # the coarse pants' outline edges (35-70 mm) are longer than either scale, so each
    # vertex is weighed as if its edges were the scale long: kappa / scale^3 = scale / unit,
    # twice as dear at twice the scale (on a fine outline it would be 2^4 times)
    assert dear == pytest.approx(2.0 * conformal_energy(notch, k, pants.uv)[0])
