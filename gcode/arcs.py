"""G2/G3 arc fitting: turn dense polylines into a few arcs and lines within a chordal tolerance.

Greedy extension: from the current point, every candidate end point in a window is tried at
once (vectorised), both as a straight line and as an arc, and the longest run that stays
within the tolerance wins. Each candidate arc's centre is constrained to the perpendicular
bisector of its chord, which makes the least-squares circle fit linear in one unknown and
guarantees start and end radii agree exactly, as GRBL demands of G2/G3 (error:33).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["FittedPath", "fit_arcs", "path_length", "sample_path"]

LINE, CW, CCW = 1, 2, 3


@dataclass
class FittedPath:
    """A path from ``start`` through primitives: kind (m,) int (1 line, 2 G2, 3 G3), end (m,2),
    center (m,2) float (NaN for lines)."""

    start: np.ndarray
    kind: np.ndarray
    end: np.ndarray
    center: np.ndarray

    def __len__(self) -> int:
        return len(self.kind)

    @classmethod
    def lines(cls, points: np.ndarray) -> FittedPath:
        """The polyline itself, one line per segment (no fitting)."""
        pts = np.asarray(points, float)
        m = len(pts) - 1
        return cls(pts[0].copy(), np.full(m, LINE), pts[1:].copy(), np.full((m, 2), np.nan))


def _dedupe(points: np.ndarray, eps: float = 1e-9) -> np.ndarray:
    if len(points) < 2:
        return points
    keep = np.ones(len(points), bool)
    keep[1:] = np.hypot(*np.diff(points, axis=0).T) > eps
    return points[keep]


def _candidates(first: int, n: int, most: int = 64) -> np.ndarray:
    """End indices to try: all of them in a short window, an even subset plus the last one
    in a long window (keeps every test O(64 x window) while the window grows)."""
    step = max(1, -(-(n - first) // most))
    return np.unique(np.r_[np.arange(first, n, step), n - 1])


def _line_reach(q: np.ndarray, tol: float) -> int:
    """Largest j such that every q[k], k<=j, lies within tol of the chord q0->qj.

    The largest valid candidate, not the first failure: with noisy samples a short run can
    fail where a longer one fits, and every candidate is checked over all its points."""
    cand = _candidates(1, len(q))
    chords = q[cand]  # (J,2), q[0] == 0
    c2 = np.einsum("ij,ij->i", chords, chords)
    t = np.clip((q @ chords.T).T / np.maximum(c2, 1e-300)[:, None], 0.0, 1.0)  # (J,K)
    dx = q[None, :, 0] - t * chords[:, None, 0]
    dy = q[None, :, 1] - t * chords[:, None, 1]
    d = np.hypot(dx, dy)
    jj = cand[:, None]
    kk = np.arange(len(q))[None, :]
    d = np.where(kk <= jj, d, 0.0)
    good = np.flatnonzero(d.max(axis=1) <= tol)
    return int(cand[good[-1]]) if len(good) else 1


def _arc_reach(q: np.ndarray, tol: float, max_radius: float) -> tuple[int, np.ndarray, bool]:
    """Largest j (>=2) for which an arc q0->qj fits every vertex and segment midpoint."""
    n = len(q)
    if n < 3:
        return 0, np.zeros(2), False
    cand = _candidates(2, n)
    chords = q[cand]  # candidate end points j
    clen = np.hypot(chords[:, 0], chords[:, 1])
    nrm = np.stack([-chords[:, 1], chords[:, 0]], axis=1) / np.maximum(clen, 1e-12)[:, None]
    mid = chords / 2.0
    # |q_k - c|^2 = |c|^2  with c = mid + t*nrm  ->  2 q_k.c = |q_k|^2  ->  a_k t = b_k
    qq = np.einsum("ij,ij->i", q, q)  # (K,)
    a = 2.0 * (q @ nrm.T).T  # (J,K)
    b = qq[None, :] - 2.0 * (q @ mid.T).T
    jj = cand[:, None]
    kk = np.arange(n)[None, :]
    inside = (kk <= jj) & (kk >= 1)
    a = np.where(inside, a, 0.0)
    b = np.where(inside, b, 0.0)
    saa = (a * a).sum(axis=1)
    t = (a * b).sum(axis=1) / np.maximum(saa, 1e-300)
    centre = mid + t[:, None] * nrm  # (J,2)
    r = np.hypot(centre[:, 0], centre[:, 1])
    # radial deviation of vertices and of segment midpoints (the chord's sagitta)
    samples = np.concatenate([q, (q[1:] + q[:-1]) / 2.0])  # (2n-1,2)
    s_idx = np.concatenate([np.arange(n), np.arange(n - 1) + 0.5])
    dist = np.hypot(samples[None, :, 0] - centre[:, 0, None],
                    samples[None, :, 1] - centre[:, 1, None])
    dev = np.abs(dist - r[:, None])
    dev = np.where(s_idx[None, :] <= jj, dev, 0.0)
    # consistent turning, small steps, sweep below a full turn
    v0 = q[:-1][None, :, :] - centre[:, None, :]
    v1 = q[1:][None, :, :] - centre[:, None, :]
    cr = v0[..., 0] * v1[..., 1] - v0[..., 1] * v1[..., 0]
    dt = np.einsum("jki,jki->jk", v0, v1)
    ang = np.arctan2(cr, dt)  # (J, n-1)
    seg_in = np.arange(n - 1)[None, :] < jj
    ang = np.where(seg_in, ang, 0.0)
    pos = (np.where(seg_in, ang > 0, True)).all(axis=1)
    neg = (np.where(seg_in, ang < 0, True)).all(axis=1)
    sweep = ang.sum(axis=1)
    ok = ((dev.max(axis=1) <= tol) & (pos | neg) & (np.abs(ang).max(axis=1) < np.pi / 2)
          & (np.abs(sweep) < 1.9 * np.pi) & (r <= max_radius) & (saa > 0) & (clen > 1e-9))
    good = np.flatnonzero(ok)
    if not len(good):
        return 0, np.zeros(2), False
    last = int(good[-1])
    return int(cand[last]), centre[last], bool(sweep[last] < 0)


def fit_arcs(points: np.ndarray, tol: float, *, min_arc_points: int = 4,
             max_radius: float = 5000.0, window: int = 64, max_window: int = 256) -> FittedPath:
    """Fit an open polyline (n,2) with lines and G2/G3 arcs, each within ``tol`` of it.

    For a closed contour pass the ring with its first point repeated at the end.
    An arc must span at least ``min_arc_points`` polyline vertices; shorter runs become lines
    (collinear runs merge into one line, so straight edges also shrink).
    """
    pts = _dedupe(np.asarray(points, float))
    if len(pts) < 2:
        raise ValueError("fit_arcs needs at least two distinct points")
    kinds: list[int] = []
    ends: list[np.ndarray] = []
    centres: list[np.ndarray] = []
    i, n = 0, len(pts)
    while i < n - 1:
        w = window
        while True:
            q = pts[i:i + w] - pts[i]
            jl = _line_reach(q, tol)
            ja, c, cw = _arc_reach(q, tol, max_radius)
            best = max(jl, ja)
            if best == len(q) - 1 and i + w < n and w < max_window:
                w *= 2
                continue
            break
        if ja >= min_arc_points - 1 and ja > jl:
            kinds.append(CW if cw else CCW)
            ends.append(pts[i + ja])
            centres.append(c + pts[i])
            i += ja
        else:
            jl = max(jl, 1)
            kinds.append(LINE)
            ends.append(pts[i + jl])
            centres.append(np.array([np.nan, np.nan]))
            i += jl
    return FittedPath(pts[0].copy(), np.array(kinds, int), np.array(ends), np.array(centres))


def _arc_sweep(s: np.ndarray, e: np.ndarray, c: np.ndarray, cw: np.ndarray) -> np.ndarray:
    a0 = np.arctan2(s[:, 1] - c[:, 1], s[:, 0] - c[:, 0])
    a1 = np.arctan2(e[:, 1] - c[:, 1], e[:, 0] - c[:, 0])
    sweep = a1 - a0
    sweep = np.where(cw, -np.mod(-sweep, 2 * np.pi), np.mod(sweep, 2 * np.pi))
    # G2/G3 with start == end is a full circle
    full = np.hypot(*(e - s).T) < 1e-9
    return np.where(full, np.where(cw, -2 * np.pi, 2 * np.pi), sweep)


def path_length(path: FittedPath) -> float:
    """Total length of lines and arcs (mm)."""
    if len(path) == 0:
        return 0.0
    starts = np.vstack([path.start[None], path.end[:-1]])
    is_arc = path.kind != LINE
    seg = np.hypot(*(path.end - starts).T)
    if is_arc.any():
        c = path.center[is_arc]
        r = np.hypot(*(starts[is_arc] - c).T)
        sw = _arc_sweep(starts[is_arc], path.end[is_arc], c, path.kind[is_arc] == CW)
        seg[is_arc] = r * np.abs(sw)
    return float(seg.sum())


def sample_path(path: FittedPath, step: float = 0.5) -> np.ndarray:
    """The path as a dense polyline (k,2): arcs sampled every ``step`` mm (at most)."""
    out = [path.start[None]]
    prev = path.start
    for kind, end, c in zip(path.kind, path.end, path.center, strict=True):
        if kind == LINE:
            out.append(end[None])
        else:
            r = float(np.hypot(*(prev - c)))
            sw = float(_arc_sweep(prev[None], end[None], c[None], np.array([kind == CW]))[0])
            m = max(2, int(np.ceil(abs(sw) * r / step)))
            a0 = np.arctan2(prev[1] - c[1], prev[0] - c[0])
            a = a0 + sw * np.linspace(0, 1, m + 1)[1:]
            pts = c + r * np.stack([np.cos(a), np.sin(a)], axis=1)
            pts[-1] = end
            out.append(pts)
        prev = end
    return np.vstack(out)
