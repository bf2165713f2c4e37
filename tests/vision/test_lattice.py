"""Lattice detection on simulator prints, stripes, plain cloth and noise."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from simulators.classics import classic_print
from simulators.fabric import lattice_for, random_print, render_print
from solver.wallpaper import GROUP_NAMES, gauss_reduce
from vision.lattice import detect_lattice


def test_gauss_reduce_gives_shortest_basis_of_same_lattice():
    b1, b2 = np.array([10.0, 1.0]), np.array([37.0, 9.0])  # = 3 b1 + (7, 6)
    r1, r2, _ = gauss_reduce(b1, b2, obtuse=True)
    assert np.hypot(*r1) <= np.hypot(*r2)
    assert r1 @ r2 <= 1e-9
    u = np.linalg.solve(np.column_stack([b1, b2]), np.column_stack([r1, r2]))
    assert np.allclose(u, np.round(u)) and abs(abs(np.linalg.det(u)) - 1) < 1e-9
    assert np.hypot(*r2) <= np.hypot(7, 6) + 1e-9


@pytest.mark.parametrize("group", GROUP_NAMES)
def test_clean_print_lattice_subpixel(make_print, group, vt):
    img, truth = make_print(group, seed=7, period=38.0, shape=(240, 320))
    res = detect_lattice(img, mm_per_px=0.5)
    assert res.kind == "lattice", res.message
    assert vt.lattice_error(res.basis_px, truth.basis) < 1e-3
    assert np.hypot(*res.w1) <= np.hypot(*res.w2) + 1e-9
    assert 0 < res.sigma_w1[0] < 0.01 * np.hypot(*res.w1)


def test_perturbed_prints_lattice_within_half_percent(make_print, vt):
    errs = []
    for i, group in enumerate(GROUP_NAMES):
        rng = np.random.default_rng(100 + i)
        img, truth = make_print(group, seed=100 + i, period=rng.uniform(25, 60),
                                shape=(240, 320), blur=rng.uniform(0, 2.5),
                                noise=rng.uniform(0, 0.04), jpeg=int(rng.uniform(60, 95)),
                                ramp=rng.uniform(0, 0.4))
        res = detect_lattice(img)
        errs.append(vt.lattice_error(res.basis_px, truth.basis) if res.found else np.inf)
    assert max(errs) < 5e-3, errs


def test_mild_perspective_and_fold_keep_the_lattice(make_print, vt):
    for i, group in enumerate(("p1", "pmg", "p4g", "p31m")):
        img, truth = make_print(group, seed=40 + i, period=30.0, shape=(300, 400),
                                persp=0.005, fold=1.0, noise=0.02, blur=1.0)
        res = detect_lattice(img)
        assert res.found, (group, res.message)
        assert vt.lattice_error(res.basis_px, truth.basis) < 0.02


@pytest.mark.parametrize("seed", range(6))
def test_stripes_are_a_frieze_not_a_lattice(make_stripes, seed):
    rng = np.random.default_rng(seed)
    img, period, direction = make_stripes(seed, blur=rng.uniform(0, 2.5),
                                          noise=rng.uniform(0, 0.04), jpeg=70,
                                          ramp=0.3)
    res = detect_lattice(img, mm_per_px=2.0)
    assert res.kind == "stripes", res.message
    assert res.period == pytest.approx(2.0 * period, rel=0.01)
    diff = (res.direction_deg - direction + 90) % 180 - 90
    assert abs(diff) < 1.0


@pytest.mark.parametrize("seed", range(4))
def test_noise_and_plain_cloth_have_no_lattice(seed, vt):
    rng = np.random.default_rng(seed)
    img = vt.perturb(np.full((240, 320), 0.5), rng, blur=0.7 * seed, noise=0.04,
                  jpeg=60 if seed % 2 else None, ramp=0.4)
    res = detect_lattice(img)
    assert res.kind == "plain"
    assert "no periodic print" in res.message


def _fine_stripes(period: float, angle_deg: float, seed: int) -> np.ndarray:
    """Hard stripes a few pixels apart (a rib knit, a pinstripe seen from afar), turned
    off the pixel axes, integrated over the pixels as a sensor does."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:2400, 0:3000].astype(np.float32) / 3
    a = np.deg2rad(angle_deg)
    u = (xx * np.cos(a) + yy * np.sin(a)) / period
    img = cv2.resize((0.5 + 0.4 * (np.mod(u, 1.0) < 0.35)).astype(np.float32), (1000, 800),
                     interpolation=cv2.INTER_AREA)
    return np.clip(img * 255 + rng.normal(0, 3, img.shape), 0, 255).astype(np.uint8)


