"""Prints of all 17 wallpaper groups and the textile classics have exactly their symmetry.

The check works on the rendered pixels, against solver.wallpaper's table:

- every operation of the print's group (``Wallpaper.cartesian_ops``), applied to the image
  by resampling, gives a copy that correlates ~1 with the image;
- for every linear part of the lattice's holohedry (all rotations by 60/90/120/180
  degrees and all reflections that map the lattice to itself, so every possible
  symmetry of a pattern with this lattice), the transformed image is matched against
  the original at *all* translations (normalised cross-correlation). Peaks are allowed
  only where the group predicts one (its own operations plus lattice translations);
  everywhere else the correlation must be clearly lower. This catches any accidental
  extra symmetry: another rotation centre, a mirror where the group has a glide, a
  smaller lattice.
"""

from __future__ import annotations

import itertools
import json
import math

import cv2
import numpy as np
import pytest
from scipy import ndimage

from simulators.classics import CLASSIC_GROUPS, CLASSICS, classic_print, woven_check
from simulators.fabric import Frieze, lattice_for, random_print, render_print
from solver.wallpaper import GROUP_NAMES, GROUPS, Wallpaper
from station.cli import main as station

MM_PER_PX = 1.0
SIZE_PX = 360  # image side; repeats of 32 px leave room for a full-cell search window
IN_GROUP = 0.95  # correlation an operation of the group must reach
RANDOM_OFF = 0.8  # ... that no other isometry may reach (random prints)
CLASSIC_OFF = 0.9  # classics have few colours and simple shapes: near-symmetries are larger


def _holohedry(basis: np.ndarray) -> list[np.ndarray]:
    """Cartesian linear parts of every isometry mapping the lattice to itself."""
    binv = np.linalg.inv(basis)
    out = []
    for e in itertools.product((-1, 0, 1), repeat=4):
        a = np.array(e, float).reshape(2, 2)
        if not np.isclose(abs(np.linalg.det(a)), 1.0):
            continue
        lin = basis @ a @ binv
        if np.allclose(lin @ lin.T, np.eye(2), atol=1e-6):
            out.append(lin)
    return out


def _warp(img: np.ndarray, lin: np.ndarray, t: np.ndarray) -> np.ndarray:
    """J(p) = img(lin p + t) in pixel coordinates; -1 where the source is outside."""
    m = np.hstack([lin, np.reshape(t, (2, 1))])
    h, w = img.shape[:2]
    return cv2.warpAffine(img, m, (w, h), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=(-1, -1, -1))


def _to_pixels(wp: Wallpaper, s: float) -> Wallpaper:
    return Wallpaper(wp.group, wp.w1 / s, wp.w2 / s, wp.origin / s)


def op_correlations(img: np.ndarray, wp: Wallpaper) -> np.ndarray:
    """Pearson correlation of the image with its copy under each op of the group."""
    f = img.astype(np.float32)
    h, w = f.shape[:2]
    c = np.array([(w - 1) / 2, (h - 1) / 2])
    out = []
    for op in wp.cartesian_ops():
        lin, t = op[:2, :2], op[:2, 2]
        # the same op composed with the lattice translation that keeps the centre in view
        t = t - (lin @ c + t - c - wp.lattice_residual((lin @ c + t - c)[None])[0])
        j = _warp(f, lin, t)
        ok = ndimage.binary_erosion(np.all(j >= 0, axis=2), iterations=2)
        out.append(np.corrcoef(f[ok].ravel(), j[ok].ravel())[0, 1])
    return np.array(out)


