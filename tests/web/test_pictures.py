"""Pictures show the fabric as it is: the photograph, or only the lattice that is known."""

from __future__ import annotations

import ast
import json
from collections import Counter
from pathlib import Path

import cv2
import numpy as np

import station.render
from solver.nest.layout import Layout
from solver.wallpaper import Wallpaper
from station.cli import main
from station.render import cloth_image, fabric_picture, lattice_colours

GARMENT = Path(__file__).resolve().parents[1] / "data" / "garments" / "berkeley" / \
    "tshirt-coarse.obj"

CLOTH, LINE = (222, 226, 230), (150, 150, 150)


def test_render_draws_no_simulated_print():
    tree = ast.parse(Path(station.render.__file__).read_text())
    imported = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)} | {
        a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    assert not any(m and m.split(".")[0] == "simulators" for m in imported), imported


def test_without_a_photograph_only_the_lattice_is_drawn():
    wallpaper = Wallpaper("p4m", (30.0, 0.0), (0.0, 30.0), origin=(5.0, 7.0))
    colour_of = lattice_colours(wallpaper, pixel_mm=0.5)
    i, j = np.meshgrid(np.arange(-3, 4), np.arange(-3, 4))
    cells = np.column_stack([i.ravel(), j.ravel()]).astype(float)
    on_lines = wallpaper.to_cartesian(cells + [0.0, 0.37])  # on the lines along w2
    centres = wallpaper.to_cartesian(cells + 0.5)
    assert (colour_of(on_lines) == LINE).all()
    assert (colour_of(centres) == CLOTH).all()
    # an oblique lattice too: lines follow w1 and w2, not the picture's axes
    oblique = Wallpaper("p2", (25.0, 4.0), (-6.0, 31.0))
    colour_of = lattice_colours(oblique, pixel_mm=0.5)
    assert (colour_of(oblique.to_cartesian(cells * [1, 0] + [0, 0.61])) == LINE).all()
    assert (colour_of(oblique.to_cartesian(cells + 0.5)) == CLOTH).all()


def test_the_cloth_under_a_marker_is_the_photograph():
    rng = np.random.default_rng(3)
    photo = rng.integers(0, 255, (120, 200, 3), dtype=np.uint8)
    layout = Layout(width=120 * 1.5, length=200 * 1.5, gap=0.0, pieces=[],
                    fabric={"group": "p1", "w1": [40, 0], "w2": [0, 40]})
    assert np.array_equal(cloth_image(layout, 200, photo=photo, photo_mm_per_px=1.5), photo)
    # without the photograph: the layout's lattice on plain cloth, every 40 mm
    ruled = cloth_image(layout, 300)  # 1 mm per pixel
    assert ruled.shape == (180, 300, 3)
    columns = np.flatnonzero((ruled[90] == LINE).all(axis=1))
    assert set(range(40, 300, 40)) <= set(columns) and len(columns) <= 2 * 8


def test_a_fabric_file_that_names_its_picture_is_drawn_from_it(tmp_path):
    """`station simulate-fabric` writes the tartan and its truth; `station fit --png` draws
    the pieces over that tartan, sampled through the lattice, not over a stand-in."""
    image, truth = tmp_path / "tartan.png", tmp_path / "TRUTH.json"
    assert main(["simulate-fabric", "--classic", "tartan", "--repeat", "60", "--size", "120",
                 "90", "--mm-per-px", "0.5", "-o", str(image), "--truth", str(truth)]) == 0
    doc = json.loads(truth.read_text())
    doc["image"] = image.name  # beside the FABRIC.json: found relative to it
    truth.write_text(json.dumps(doc))
    wallpaper = Wallpaper.from_dict(doc)
    colour_of = fabric_picture(truth, wallpaper)
    picture = cv2.imread(str(image))
    inside = np.array([[20.0, 15.0], [33.5, 41.0], [47.0, 28.5]])  # mm, whole pixels
    expected = picture[(inside[:, 1] / 0.5).astype(int), (inside[:, 0] / 0.5).astype(int)]
    assert np.array_equal(colour_of(inside), expected)
    far = inside + 7 * wallpaper.w1 - 4 * wallpaper.w2  # off the picture: one repeat away
    assert np.abs(colour_of(far).astype(int) - expected).max() <= 2
    plain = tmp_path / "plain.json"  # a FABRIC.json without a picture: the lattice only
    plain.write_text(json.dumps({k: doc[k] for k in ("group", "w1", "w2")}))
    assert fabric_picture(plain, wallpaper) is None
    out = tmp_path / "fit.png"
    assert main(["fit", str(GARMENT), "--fabric", str(truth), "--units", "m", "--png",
                 str(out)]) == 0
    # the tartan's own colours fill the pieces: its three commonest are the picture's
    drawn = Counter(map(tuple, cv2.imread(str(out)).reshape(-1, 3).tolist()))
    drawn.pop((245, 245, 245))  # the page around the pieces
    woven = Counter(map(tuple, picture.reshape(-1, 3).tolist()))
    assert [c for c, _ in drawn.most_common(3)] == [c for c, _ in woven.most_common(3)]