@pytest.mark.parametrize(("period", "angle"), [(7.5, 2.0), (8.4, 42.6), (6.3, 10.0),
                                               (9.6, 2.0)])
def test_fine_stripes_off_the_axes_are_stripes(period, angle):
    """A ridge a few pixels wide off the pixel axes is sampled between pixels; linear
    interpolation made it ripple along its length as a 2-D print's would, and these
    read as lattices."""
    res = detect_lattice(_fine_stripes(period, angle, seed=1), mm_per_px=1.0)
    assert res.kind == "stripes", res.message
    assert res.period == pytest.approx(period, rel=0.01)


def test_smooth_shading_over_plain_cloth_makes_no_lattice():
    """Uneven dyeing or light, a few blotches across the frame: peaks of its
    autocorrelation at lags the frame shows fewer than three times are chance (10 of
    these 32 frames gave a lattice before a repeat seen so few times had to be strong)."""
    lattices = 0
    for blotch_px in (40.0, 80.0):
        for seed in range(16):
            rng = np.random.default_rng(seed)
            shade = cv2.GaussianBlur(rng.standard_normal((1000, 1000)).astype(np.float32),
                                     (0, 0), blotch_px)
            img = 128 + 10 * shade / shade.std() + rng.normal(0, 3, shade.shape)
            lattices += detect_lattice(np.clip(img, 0, 255).astype(np.uint8),
                                       mm_per_px=0.25).found
    assert lattices <= 1


@pytest.mark.parametrize("group", GROUP_NAMES)
def test_a_strong_print_seen_fewer_than_three_times_across_is_found(group):
    rng = np.random.default_rng(GROUP_NAMES.index(group))
    w1, w2 = lattice_for(group, 380.0, rng=rng)
    img = render_print(random_print(group, w1=w1, w2=w2, seed=7), (1000, 1000), 1.0)
    res = detect_lattice(img, mm_per_px=1.0)
    assert res.found, res.message


def test_bad_input_is_refused_with_a_reason():
    with pytest.raises(ValueError, match="mm_per_px"):
        detect_lattice(np.zeros((64, 64), np.uint8), mm_per_px=0)
    with pytest.raises(ValueError, match="too small"):
        detect_lattice(np.zeros((8, 8), np.uint8))


@pytest.mark.parametrize("name, repeat, rotation", [
    ("gingham", 27.7, 1.3), ("plaid", 33.3, 0.7), ("diamonds", 30.1, 0.4),
    ("houndstooth", 25.9, 2.2), ("polka-hex", 31.0, 3.0)])
def test_a_fine_print_in_a_large_frame_is_read_on_its_own_repeat(name, repeat, rotation, vt):
    """A 26-35 px repeat in a 4096 px frame: 7-9 working px, thousands of equally tall
    autocorrelation peaks. The lattice comes from those nearest zero lag; the tallest
    few hundred once gave superlattices of index 5 to 30 on every one of these."""
    p = classic_print(name, repeat, rotation=rotation)
    res = detect_lattice(render_print(p, (4096, 1800), 1.0), mm_per_px=1.0)
    assert res.kind == "lattice", res.message
    assert vt.lattice_error(res.basis, p.wallpaper.basis) < 0.01
