"""The lattice of small, blurred, wrinkled prints (issue 15): the detector must not take a
multiple (the fundamental peaks lowered by blur, a sparse lattice seen at two long lags)
nor a sub-lattice (a partial symmetry, or a finer lattice the grey of two inks shares),
and the group read on it must never be a supergroup.

The images come from the simulators as in ``bench.vision.blurred`` (20-34 px repeats,
blur up to 3 px, noise, wrinkles, JPEG) with seed 71, apart from the benchmark's seed 0
and from the seeds the detector's constants were calibrated on (11, 23).
"""

from __future__ import annotations

import numpy as np

from bench.vision import blurred, lattice_match
from vision.lattice import detect_lattice
from vision.pipeline import CONFIRM_BELOW, detect_fabric
from vision.subgroups import error_kind


def _lattice_right(found, truth, tol) -> bool:
    same, err = lattice_match(found, truth)
    return bool(same and err < tol)


def test_small_blurred_prints_give_the_true_lattice_and_never_a_supergroup():
    lattice_ok, outcomes = [], []
    for s in blurred(2, seed=71):
        det = detect_fabric(s.image, mm_per_px=s.mm_per_px)
        right = det.lattice.found and _lattice_right(det.lattice.basis, s.basis, s.tol)
        lattice_ok.append(right)
        outcomes.append((s.name, error_kind(det.classification.group, s.truth),
                         det.classification.confidence, right))
    assert len(outcomes) == 34
    # Before this detector 24 of these 34 (71 %) had the right lattice; now 33.
    assert sum(lattice_ok) >= 31, [o for o in outcomes if not o[3]]
    # No supergroup on the right lattice; on a wrong one (one pmg blurred past its
    # first repeats, read as cmm before and now) never taken without the operator.
    supergroups = [o for o in outcomes if o[1] == "supergroup"]
    assert not [o for o in supergroups if o[3] or o[2] >= CONFIRM_BELOW], supergroups


def _two_ink_print(period: int = 30, shape=(240, 300)) -> np.ndarray:
    """Grey dots on a square lattice of ``period`` px, alternately pink and lilac of
    the same grey: the print's lattice is the checkerboard of the two inks (vectors
    (period, period) and (period, -period)), while its grey repeats on the finer one."""
    h, w = shape
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    i, j = np.floor(yy / period), np.floor(xx / period)
    cy, cx = (i + 0.5) * period, (j + 0.5) * period
    dot = np.exp(-((yy - cy) ** 2 + (xx - cx) ** 2) / (2 * (0.18 * period) ** 2))
    pink = np.array([180.0, 120.0, 230.0])  # BGR
    lilac = np.array([230.0, 140.0, 175.0])
    # Equal grey (OpenCV weights 0.114 B + 0.587 G + 0.299 R) within half a level.
    lilac[1] += (pink @ [0.114, 0.587, 0.299] - lilac @ [0.114, 0.587, 0.299]) / 0.587
    ink = np.where(((i + j) % 2 == 0)[..., None], pink, lilac)
    paper = np.full(3, 245.0)
    img = paper + dot[..., None] * (ink - paper)
    rng = np.random.default_rng(5)
    return np.clip(img + rng.normal(0, 2.0, img.shape), 0, 255).astype(np.uint8)


def test_two_inks_of_equal_grey_give_the_colour_lattice():
    img = _two_ink_print()
    truth = np.array([[30.0, 30.0], [30.0, -30.0]])
    res = detect_lattice(img)
    assert res.found, res.message
    assert _lattice_right(res.basis_px, truth, 0.02), res.basis_px
    # Its grey alone repeats on the finer square lattice: colour is what tells them apart.
    grey = detect_lattice(np.ascontiguousarray(img.mean(axis=2)).astype(np.uint8))
    assert grey.found and _lattice_right(grey.basis_px, np.eye(2) * 30.0, 0.02)
