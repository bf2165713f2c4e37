"""Small plane geometry that every part of the solver needs: rotations, areas, arc-length
resampling and the closest point of a polygon.

One home, so that a sign convention (counter-clockwise positive, ``R(a) = [[c, -s], [s, c]]``)
or a numerical guard is written once. Everything is vectorised over its first axes;
arrays of points are ``(n, 2) float`` in mm, faces ``(F, 3) int``. This module imports
nothing of the project and only NumPy, so any solver module (the print's
:mod:`solver.wallpaper` too, which vision loads) can use it without an import circle or
start-up cost.
"""

from __future__ import annotations

import math

import numpy as np

FLIP = np.diag([-1.0, 1.0])  # mirror across the pattern's y axis (left piece <-> right piece)


# ---------------------------------------------------------------------- rotations


def rotation_matrices(angles: np.ndarray) -> np.ndarray:
    """``(...)`` angles in radians -> ``(..., 2, 2)`` rotation matrices ``[[c, -s], [s, c]]``."""
    c, s = np.cos(angles), np.sin(angles)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def rotate(angles: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``R(angles) x`` for ``(...)`` angles and ``(..., 2)`` vectors, without building
    matrices."""
    c, s = np.cos(angles), np.sin(angles)
    return np.stack([c * x[..., 0] - s * x[..., 1], s * x[..., 0] + c * x[..., 1]], -1)


def rotate_back(angles: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``R(angles)^T x``: the inverse rotation of :func:`rotate`."""
    c, s = np.cos(angles), np.sin(angles)
    return np.stack([c * x[..., 0] + s * x[..., 1], c * x[..., 1] - s * x[..., 0]], -1)


def rotation_matrix(angle: float) -> np.ndarray:
    """(2, 2) rotation by one scalar ``angle`` (radians), computed with :mod:`math`
    (a scalar path: no array dispatch for one matrix)."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s], [s, c]])


def rotation_affine(deg: float) -> np.ndarray:
    """(2, 3) affine map ``[R | 0]`` rotating by ``deg`` degrees about the origin."""
    return np.column_stack([rotation_matrix(math.radians(deg)), np.zeros(2)])


# ---------------------------------------------------------------------- areas


def edge_vectors(uv: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, ...]:
    """x and y of each face's edge vectors 0->1 and 0->2, as contiguous (F,) arrays
    (gathering x and y apart is several times faster than slicing a gathered (F,3,2))."""
    x, y = np.ascontiguousarray(uv[:, 0]), np.ascontiguousarray(uv[:, 1])
    i, j, k = faces.T
    x0, y0 = x[i], y[i]
    return x[j] - x0, y[j] - y0, x[k] - x0, y[k] - y0


def signed_areas(uv: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F,) signed triangle areas of ``faces`` over ``uv`` (positive = counter-clockwise)."""
    ax, ay, bx, by = edge_vectors(uv, faces)
    return 0.5 * (ax * by - ay * bx)


def polygon_area(poly: np.ndarray) -> float:
    """Signed area of a closed polygon (n, 2), last point not repeated (shoelace;
    positive = counter-clockwise)."""
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


# ---------------------------------------------------------------------- curves


def resample_polyline(poly: np.ndarray, n: int) -> np.ndarray:
    """n+1 points at equal arc length along an open polyline (ends kept exactly)."""
    seg = np.linalg.norm(np.diff(poly, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if s[-1] == 0:
        return np.repeat(poly[:1], n + 1, axis=0)
    target = np.linspace(0.0, s[-1], n + 1)
    out = np.column_stack([np.interp(target, s, poly[:, 0]), np.interp(target, s, poly[:, 1])])
    out[0], out[-1] = poly[0], poly[-1]
    return out


def resample_closed(poly: np.ndarray, n: int) -> np.ndarray:
    """(n, 2) points evenly spaced by arc length around a closed polygon, from ``poly[0]``."""
    return resample_polyline(np.vstack([poly, poly[:1]]), n)[:-1]


def closest_on_polygon(points: np.ndarray, poly: np.ndarray, chunk: int = 256) -> np.ndarray:
    """(n, 2) closest point of the closed polygon ``poly`` to each of ``points``.

    Vectorised over the polygon's segments, in chunks of ``chunk`` points so that fine
    outlines (thousands of vertices) stay within a few megabytes."""
    d = np.roll(poly, -1, axis=0) - poly
    len2 = np.maximum((d * d).sum(1), 1e-300)
    out = np.empty((len(points), 2))
    for k in range(0, len(points), chunk):
        p = points[k:k + chunk]
        rel = p[:, None, :] - poly[None, :, :]
        t = np.clip(np.einsum("nkj,kj->nk", rel, d) / len2, 0, 1)
        foot = poly[None] + t[..., None] * d[None]
        best = np.argmin(((p[:, None, :] - foot) ** 2).sum(-1), axis=1)
        out[k:k + chunk] = foot[np.arange(len(p)), best]
    return out