def isometry_scan(img: np.ndarray, wp: Wallpaper, template: int = 96):
    """For every holohedry linear part: (in group?, best predicted peak, best elsewhere)."""
    f = img.astype(np.float32)
    h, w = f.shape[:2]
    c = np.array([(w - 1) / 2, (h - 1) / 2])
    span = int(np.ceil(np.abs(wp.basis).sum(1).max())) + 4
    a = np.floor(c - template / 2).astype(int)
    tmpl = f[a[1]:a[1] + template, a[0]:a[0] + template]
    lo, hi = a - span, a + template + span
    ops = wp.cartesian_ops()
    results = []
    for lin in _holohedry(wp.basis):
        j = _warp(f, lin, c - lin @ c)  # J(p) = I(c + L (p - c))
        win = j[lo[1]:hi[1], lo[0]:hi[0]]
        assert win.min() >= 0, "search window leaves the image"
        r = cv2.matchTemplate(win, tmpl, cv2.TM_CCOEFF_NORMED)
        oy, ox = np.mgrid[0:r.shape[0], 0:r.shape[1]]
        tau = np.stack([ox, oy], -1).reshape(-1, 2) + lo - a  # I(g p) = J(p + tau)
        mask = np.zeros(r.shape, bool)
        predicted = []
        for op in ops:
            if not np.allclose(op[:2, :2], lin, atol=1e-6):
                continue
            tau0 = np.linalg.solve(lin, op[:2, 2] - c) + c
            near = (np.hypot(*wp.lattice_residual(tau - tau0).T) < 3.0).reshape(r.shape)
            mask |= near
            predicted.append(r[near].max())
        off = float(r[~mask].max())
        results.append((bool(predicted), min(predicted) if predicted else None, off))
    return results


def assert_exact_symmetry(img: np.ndarray, wp_mm: Wallpaper, off_limit: float) -> None:
    wp = _to_pixels(wp_mm, MM_PER_PX)
    corr = op_correlations(img, wp)
    assert corr.min() >= IN_GROUP, f"{wp.group}: an operation of the group fails: {corr}"
    scan = isometry_scan(img, wp)
    n_linear = sum(1 for s in scan if s[0])
    assert n_linear == len({tuple(np.round(op[:2, :2], 6).ravel())
                            for op in wp.cartesian_ops()})
    for in_group, best_predicted, off in scan:
        if in_group:
            assert best_predicted >= IN_GROUP
        assert off <= off_limit, f"{wp.group}: accidental extra symmetry ({off:.3f})"


@pytest.mark.parametrize("group", GROUP_NAMES)
def test_random_print_has_exactly_its_group(group):
    for seed, rotation in ((GROUP_NAMES.index(group), 23.0),):
        p = random_print(group, 32.0, seed=seed, rotation=rotation)
        assert p.truth.group == group
        img = render_print(p, (SIZE_PX * MM_PER_PX,) * 2, MM_PER_PX)
        assert_exact_symmetry(img, p.truth, RANDOM_OFF)


@pytest.mark.parametrize(("threads", "weft", "exact_at_thread_scale"),
                         [(9, 9, False), (8, 8, False), (9, 5, True), (8, 5, False)])
def test_woven_check_has_its_designed_group_above_the_yarn(threads, weft,
                                                           exact_at_thread_scale):
    """A woven gingham is not p4m thread by thread (quarter turns or mirrors swap warp-up
    and weft-up crossings), an uneven check is pmm there only with odd bands; every
    designed operation holds once the yarn's two-thread repeat is smoothed away."""
    p = woven_check(32.0, threads, weft_threads=weft, rotation=12.0)
    assert p.truth.group == ("p4m" if weft == threads else "pmm")
    img = render_print(p, (SIZE_PX * MM_PER_PX,) * 2, MM_PER_PX)
    wp = _to_pixels(p.truth, MM_PER_PX)
    assert (op_correlations(img, wp).min() >= IN_GROUP) == exact_at_thread_scale
    thread_px = 32.0 / (2 * threads) / MM_PER_PX
    smooth = cv2.GaussianBlur(img.astype(np.float32), (0, 0), 0.75 * math.sqrt(2) * thread_px)
    assert op_correlations(smooth, wp).min() >= IN_GROUP


