"""How a pattern maker reads a reshaped pattern: fair outlines and seams that still sew.

Two measures of a reshape, both between the input pattern and the reshaped one (same
mesh, same vertex order), used by the report, the tests and the benchmark alike:

- `outline_roughness`: along every outline, the part of the displacement that a moving
  average over ``window_mm`` of arc length does not explain. A smooth change (a seam
  moved, a side let out) is explained by its own average; a zig-zag of a few millimetres
  is not, and the cut line would follow it.
- `seam_ease_changes`: per seam line, the length change of both sides and of their
  difference (the ease the pattern maker gave the seam). A sewer sews the two sides edge
  to edge; a change of the ease makes one side stretch or the print drift along it.
"""

from __future__ import annotations

import numpy as np

from solver.garment.notches import chain_seam_rows


def _window_mean(s: np.ndarray, f: np.ndarray, period: float, width: float) -> np.ndarray:
    """(n,k) mean of the closed piecewise-linear function through (s, f) (period
    ``period``) over [s - width/2, s + width/2], integrated exactly.

    ``s`` (n,) increasing arc lengths from 0, ``f`` (n,k) values at them.
    """
    n = len(s)
    knots = np.append(s, period)
    vals = np.vstack([f, f[:1]])
    h = np.maximum(np.diff(knots), 1e-12)
    cum = np.vstack([np.zeros((1, f.shape[1])),
                     np.cumsum(0.5 * h[:, None] * (vals[:-1] + vals[1:]), axis=0)])

    def integral(x: np.ndarray) -> np.ndarray:
        turns, rest = np.divmod(x, period)
        j = np.clip(np.searchsorted(knots, rest, side="right") - 1, 0, n - 1)
        t = (rest - knots[j])[:, None]
        slope = (vals[j + 1] - vals[j]) / h[j, None]
        return turns[:, None] * cum[-1] + cum[j] + vals[j] * t + 0.5 * slope * t * t

    return (integral(s + 0.5 * width) - integral(s - 0.5 * width)) / width


def outline_roughness(garment, uv: np.ndarray, *, window_mm: float = 10.0) -> np.ndarray:
    """(B,) mm: for every outline and hole vertex of every piece, the length of its
    displacement (``uv`` minus ``garment.uv``) minus the displacement's ``window_mm``
    moving average along the input outline's arc length.

    ``uv`` (V,2) is the reshaped pattern on ``garment``'s mesh. Zero for a rigid motion
    of a piece away from its corners, and for any displacement that varies slowly along
    the outline; a zig-zag of amplitude a over a few millimetres gives about a.
    """
    uv = np.asarray(uv, float)
    if uv.shape != garment.uv.shape:
        raise ValueError(f"uv has shape {uv.shape}, the garment's pattern {garment.uv.shape}")
    if not window_mm > 0:
        raise ValueError(f"the smoothing window must be > 0 mm, got {window_mm}")
    disp = uv - garment.uv
    out = []
    for i in range(garment.n_pieces):
        for loop in garment.piece_loops(i):
            if len(loop) < 3:
                continue
            p = garment.uv[loop]
            seg = np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1)
            s = np.concatenate([[0.0], np.cumsum(seg[:-1])])
            mean = _window_mean(s, disp[loop], float(seg.sum()), window_mm)
            out.append(np.linalg.norm(disp[loop] - mean, axis=1))
    return np.concatenate(out) if out else np.zeros(0)


def seam_side_lengths(garment, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(S,) and (S,) mm: the length of each seam line's first and second side in ``uv``."""
    e, n = garment.seam_edges, len(garment.seam_lines)
    line = np.asarray(garment.seam_line_of_edge, np.int64)
    first = np.linalg.norm(uv[e[:, 1]] - uv[e[:, 0]], axis=1) if len(e) else np.zeros(0)
    second = np.linalg.norm(uv[e[:, 3]] - uv[e[:, 2]], axis=1) if len(e) else np.zeros(0)
    return (np.bincount(line, weights=first, minlength=n),
            np.bincount(line, weights=second, minlength=n))


def sewn_drift(garment, uv: np.ndarray) -> np.ndarray:
    """(S,) mm: per seam line, how far a point of one side slides along the other when
    the seam is sewn from one end: the largest change, over every station along the
    seam, of the two sides' length difference up to it. A notch and its partner drifted
    apart by at most this much; 0 when every twin pair keeps its length difference."""
    uv = np.asarray(uv, float)
    e = garment.seam_edges
    out = np.zeros(len(garment.seam_lines))
    if not len(e):
        return out
    change = (np.linalg.norm(uv[e[:, 1]] - uv[e[:, 0]], axis=1)
              - np.linalg.norm(uv[e[:, 3]] - uv[e[:, 2]], axis=1)
              - np.linalg.norm(garment.uv[e[:, 1]] - garment.uv[e[:, 0]], axis=1)
              + np.linalg.norm(garment.uv[e[:, 3]] - garment.uv[e[:, 2]], axis=1))
    line = np.asarray(garment.seam_line_of_edge, np.int64)
    for k in range(len(out)):  # one short chain per seam line
        rows = np.flatnonzero(line == k)
        if not rows.size:
            continue
        order = chain_seam_rows(np.column_stack([e[rows, :2], rows]))[:, 2]
        out[k] = float(np.abs(np.cumsum(change[order])).max())
    return out


def seam_ease_changes(garment, uv: np.ndarray) -> list[dict]:
    """Per seam line what reshaping to ``uv`` did to it: the length change of both sides
    (mm), the change of their difference, the ease (mm; 0 for a seam that sews as
    before), and `sewn_drift` (mm)."""
    a0, b0 = seam_side_lengths(garment, garment.uv)
    a1, b1 = seam_side_lengths(garment, np.asarray(uv, float))
    drift = sewn_drift(garment, uv)
    return [{"seam": s.name or str(k), "pieces": [garment.piece_names[s.piece_a],
                                                  garment.piece_names[s.piece_b]],
             "length_mm": [round(float(a0[k]), 3), round(float(b0[k]), 3)],
             "side_change_mm": [round(float(a1[k] - a0[k]), 4),
                                round(float(b1[k] - b0[k]), 4)],
             "ease_change_mm": round(float((a1[k] - b1[k]) - (a0[k] - b0[k])), 4),
             "sewn_drift_mm": round(float(drift[k]), 4)}
            for k, s in enumerate(garment.seam_lines)]
