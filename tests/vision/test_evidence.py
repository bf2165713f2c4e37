"""No lattice without evidence: cloth whose repeats do not look alike along both
lattice vectors is reported plain, saying why, and the operator may still confirm the
reading that was refused."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from bench.vision import PHOTOS
from simulators.fabric import random_print, render_print
from solver.wallpaper import Wallpaper
from vision.neighbours import directional_likeness
from vision.pipeline import confirm_fabric, detect_fabric

N = 24
LEOPARD = "ms_leopard_knit.jpg"


def _grid(rows: int, cols: int) -> np.ndarray:
    i, j = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    return np.stack([i.ravel(), j.ravel()], axis=1).astype(float)


def test_likeness_is_measured_along_each_lattice_vector():
    """Cells constant along w2 (streaks running along it) and random along w1."""
    rng = np.random.default_rng(0)
    ij = _grid(6, 5)
    columns = rng.standard_normal((6, N, N))
    cells = columns[ij[:, 0].astype(int)] + 0.05 * rng.standard_normal((len(ij), N, N))
    along_w1, along_w2 = directional_likeness(cells, ij)
    assert along_w2 > 0.99 and abs(along_w1) < 0.2


def test_a_direction_with_no_neighbours_in_view_is_not_measured():
    """One row of repeats (a sweater's band of argyle diamonds): nothing across it."""
    rng = np.random.default_rng(1)
    cells = np.repeat(rng.standard_normal((1, N, N)), 5, axis=0)
    along_w1, along_w2 = directional_likeness(cells, _grid(5, 1))
    assert along_w1 == pytest.approx(1.0) and np.isnan(along_w2)
    with pytest.raises(ValueError, match="indices"):
        directional_likeness(cells, _grid(4, 1))


def _tossed_print(seed: int, side: int = 640) -> np.ndarray:
    """Spots of random size tossed at random over the cloth, lit from one side: a
    leopard print with no repeat in view."""
    rng = np.random.default_rng(seed)
    img = np.full((side, side, 3), (70, 160, 200), np.uint8)
    for x, y, r in zip(rng.uniform(0, side, 260), rng.uniform(0, side, 260),
                       rng.uniform(6, 22, 260), strict=True):
        axes = (int(r), int(r * rng.uniform(0.5, 1.0)))
        cv2.ellipse(img, (int(x), int(y)), axes, rng.uniform(0, 180), 0, 360, (30, 40, 50), -1)
    ramp = np.linspace(0.8, 1.1, side)[None, :, None]
    return np.clip(img * ramp + rng.normal(0, 4, img.shape), 0, 255).astype(np.uint8)


def _streaked_plain(seed: int) -> np.ndarray:
    """Plain dyed cloth under a line-scan camera: yarn texture and soft column streaks
    at irregular spacing, as in the Tianchi frames."""
    rng = np.random.default_rng(seed)
    h, w = 600, 1400
    streaks = np.convolve(rng.standard_normal(w), np.hanning(61), mode="same")
    yarn = cv2.GaussianBlur(rng.standard_normal((h, w)), (0, 0), 1.2)
    gray = 150 + 6 * streaks[None, :] / streaks.std() + 5 * yarn / yarn.std()
    return np.clip(gray, 0, 255).astype(np.uint8)


@pytest.mark.parametrize("image", [_tossed_print(3), _tossed_print(4), _streaked_plain(5),
                                   _streaked_plain(6)],
                         ids=["tossed-3", "tossed-4", "streaks-5", "streaks-6"])
def test_cloth_without_a_repeat_gives_no_lattice(image):
    det = detect_fabric(image, mm_per_px=1.0)
    assert det.lattice.kind in ("plain", "stripes"), det.lattice
    assert det.wallpaper is None and det.fabric_json()["group"] is None
    assert det.lattice.message


def test_a_refused_reading_is_the_operators_to_confirm():
    doc = {"group": None, "kind": "plain", "units": "mm", "message": "no repeat across",
           "candidate": Wallpaper("p1", (20.0, 1.0), (-2.0, 21.0), (3.0, 4.0)).to_dict()}
    confirmed = confirm_fabric(doc, "p2")
    assert confirmed["group"] == "p2" and confirmed["kind"] == "lattice"
    assert confirmed["w1"] == [20.0, 1.0] and confirmed["refused"] == "no repeat across"
    assert "candidate" not in confirmed and confirmed["confirmed"]
    kept_plain = confirm_fabric(doc)  # the operator accepts: no print to cut to
    assert kept_plain["group"] is None and kept_plain["kind"] == "plain"
    with pytest.raises(ValueError, match="no lattice was detected"):
        confirm_fabric({"group": None, "kind": "plain"})


@pytest.mark.skipif(not (PHOTOS / LEOPARD).is_file(), reason=f"{LEOPARD} is not here "
                    f"({PHOTOS}): the photographs live outside the project, in ../shared")
def test_a_leopard_knit_reports_why_and_keeps_its_candidate():
    """The knit's stitches offer a lattice; the leopard spots on it do not repeat."""
    det = detect_fabric(cv2.imread(str(PHOTOS / LEOPARD)), mm_per_px=1.0)
    doc = det.fabric_json()
    assert doc["group"] is None and doc["kind"] == "plain"
    assert "no repeat across the frame" in doc["message"]
    assert confirm_fabric(doc, "p1")["w1"] == doc["candidate"]["w1"]


def test_a_print_one_repeat_tall_keeps_its_lattice():
    """Five repeats in a row, fewer than two across: nothing says there is no repeat."""
    p = random_print("pmm", 50.0, seed=2)
    det = detect_fabric(render_print(p, (320.0, 70.0), 1.0), mm_per_px=1.0)
    assert det.lattice.found and det.candidate is None
    assert det.classification.group == "pmm" and det.classification.n_repeats == 5
