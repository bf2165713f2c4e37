"""Helpers for the gcode tests: layouts made from shapely shapes, and an independent reader
that turns G-code back into tool-on and tool-off paths (it shares no code with gcode/).
(A uniquely named module rather than a conftest: test directories have no __init__.py.)"""

from __future__ import annotations

import math
import re

import numpy as np
from shapely.geometry import Point, Polygon, box

_WORD = re.compile(r"([A-Z])([-+]?[0-9.]+)")


def trace(lines: list[str], *, knife_down: float | None = None, step: float = 0.05) -> list[dict]:
    """Every motion of a program: dict(line, g, pts (k,2) sampled path, on, s, f, z0, z1).

    ``on`` is the laser (M3/M4 with S>0) or, when ``knife_down`` is given, the knife at or
    below that Z for the whole move.
    """
    pos = [None, None, None]
    g = None
    s = 0.0
    f = None
    spindle = 5
    out = []
    for i, raw in enumerate(lines):
        code = re.sub(r"\([^)]*\)", "", raw).split(";")[0].upper().replace(" ", "")
        if not code:
            continue
        words = _WORD.findall(code)
        assert "".join(a + b for a, b in words) == code, f"unparsed line {raw!r}"
        vals = {}
        gs = []
        for a, b in words:
            if a == "G":
                gs.append(float(b))
            elif a == "M":
                m = int(float(b))
                if m in (3, 4, 5):
                    spindle = m
            else:
                vals[a] = float(b)
        for gg in gs:
            if gg in (0, 1, 2, 3):
                g = int(gg)
        if "S" in vals:
            s = vals["S"]
        if "F" in vals:
            f = vals["F"]
        if 4.0 in gs or not any(k in vals for k in "XYZ"):
            continue
        tgt = [vals.get("X", pos[0]), vals.get("Y", pos[1]), vals.get("Z", pos[2])]
        if g in (0, 1):
            if tgt[0] is None:
                pts = np.zeros((0, 2))
            elif pos[0] is None:
                pts = np.array([[tgt[0], tgt[1]]], float)
            else:
                pts = np.array([[pos[0], pos[1]], [tgt[0], tgt[1]]], float)
        else:
            c = (pos[0] + vals.get("I", 0.0), pos[1] + vals.get("J", 0.0))
            r = math.hypot(pos[0] - c[0], pos[1] - c[1])
            a0 = math.atan2(pos[1] - c[1], pos[0] - c[0])
            a1 = math.atan2(tgt[1] - c[1], tgt[0] - c[0])
            sw = a1 - a0
            sw = -((-sw) % (2 * math.pi)) if g == 2 else sw % (2 * math.pi)
            if abs(sw) < 1e-12:
                sw = -2 * math.pi if g == 2 else 2 * math.pi
            k = max(2, int(abs(sw) * r / step))
            a = a0 + sw * np.linspace(0, 1, k + 1)
            pts = np.c_[c[0] + r * np.cos(a), c[1] + r * np.sin(a)]
            pts[0], pts[-1] = pos[:2], tgt[:2]
        if knife_down is None:
            on = spindle in (3, 4) and s > 0
        else:
            z0, z1 = pos[2], tgt[2]
            on = z0 is not None and z1 is not None and max(z0, z1) <= knife_down + 1e-9
        out.append({"line": i, "g": g, "pts": pts, "on": on, "s": s, "f": f,
                    "z0": pos[2], "z1": tgt[2]})
        pos = tgt
    return out


def ring(geom) -> list[list[float]]:
    return np.asarray(geom.exterior.coords)[:-1].tolist()


def make_layout(origin=(0.0, 0.0)) -> dict:
    """Three pieces: a disc with a hole, notch and mark; a three-lobed curve; a square."""
    disc = Point(150, 150).buffer(80, quad_segs=64)
    hole = Point(150, 150).buffer(20, quad_segs=32)
    t = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    r = 100 + 25 * np.sin(3 * t)
    lobes = np.c_[500 + r * np.cos(t), 200 + r * np.sin(t)]
    sq = box(700, 50, 900, 300)
    return {
        "version": 1, "units": "mm", "width": 1000, "length": 1000, "gap": 10,
        "origin": list(origin),
        "pieces": [
            {"id": "disc#1", "name": "disc", "transform": [[1, 0, 0], [0, 1, 0]],
             "outline": ring(disc),
             "holes": [np.asarray(hole.exterior.coords)[:-1][::-1].tolist()],
             "notches": [{"at": [230, 150], "direction": [1, 0]}],
             "marks": [[150, 100]], "grainline": None},
            {"id": "lobes#1", "name": "lobes", "transform": [[1, 0, 0], [0, 1, 0]],
             "outline": lobes.tolist(), "holes": [],
             "notches": [{"at": lobes[0].tolist(), "direction": [-1, 0]},
                         {"at": lobes[100].tolist(), "direction": [0, 0]}],
             "marks": [], "grainline": None},
            {"id": "front#1", "name": "front (x)$%!?~\nG0 X9999", "transform": None,
             "outline": ring(sq), "holes": [], "notches": [{"at": [800, 50], "direction": [0, 1]}],
             "marks": [[800, 100], [750, 200]], "grainline": [[800, 60], [800, 290]]},
        ],
    }


def piece_polygons(layout: dict) -> dict[str, Polygon]:
    ox, oy = layout.get("origin", [0, 0])
    out = {}
    for p in layout["pieces"]:
        holes = [np.asarray(h) + [ox, oy] for h in p.get("holes") or []]
        out[p["id"]] = Polygon(np.asarray(p["outline"]) + [ox, oy], holes)
    return out
