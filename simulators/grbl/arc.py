"""G2/G3 arcs cut into chords, as GRBL's mc_arc does: centre from R or from I/J/K, the sweep's
direction, and as many chords as keep each within the `$12` arc tolerance."""

from __future__ import annotations

import math

import numpy as np

import simulators.grbl.codes as C
from simulators.grbl.parser_state import GrblError, ParserState

#: plane (G17/G18/G19) -> (first axis, second axis, linear axis)
PLANES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}


def arc_points(
    state: ParserState,
    values: dict[str, float],
    target: np.ndarray,
    clockwise: bool,
    settings: dict[int, float],
    unit: float,
) -> tuple[np.ndarray, set[str]]:
    """Segment a G2/G3 arc into chords within the `$12` arc tolerance: ((k,3) points, the
    words the arc used)."""
    a0, a1, lin = PLANES[state.plane]
    pos = state.position
    if not any(k in values for k in ("XYZ"[a0], "XYZ"[a1])):
        raise GrblError(C.E_GCODE_NO_AXIS_WORDS_IN_PLANE)
    dx, dy = target[a0] - pos[a0], target[a1] - pos[a1]
    if "R" in values:
        if np.allclose(pos, target):
            raise GrblError(C.E_GCODE_INVALID_TARGET)
        i_off, j_off, r = _centre_from_radius(values["R"] * unit, dx, dy, clockwise)
        used = {"R"}
    else:
        i_off, j_off, r = _centre_from_offsets(values, ("IJK"[a0], "IJK"[a1]), dx, dy, unit)
        used = {n for n in "IJK" if n in values}
    cx, cy = pos[a0] + i_off, pos[a1] + j_off
    start = math.atan2(pos[a1] - cy, pos[a0] - cx)
    travel = _sweep(start, math.atan2(target[a1] - cy, target[a0] - cx), clockwise)
    tol = float(settings[12])
    n = int(abs(0.5 * travel * r) / math.sqrt(tol * (2 * r - tol))) if r > tol else 0
    n = max(n, 1)
    t = np.arange(1, n + 1) / n
    ang = start + travel * t
    pts = np.repeat(pos[None, :], n, axis=0).astype(float)
    pts[:, a0] = cx + r * np.cos(ang)
    pts[:, a1] = cy + r * np.sin(ang)
    pts[:, lin] = pos[lin] + (target[lin] - pos[lin]) * t
    pts[-1] = target
    return pts, used


def _centre_from_radius(r: float, dx: float, dy: float,
                        clockwise: bool) -> tuple[float, float, float]:
    """(centre offset along the plane's two axes, radius) of an R-form arc; a negative R
    asks for the arc over 180 degrees."""
    h2 = 4.0 * r * r - dx * dx - dy * dy
    if h2 < 0:
        raise GrblError(C.E_GCODE_ARC_RADIUS_ERROR)
    h = -math.sqrt(h2) / math.hypot(dx, dy)
    if not clockwise:
        h = -h
    if r < 0:
        h, r = -h, -r
    return 0.5 * (dx - dy * h), 0.5 * (dy + dx * h), r


def _centre_from_offsets(values: dict[str, float], names: tuple[str, str], dx: float,
                         dy: float, unit: float) -> tuple[float, float, float]:
    """(centre offset, radius) of an I/J/K-form arc; the end must lie on the circle within
    GRBL's tolerance (0.005 mm, or 0.5 mm and 0.1 % of the radius)."""
    if not any(n in values for n in names):
        raise GrblError(C.E_GCODE_NO_OFFSETS_IN_PLANE)
    i_off = values.get(names[0], 0.0) * unit
    j_off = values.get(names[1], 0.0) * unit
    r = math.hypot(i_off, j_off)
    delta = abs(math.hypot(dx - i_off, dy - j_off) - r)
    if delta > 0.005 and (delta > 0.5 or delta > 0.001 * r):
        raise GrblError(C.E_GCODE_INVALID_TARGET)
    return i_off, j_off, r


def _sweep(start: float, end: float, clockwise: bool) -> float:
    """Signed angle from ``start`` to ``end`` in the arc's direction; a full circle when
    they meet."""
    travel = end - start
    eps = 5e-7
    if clockwise:
        if travel >= -eps:
            travel -= 2 * math.pi
    elif travel <= eps:
        travel += 2 * math.pi
    return travel