@pytest.mark.parametrize("name", [c for c in CLASSICS if c != "stripes"])
def test_classic_has_exactly_its_group(name):
    p = classic_print(name, 32.0, rotation=12.0, origin=(5.0, 7.0))
    assert p.truth.group == CLASSIC_GROUPS[name]
    img = render_print(p, (SIZE_PX * MM_PER_PX,) * 2, MM_PER_PX)
    assert_exact_symmetry(img, p.truth, CLASSIC_OFF)


def test_a_print_with_an_extra_symmetry_is_caught():
    """The scan is not blind: a p4m print described as p4 (or as pmm) fails it."""
    p = classic_print("polka-square", 32.0, rotation=12.0, origin=(5.0, 7.0))
    img = render_print(p, (SIZE_PX * MM_PER_PX,) * 2, MM_PER_PX)
    for weaker in ("p4", "pmm", "p2"):
        wp = Wallpaper(weaker, p.truth.w1, p.truth.w2, p.truth.origin)
        with pytest.raises(AssertionError, match="accidental extra symmetry"):
            assert_exact_symmetry(img, wp, CLASSIC_OFF)


def test_stripes_are_a_frieze():
    p = classic_print("stripes", 24.0, rotation=30.0, origin=(3.0, 4.0))
    truth = p.truth
    assert isinstance(truth, Frieze) and p.wallpaper is None
    assert truth.group == CLASSIC_GROUPS["stripes"].split()[0]
    rng = np.random.default_rng(0)
    pts = rng.uniform(-100, 100, (200, 2))
    d = truth.direction
    axis = truth.w1 / np.hypot(*truth.w1)

    def colour(q):
        return p.colour_at(q[:, :1], q[:, 1:], 0.1)[:, 0]

    base = colour(pts)
    assert np.abs(colour(pts + 37.3 * d) - base).max() < 1e-3  # constant along the stripes
    assert np.abs(colour(pts + truth.w1) - base).max() < 1e-3  # period w1
    # mirror along the axis (p11m) holds; the mirror across it and the half-turn do not
    along = ((pts - truth.origin) @ axis)[:, None] * axis + truth.origin
    mirrored = 2 * along - pts
    assert np.abs(colour(mirrored) - base).max() < 1e-3
    across = pts - 2 * (((pts - truth.origin) @ axis)[:, None] * axis)
    assert np.abs(colour(across) - base).max() > 0.2
    assert d @ truth.w1 == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("group", GROUP_NAMES)
def test_lattice_fits_its_group_at_any_rotation(group):
    rng = np.random.default_rng(5)
    for rotation in (0.0, 33.0, -120.0):
        w1, w2 = lattice_for(group, 25.0, rotation=rotation, rng=rng)
        wp = Wallpaper(group, w1, w2)
        assert np.hypot(*w1) == pytest.approx(25.0)
        assert math.degrees(math.atan2(w1[1], w1[0])) == pytest.approx(rotation)
        assert wp.info.lattice == GROUPS[group].lattice


def test_unknown_group_or_classic_is_refused():
    with pytest.raises(ValueError, match="unknown wallpaper group"):
        random_print("p5")
    with pytest.raises(ValueError, match="unknown classic"):
        classic_print("paisley")
    with pytest.raises(ValueError, match="repeat must be positive"):
        random_print("p1", -3.0)


def test_pixel_convention_and_periodicity():
    """Pixel (col, row) is centred on offset + (col, row) * s mm: shifting the offset by
    a lattice vector reproduces the image, shifting it by whole pixels crops it."""
    p = random_print("p3", 20.0, seed=4)
    s = 0.5
    a = render_print(p, (60, 50), s)
    b = render_print(p, (60, 50), s, offset=tuple(p.truth.w1 + 2 * p.truth.w2))
    assert np.abs(a.astype(int) - b.astype(int)).max() <= 2
    c = render_print(p, (60, 50), s, offset=(3 * s, 7 * s))
    assert np.abs(a[7:, 3:].astype(int) - c[:-7, :-3].astype(int)).max() <= 1
    assert a.shape == (100, 120, 3) and a.dtype == np.uint8


