"""A pattern's own curves: Bezier and circular-arc edges, and their fine samples for cutting.

A specification draws necklines and armholes as curves; the solver meshes them at ~20 mm,
and a cut line made from that mesh's outline is faceted (a chord of 18 mm across a neckline
of 80 mm radius strays 0.5 mm from it). The mesh's boundary vertices lie on the curve, so
the cutter can follow the curve itself between them: each boundary edge keeps the curve's
samples between its two ends, chosen adaptively so that no chord strays more than
``tol_mm`` from the curve, and the mesh's vertices stay a subset of the fine outline (seams,
notches and alignment keep their correspondences).

The samples are stored relative to their edge's chord, ``p = a + s (b - a) + h perp(b - a)``
with ``perp(x, y) = (-y, x)`` (the convention of pygarment's control points): they follow
the edge through any rotation, translation or uniform scale of the pattern, and through a
reshape they bend with the chord rather than stay behind.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = ["CHORD_TOL_MM", "Curve", "adaptive_parameters", "edge_curve", "fine_loop",
           "from_chord", "to_chord"]

#: farthest a cut line's chord may stray from the pattern's curve, mm
CHORD_TOL_MM = 0.1
Curve = Callable[[np.ndarray], np.ndarray]  # (k,) parameters in [0, 1] -> (k,2) points
_PROBES = np.array([0.25, 0.5, 0.75])  # where each interval's chord is checked
_MAX_ROUNDS = 24


def _rel_to_abs(start: np.ndarray, end: np.ndarray, rel: Any) -> np.ndarray:
    e = end - start
    perp = np.array([-e[1], e[0]])
    rel = np.asarray(rel, dtype=float)
    return start + rel[0] * e + rel[1] * perp


def _bezier(ctrl: np.ndarray) -> Curve:
    """The Bezier curve with control polygon ``ctrl`` (k,2)."""
    n = len(ctrl) - 1
    coef = np.array([math.comb(n, i) for i in range(n + 1)], dtype=float)
    i = np.arange(n + 1)

    def at(t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)[:, None]
        return (coef * t ** i * (1 - t) ** (n - i)) @ ctrl

    return at


def _arc(start: np.ndarray, end: np.ndarray, params: Any) -> Curve:
    """SVG-style circular arc from start to end (radius, large_arc, sweep=right)."""
    radius, large_arc, right = float(params[0]), bool(params[1]), bool(params[2])
    chord = end - start
    d = float(np.hypot(*chord))
    if d == 0:
        return lambda t: np.repeat(start[None], len(t), axis=0)
    r = max(abs(radius), d / 2)  # SVG scales a too-small radius up to fit
    h = math.sqrt(max(r * r - d * d / 4, 0.0))
    left = np.array([-chord[1], chord[0]]) / d
    side = 1.0 if large_arc != right else -1.0
    centre = (start + end) / 2 + side * h * left
    a0 = math.atan2(*(start - centre)[::-1])
    a1 = math.atan2(*(end - centre)[::-1])
    if right:  # sweep flag: angle increases
        while a1 <= a0:
            a1 += 2 * math.pi
    else:
        while a1 >= a0:
            a1 -= 2 * math.pi

    def at(t: np.ndarray) -> np.ndarray:
        ang = a0 + (a1 - a0) * np.asarray(t, dtype=float)
        return centre + r * np.column_stack([np.cos(ang), np.sin(ang)])

    return at


def edge_curve(start: np.ndarray, end: np.ndarray, curvature: Any, *,
               where: str = "") -> Curve | None:
    """The curve of one specification edge (pygarment conventions), None if straight.

    ``curvature``: a list (Garment-Pattern-Generator: one quadratic control point) or an
    object ``{"type": "quadratic" | "cubic" | "circle", "params": [...]}`` (GarmentCode).
    """
    if curvature is None:
        return None
    if isinstance(curvature, list):
        return _bezier(np.array([start, _rel_to_abs(start, end, curvature), end]))
    if not isinstance(curvature, dict):
        raise ValueError(f"{where}: curvature must be a list or an object")
    kind = curvature.get("type")
    params = curvature.get("params")
    if kind in ("quadratic", "cubic"):
        need = 1 if kind == "quadratic" else 2
        if not isinstance(params, list) or len(params) != need:
            raise ValueError(f"{where}: {kind} curvature needs {need} control point(s)")
        return _bezier(np.array([start, *(_rel_to_abs(start, end, p) for p in params), end]))
    if kind == "circle":
        if not isinstance(params, list) or len(params) != 3:
            raise ValueError(f"{where}: circle curvature needs [radius, large_arc, right]")
        return _arc(start, end, params)
    raise ValueError(f"{where}: unknown curvature type {kind!r}")


def adaptive_parameters(curve: Curve, t: np.ndarray, tol_mm: float = CHORD_TOL_MM
                        ) -> np.ndarray:
    """Sorted parameters, ``t`` among them, between which every chord of ``curve`` stays
    within ``tol_mm`` of it.

    Each round checks every interval at once (the curve at a quarter, half and three
    quarters of it against the chord) and halves those that stray; a chord's error shrinks
    fourfold per halving, so a few rounds suffice. Probing three points keeps an S-bend,
    whose midpoint may sit on the chord, from passing unsplit.
    """
    t = np.unique(np.asarray(t, dtype=float))
    if not tol_mm > 0:
        raise ValueError(f"chord tolerance must be > 0 mm, got {tol_mm!r}")
    for _ in range(_MAX_ROUNDS):
        t0, t1 = t[:-1], t[1:]
        a, b = curve(t0), curve(t1)
        probe = t0[:, None] + (t1 - t0)[:, None] * _PROBES  # (k,3)
        p = curve(probe.ravel()).reshape(len(t0), len(_PROBES), 2)
        bad = _chord_distance(p, a, b).max(axis=1) > tol_mm
        if not bad.any():
            break
        t = np.sort(np.concatenate([t, 0.5 * (t0[bad] + t1[bad])]))
    return t


def _chord_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(k,m) distance of points p (k,m,2) to the segments a (k,2) -> b (k,2)."""
    d = (b - a)[:, None, :]
    len2 = np.maximum((d * d).sum(-1), 1e-300)
    u = np.clip(((p - a[:, None]) * d).sum(-1) / len2, 0.0, 1.0)
    return np.hypot(*(p - a[:, None] - u[..., None] * d).transpose(2, 0, 1))


