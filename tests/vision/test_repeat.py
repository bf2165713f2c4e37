"""A lattice read too fine (``vision.repeat``): alternate repeats that differ the same way
all over the cloth mean the step between them is not a repeat of the print. Exact
numbers on constructed cells, then line prints whose faint layer repeats on a sublattice
of the bold one (``simulators.lineart``), then true lattices on distorted cloth."""

from __future__ import annotations

import numpy as np
import pytest

from bench.vision import cloth, lattice_match
from simulators.lineart import layered_print
from vision.consistency import alternation
from vision.lattice import detect_lattice, prepare_image
from vision.pipeline import detect_fabric
from vision.repeat import step_is_repeat, true_lattice
from vision.subgroups import error_kind

N = 32


def _smooth(rng, scale: float = 5.0) -> np.ndarray:
    k = np.fft.fftfreq(N) * N
    ka, kb = np.meshgrid(k, k, indexing="ij")
    field = np.fft.ifft2(np.fft.fft2(rng.normal(size=(N, N)))
                         * np.exp(-0.5 * (ka**2 + kb**2) / scale**2)).real
    return field / np.sqrt((field**2).sum())


def _cells(rng, parity, diff: float, noise: float, drift: float = 0.3, side: int = 12):
    """Cells of a side x side block of repeats: a motif of unit energy, +-``diff`` times
    a fixed pattern of unit energy by ``parity`` class, a drift linear in (i, j) and
    white noise per repeat."""
    motif, d, slope = _smooth(rng), _smooth(rng), _smooth(rng)
    ii, jj = np.meshgrid(np.arange(side), np.arange(side), indexing="ij")
    ij = np.stack([ii.ravel(), jj.ravel()], 1)
    sign = 1.0 - 2.0 * ((ij @ np.array(parity)) % 2)
    cells = (motif[None] + diff * sign[:, None, None] * d[None]
             + drift * ((ij[:, 0] + 0.5 * ij[:, 1]) / side)[:, None, None] * slope[None]
             + rng.normal(0, noise / N, (len(ij), N, N)))
    return cells, ij


@pytest.mark.parametrize("parity", [(1, 0), (0, 1), (1, 1)])
def test_alternation_measures_the_shared_difference(parity):
    rng = np.random.default_rng(sum(parity))
    diff = 0.15  # own = 2 |d|^2 / |m|^2 = 0.045
    cells, ij = _cells(rng, parity, diff, noise=0.5)
    alt = alternation(cells, ij)
    assert alt.parity == parity
    assert alt.own == pytest.approx(2 * diff**2, rel=0.25)
    assert alt.z > 8
    assert not step_is_repeat(alt)


def test_no_alternation_under_noise_and_drift():
    for seed in range(5):
        rng = np.random.default_rng(10 + seed)
        cells, ij = _cells(rng, (1, 1), 0.0, noise=1.0, drift=2.0)
        alt = alternation(cells, ij)
        assert abs(alt.own) < 0.002 and abs(alt.z) < 5, alt
        assert step_is_repeat(alt)


def test_too_few_repeats_give_no_answer():
    cells, ij = _cells(np.random.default_rng(0), (1, 0), 0.1, noise=0.1, side=3)
    assert alternation(cells, ij) is None


SUBLATTICES = (np.array([[2, 0], [0, 1]]), np.array([[1, 1], [1, -1]]))


def _faint_on_sublattice(groups, seeds):
    for group in groups:
        for seed in seeds:
            rng = np.random.default_rng(500 + seed)
            img, truth, basis = layered_print(group, rng.uniform(25, 45), (480, 360),
                                              seed=seed, faint_cell=SUBLATTICES[seed % 2])
            img = np.clip(img + rng.normal(0, 4, img.shape), 0, 255).astype(np.uint8)
            yield group, seed, img, truth, basis


def _read(samples, true_repeat: bool = True):
    out = []
    for group, seed, img, truth, basis in samples:
        det = detect_fabric(img, mm_per_px=0.25, true_repeat=true_repeat)
        ok = det.lattice.found and lattice_match(det.lattice.basis, basis)[1] < 0.03
        out.append((group, seed, truth, det.classification.group, bool(ok),
                    error_kind(det.classification.group, truth, None)))
    return out


@pytest.fixture(scope="module")
def faint():
    return list(_faint_on_sublattice(("p4m", "pmm", "p6", "cm", "pgg", "p31m"), (20, 21)))


def test_a_faint_layer_on_a_sublattice_sets_the_lattice(faint):
    """Without the test the bold layer's finer lattice is read and the group comes out a
    supergroup on most of these prints; with it the print's own lattice is found."""
    found = _read(faint)
    assert sum(f[4] for f in found) >= 0.8 * len(found), found
    assert sum(f[5] == "supergroup" for f in found) <= 0.2 * len(found), found
    before = _read(faint, true_repeat=False)
    assert sum(f[5] == "supergroup" for f in before) >= 0.5 * len(before), before


def test_true_lattices_on_distorted_cloth_are_kept():
    """Prints on stretched, wrinkled, woven cloth (the bench's ``cloth`` source, seeds
    it is not measured on): the lattice read is never halved."""
    for s in cloth(1, seed=40):
        flat, scale = prepare_image(s.image)
        lat = detect_lattice(s.image, mm_per_px=s.mm_per_px, prepared=(flat, scale))
        if not lat.found:
            continue
        kept = true_lattice(s.image, lat, prepared=(flat, scale))
        assert np.allclose(kept.basis, lat.basis), s.name