def test_without_anti_aliasing_a_lattice_of_whole_pixels_repeats_exactly():
    """As a drawing program writes a print: on a lattice of whole pixels every repeat
    is the same pixels (the anti-aliased rendering blends its edges differently)."""
    p = random_print("p4m", w1=np.array([24.0, 0.0]), w2=np.array([0.0, 24.0]), seed=3,
                     origin=(0.3, 0.7))
    hard = render_print(p, (96, 72), 1.0, anti_alias=False)
    assert np.array_equal(hard[:, 24:], hard[:, :-24])
    assert np.array_equal(hard[24:], hard[:-24])
    assert not np.array_equal(hard, render_print(p, (96, 72), 1.0))


def test_anti_aliased_against_a_supersampled_reference():
    """At 6 px per repeat, point sampling aliases into moiré (low-frequency error that
    survives a slight blur); the band-limited rendering matches the box average of an
    8x finer rendering up to the shape of the pixel filter, which the blur removes."""
    p = random_print("p4m", 6.0, seed=2, rotation=11.0)
    img = render_print(p, (96, 96), 1.0).astype(np.float32)
    fine = render_print(p, (96, 96), 1.0 / 8, offset=(-7 / 16, -7 / 16)).astype(np.float32)
    ref = cv2.resize(fine, (96, 96), interpolation=cv2.INTER_AREA)
    point = render_print(p, (96, 96), 1.0 / 8).astype(np.float32)[::8, ::8]

    def error(a):
        return np.abs(cv2.GaussianBlur(a, (0, 0), 1.0) - cv2.GaussianBlur(ref, (0, 0), 1.0)).mean()

    assert error(img) < 2.0
    assert error(point) > 3 * error(img)


def test_random_print_is_repeatable_and_seeded():
    a = render_print(random_print("pgg", 30.0, seed=7), (64, 64), 0.5)
    b = render_print(random_print("pgg", 30.0, seed=7), (64, 64), 0.5)
    c = render_print(random_print("pgg", 30.0, seed=8), (64, 64), 0.5)
    assert np.array_equal(a, b)
    assert np.abs(a.astype(int) - c.astype(int)).mean() > 10


def test_simulate_fabric_command(tmp_path, capsys):
    img, truth = tmp_path / "p.png", tmp_path / "truth.json"
    rc = station(["simulate-fabric", "--group", "cmm", "--repeat", "30", "--rotation", "20",
                  "--seed", "3", "--size", "90", "60", "--mm-per-px", "0.5", "-o", str(img),
                  "--truth", str(truth), "--json"])
    assert rc == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed == json.loads(truth.read_text())
    wp = Wallpaper.load(truth)
    expected = random_print("cmm", 30.0, rotation=20.0, seed=3).truth
    assert wp.group == "cmm"
    assert np.allclose(wp.basis, expected.basis) and np.allclose(wp.origin, expected.origin)
    frame = cv2.imread(str(img))
    assert frame.shape == (120, 180, 3)
    assert printed["mm_per_px"] == 0.5 and printed["image_size_px"] == [180, 120]


def test_simulate_fabric_command_classic_and_errors(tmp_path, capsys):
    truth = tmp_path / "t.json"
    assert station(["simulate-fabric", "--classic", "herringbone", "--repeat", "24",
                    "--size", "40", "30", "-o", str(tmp_path / "h.png"),
                    "--truth", str(truth)]) == 0
    assert Wallpaper.load(truth).group == "pmg"
    rc = station(["simulate-fabric", "--group", "p1", "-o", str(tmp_path / "no" / "x.png")])
    assert rc == 2
    assert "does not exist" in capsys.readouterr().err
    assert station(["simulate-fabric", "--group", "p1", "--mm-per-px", "0",
                    "-o", str(tmp_path / "x.png")]) == 2


def test_woven_check_refuses_impossible_setts():
    for threads, weft in ((0, None), (5, 0), (5, 10)):
        with pytest.raises(ValueError, match="threads"):
            woven_check(10.0, threads, weft_threads=weft)