def to_chord(a: np.ndarray, b: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(m,2) points as (s, h) in the frame of chord a -> b (see the module docstring)."""
    e = b - a
    len2 = max(float(e @ e), 1e-300)
    rel = points - a
    return np.column_stack([rel @ e, rel @ np.array([-e[1], e[0]])]) / len2


def from_chord(a: np.ndarray, b: np.ndarray, rel: np.ndarray) -> np.ndarray:
    """(m,2) points from their (s, h) chord coordinates on chord a -> b."""
    e = b - a
    return a + rel[:, :1] * e + rel[:, 1:] * np.array([-e[1], e[0]])


def fine_loop(uv: np.ndarray, loop: np.ndarray, curves: dict[tuple[int, int], np.ndarray]
              ) -> tuple[np.ndarray, np.ndarray]:
    """A mesh loop with its edges' curve samples put back: the (M,2) fine loop and, per fine
    point, the loop edge k (``loop[k] -> loop[k + 1]``) it lies on.

    ``curves`` maps a directed boundary edge (a, b) to its interior samples in (s, h) chord
    coordinates, as :func:`to_chord` gives them; an edge listed the other way round is read
    backwards, and an edge not listed stays a chord.
    """
    nxt = np.roll(loop, -1)
    pts, owner = [], []
    for k, (a, b) in enumerate(zip(loop.tolist(), nxt.tolist())):
        pts.append(uv[a][None])
        owner.append(k)
        rel = curves.get((a, b))
        if rel is None and (b, a) in curves:
            back = curves[(b, a)][::-1]
            rel = np.column_stack([1.0 - back[:, 0], -back[:, 1]])
        if rel is not None and len(rel):
            pts.append(from_chord(uv[a], uv[b], rel))
            owner.extend([k] * len(rel))
    return np.concatenate(pts), np.asarray(owner, dtype=np.int64)
