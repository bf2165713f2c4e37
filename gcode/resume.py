"""Resuming a piece where its cut stopped, with a short overlap, never from its start.

A piece's strokes (tool-down runs, in cut order) are saved before its first line is
streamed (`save_strokes`); they are the reference its progress is measured on for as long
as the piece is unfinished, since a program built again later starts its contours from
wherever the head then is. While cutting, each status report's head position is matched
to the strokes (`advance`): the first point at or after the progress so far that lies
under the head, so a path that passes near itself never lets progress jump ahead. The
station journals that length; after an interruption the head's rest position (when still
trusted) carries it to where the buffered moves really stopped. The resumed piece
(`resumed_toolpath`) starts `OVERLAP_MM` before that point, so the kerf joins cleanly,
and goes on with the rest of its strokes.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from gcode.arcs import sample_path
from gcode.machine import Machine
from gcode.toolpath import PieceToolpath, open_contour

__all__ = ["OVERLAP_MM", "STROKES", "PieceStrokes", "advance", "load_strokes",
           "piece_strokes", "resumed_toolpath", "save_strokes"]

#: How far before the point reached a resumed piece starts again (mm of cut path).
OVERLAP_MM = 3.0
#: A head position within this distance of a stroke is on it (mm).
ON_PATH_MM = 0.3
STROKES = "piece-strokes.json"


@dataclass
class PieceStrokes:
    """A piece's tool-down runs in cut order: the kind of contour each belongs to
    (``outline``, ``notch``, ``mark``, ``hole``) and its points (k, 2), mm."""

    kinds: list[str]
    points: list[np.ndarray]

    @property
    def lengths(self) -> np.ndarray:
        return np.array([float(np.hypot(*np.diff(p, axis=0).T).sum()) if len(p) > 1 else 0.0
                         for p in self.points])

    @property
    def total_mm(self) -> float:
        return float(self.lengths.sum())

    @cached_property
    def segments(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every segment's start (m, 2), end (m, 2) and cut length before it (m,)."""
        return _segments(self)


def piece_strokes(toolpath: PieceToolpath) -> PieceStrokes:
    """The strokes of a toolpath, arcs sampled every 0.5 mm."""
    kinds, points = [], []
    for contour in toolpath.contours:
        for stroke in contour.strokes:
            kinds.append(contour.kind)
            points.append(sample_path(stroke, 0.5) if len(stroke) else stroke.start[None, :])
    return PieceStrokes(kinds, points)


def save_strokes(path: Path, job_id: int, strokes: dict[int, PieceStrokes]) -> None:
    """Write the strokes by store piece index durably (temporary file, fsync, rename)."""
    tmp = path.with_suffix(".tmp")
    doc = {"job": job_id, "pieces": {str(k): {"kinds": s.kinds, "points": [
        np.round(p, 4).tolist() for p in s.points]} for k, s in strokes.items()}}
    with open(tmp, "w") as f:
        json.dump(doc, f)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def load_strokes(path: Path, job_id: int) -> dict[int, PieceStrokes]:
    """What `save_strokes` wrote for this job ({} if nothing, or another job's)."""
    try:
        doc = json.loads(path.read_text())
    except (FileNotFoundError, json.JSONDecodeError):
        return {}
    if not isinstance(doc, dict) or doc.get("job") != job_id:
        return {}
    return {int(k): PieceStrokes(list(v["kinds"]), [np.asarray(p, float).reshape(-1, 2)
                                                    for p in v["points"]])
            for k, v in doc.get("pieces", {}).items()}


def _segments(strokes: PieceStrokes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every segment's start (m, 2), end (m, 2) and cut length before it (m,)."""
    a, b, before = [], [], []
    done = 0.0
    for pts in strokes.points:
        if len(pts) < 2:
            continue
        seg = np.hypot(*np.diff(pts, axis=0).T)
        a.append(pts[:-1])
        b.append(pts[1:])
        before.append(done + np.concatenate([[0.0], np.cumsum(seg)[:-1]]))
        done += float(seg.sum())
    if not a:
        return np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0)
    return np.vstack(a), np.vstack(b), np.concatenate(before)


def advance(strokes: PieceStrokes, done_mm: float, here: np.ndarray | None,
            most_mm: float = np.inf) -> float:
    """The cut length reached once the head is at ``here``: the first point of the strokes
    at or after ``done_mm``, and at most ``most_mm`` beyond it, within `ON_PATH_MM` of the
    head; ``done_mm`` if none is.

    ``most_mm`` is what the machine can have cut since the head was last seen on the path:
    a rapid between two strokes may pass over a stroke cut later, which must not count.
    """
    if here is None:
        return done_mm
    a, b, before = strokes.segments
    d = b - a
    length = np.hypot(*d.T)
    t = np.clip(np.einsum("ij,ij->i", here - a, d) / np.maximum(length ** 2, 1e-12), 0, 1)
    reach = before + t * length
    near = (np.hypot(*(a + t[:, None] * d - here).T) < ON_PATH_MM) & \
        (before + length >= done_mm - 1e-9) & (reach <= done_mm + most_mm)
    hits = np.flatnonzero(near)
    if not len(hits):
        return done_mm
    return max(done_mm, float(reach[hits[0]]))


def resumed_toolpath(toolpath: PieceToolpath, strokes: PieceStrokes, done_mm: float,
                     machine: Machine, overlap_mm: float = OVERLAP_MM) -> PieceToolpath:
    """The piece from ``overlap_mm`` before ``done_mm`` on: the stroke in progress from
    there, then every later stroke, each as it was (same kind: a mark stays a mark)."""
    start = max(0.0, done_mm - overlap_mm)
    contours = []
    before = 0.0
    for kind, pts, length in zip(strokes.kinds, strokes.points, strokes.lengths, strict=True):
        end = before + length
        if length == 0.0:  # a plunge (a knife marking a point): kept if not yet reached
            if before >= start:
                contours.append(open_contour(kind, pts, machine))
        elif end > start + 1e-9:
            contours.append(open_contour(kind, _from(pts, start - before) if before < start
                                         else pts, machine))
        before = end
    return PieceToolpath(toolpath.index, toolpath.id, toolpath.name, contours,
                         toolpath.polygon, list(toolpath.warnings))


def _from(pts: np.ndarray, at_mm: float) -> np.ndarray:
    """The polyline ``pts`` from ``at_mm`` along it to its end."""
    seg = np.hypot(*np.diff(pts, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    k = int(np.clip(np.searchsorted(cum, at_mm, side="right") - 1, 0, len(seg) - 1))
    t = (at_mm - cum[k]) / max(seg[k], 1e-12)
    first = pts[k] + (pts[k + 1] - pts[k]) * min(max(t, 0.0), 1.0)
    return np.vstack([first, pts[k + 1:]])
