"""The cut at the fabric's edge and the notch depth the layout allows."""

from __future__ import annotations

import numpy as np
import shapely

from gcode.arcs import sample_path
from gcode.layout import layout_from_dict
from gcode.machine import default_machine
from gcode.toolpath import build_toolpaths


def _layout(notch_depth=None) -> dict:
    square = [[0.0, 0.0], [200.0, 0.0], [200.0, 100.0], [0.0, 100.0]]  # on the selvedge y = 0
    notch = {"at": [100.0, 100.0], "direction": [0.0, -1.0]}
    if notch_depth is not None:
        notch["depth"] = notch_depth
    return {"version": 1, "units": "mm", "width": 500.0, "length": 200.0, "gap": 0.0,
            "origin": [0.0, 0.0],
            "pieces": [{"id": "a#1", "name": "a", "outline": square, "notches": [notch]}]}


def test_the_kerf_never_leaves_the_cloth_at_a_selvedge_or_the_start():
    machine = default_machine()
    (tp,) = build_toolpaths(layout_from_dict(_layout()), machine)
    outline = [c for c in tp.contours if c.kind == "outline"][0]
    pts = np.vstack([sample_path(s, 0.05) for s in outline.strokes])
    assert pts[:, 0].min() >= -1e-9 and pts[:, 1].min() >= -1e-9  # on the table, on the cloth
    half = machine.cut.kerf / 2
    # the far end of the marker is no edge (the roll runs on): cut half a kerf out there
    assert abs(pts[:, 0].max() - (200.0 + half)) < 1e-6
    assert abs(pts[:, 1].max() - (100.0 + half)) < 1e-6
    # what is left uncut of the kerf-offset outline is what lies off the cloth (or within
    # the arc tolerance of its edge, where a fitted arc could stray off it)
    tol = machine.cut.tolerance
    ring = shapely.box(0, 0, 200, 100).buffer(half, join_style="mitre").exterior
    cut = shapely.MultiLineString([sample_path(s, 0.05) for s in outline.strokes])
    uncut = ring.difference(cut.buffer(1e-6))
    assert uncut.length > 2 * 100  # the two sides on the edges
    off = shapely.get_coordinates(shapely.segmentize(uncut, 1.0))
    assert np.all((off[:, 0] <= tol + 1e-6) | (off[:, 1] <= tol + 1e-6))
    assert ring.difference(shapely.box(0, 0, 1e6, 1e6)).length <= uncut.length + 1e-3


def test_the_layout_notch_depth_caps_the_machine_notch():
    machine = default_machine()  # notch_depth 3 mm
    for given, expected in ((None, 3.0), (1.5, 1.5), (5.0, 3.0)):
        (tp,) = build_toolpaths(layout_from_dict(_layout(given)), machine)
        (notch,) = [c for c in tp.contours if c.kind == "notch"]
        inner = notch.points[np.argmin(notch.points[:, 1])]
        assert abs((100.0 - inner[1]) - expected) < 1e-9


def test_curves_and_notches_on_the_selvedge_stay_on_the_table(tmp_path, capsys):
    """Arcs fitted to a disc touching the edge, and a notch cut at the edge itself: the
    program passes its own work-area check (it used to reach y = -0.1)."""
    import json

    from station.cli import main

    t = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    disc = np.c_[100 + 80 * np.cos(t), 80 + 80 * np.sin(t)]  # touches y = 0 at t = 3pi/2
    low = disc[np.argmin(disc[:, 1])]
    layout = _layout()
    layout["pieces"] = [{"id": "disc#1", "name": "disc", "outline": disc.tolist(),
                         "notches": [{"at": low.tolist(), "direction": [0.0, 1.0],
                                      "depth": 2.0}]}]
    (tmp_path / "L.json").write_text(json.dumps(layout))
    assert main(["gcode", str(tmp_path / "L.json"), "-o", str(tmp_path / "J.nc"),
                 "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["arcs"] > 0
    (tp,) = build_toolpaths(layout_from_dict(layout), default_machine())
    (notch,) = [c for c in tp.contours if c.kind == "notch"]
    assert notch.strokes and all(sample_path(s, 0.01)[:, 1].min() >= 0 for s in notch.strokes)
