"""simulators.cloth: each fault does what it says, with the geometry it reports."""

from __future__ import annotations

import numpy as np
import pytest

from simulators.cloth import misregister, plain_cloth, stretch, weave_texture, wrinkle


def test_stretch_moves_every_point_by_its_jacobian():
    img = np.zeros((201, 301), np.float32)
    img[100, 150] = img[60, 200] = 1.0  # the centre and a point 50 px right, 40 up
    out, jac = stretch(img, 1.12, shear_deg=4.0, angle_deg=30.0)
    assert np.linalg.det(jac) == pytest.approx(1.12)
    y, x = np.unravel_index(np.argsort(out.ravel())[-8:], out.shape)
    pts = np.stack([x, y], 1).astype(float)
    weights = out[y, x]
    far = np.hypot(pts[:, 0] - 150, pts[:, 1] - 100) > 5
    moved = (pts[far] * weights[far, None]).sum(0) / weights[far].sum()
    assert moved == pytest.approx(np.array([150, 100]) + jac @ [50, -40], abs=0.7)
    assert out[100, 150] > 0.9  # the centre stays


@pytest.mark.parametrize(("weave", "period_threads"), [("plain", 2), ("twill", 4), ("rib", 1)])
def test_weave_texture_repeats_with_its_weave(weave, period_threads):
    tex = weave_texture((128, 256), 8.0, weave=weave, rng=np.random.default_rng(1))
    assert tex.mean() == pytest.approx(1.0, abs=0.01)
    spec = np.abs(np.fft.rfft(tex - tex.mean(), axis=1)).mean(0)
    # The strongest horizontal frequency is a harmonic of the weave's repeat (one
    # thread of 8 px for rib, two for plain weave, four for twill), never finer detail.
    k = int(np.argmax(spec[1:])) + 1
    assert k % (256 // (8 * period_threads)) == 0


def test_plain_cloth_has_no_print_scale_structure_and_misregistration_moves_one_channel():
    img = plain_cloth((300, 200), 4.0, seed=2)
    assert img.shape == (200, 300, 3) and img.dtype == np.uint8
    small = img.astype(float).mean(2)
    coarse = small.reshape(20, 10, 30, 10).mean((1, 3))
    assert coarse.std() < 0.08 * small.mean()  # only the soft shading bands
    shifted = misregister(img, (3.0, 0.0), channel=2)
    assert np.array_equal(shifted[..., :2], img[..., :2])
    assert np.allclose(shifted[50:150, 100:200, 2], img[50:150, 97:197, 2], atol=1)


def test_wrinkles_move_the_cloth_locally_only():
    rng = np.random.default_rng(0)
    img = (np.indices((200, 200)).sum(0) % 16 < 8).astype(np.uint8) * 200 + 20
    out = wrinkle(img, 4.0, 20.0, n=1, rng=rng)
    changed = np.abs(out.astype(int) - img) > 30
    assert 0.01 < changed.mean() < 0.5
