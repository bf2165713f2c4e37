"""Resuming a piece where its cut stopped, with a short overlap, never from its start.

A piece's strokes (tool-down runs, in cut order) are saved before its first line is
streamed (`save_strokes`); they are the reference its progress is measured on for as long
as the piece is unfinished, since a program built again later starts its contours from
wherever the head then is. While cutting, a stroke counts as cut once the sync line after
it (`gcode.program.STROKE_SYNC`, a block of role `Sync.STROKE`) is answered; within the
stroke in progress, each status report's head position is matched to that stroke only
(`advance`), and no further than the feed can have cut since, so a rapid crossing a stroke
not yet cut never counts. The
station journals that length; after a kill the head's rest position (at the end of the
last buffered line, when still trusted) carries it to where the machine really stopped.
The resumed piece (`resumed_toolpath`) starts `OVERLAP_MM` before that point, so the
kerf joins cleanly, and goes on with the rest of its strokes.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from gcode.arcs import sample_path
from gcode.blocks import Sync
from gcode.machine import Machine
from gcode.program import Program
from gcode.toolpath import PieceToolpath, open_contour

__all__ = ["OVERLAP_MM", "STROKES", "PieceStrokes", "advance", "load_strokes",
           "piece_strokes", "resumed_toolpath", "save_strokes", "stroke_syncs",
           "strokes_before"]

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
    def segments(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """See `_segments`."""
        return _segments(self)


def piece_strokes(toolpath: PieceToolpath) -> PieceStrokes:
    """The strokes of a toolpath, arcs sampled every 0.5 mm."""
    kinds, points = [], []
    for contour in toolpath.contours:
        for stroke in contour.strokes:
            kinds.append(contour.kind)
            points.append(sample_path(stroke, 0.5) if len(stroke) else stroke.start[None, :])
    return PieceStrokes(kinds, points)


def save_strokes(path: Path, job_id: int, strokes: dict[int, PieceStrokes],
                 stopped: tuple[int, np.ndarray] | None = None) -> None:
    """Write the strokes by store piece index durably (temporary file, fsync, rename);
    ``stopped``: (piece, head position) where a safe stop left the journal exact."""
    tmp = path.with_suffix(".tmp")
    doc: dict = {"job": job_id, "pieces": {str(k): {"kinds": s.kinds, "points": [
        np.round(p, 4).tolist() for p in s.points]} for k, s in strokes.items()}}
    if stopped is not None:
        doc["stopped"] = {"piece": int(stopped[0]), "at": np.round(stopped[1], 4).tolist()}
    with open(tmp, "w") as f:
        json.dump(doc, f)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def load_strokes(path: Path, job_id: int
                 ) -> tuple[dict[int, PieceStrokes], tuple[int, np.ndarray] | None]:
    """What `save_strokes` wrote for this job: the strokes ({} if nothing, or another
    job's) and where a safe stop left the head, if one did since."""
    try:
        doc = json.loads(path.read_text())
    except (FileNotFoundError, json.JSONDecodeError):
        return {}, None
    if not isinstance(doc, dict) or doc.get("job") != job_id:
        return {}, None
    strokes = {int(k): PieceStrokes(list(v["kinds"]), [np.asarray(p, float).reshape(-1, 2)
                                                       for p in v["points"]])
               for k, v in doc.get("pieces", {}).items()}
    stop = doc.get("stopped")
    return strokes, None if stop is None else (int(stop["piece"]),
                                               np.asarray(stop["at"], float))


def _segments(strokes: PieceStrokes) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every segment's start (m, 2), end (m, 2), cut length before it (m,) and stroke (m,)."""
    a, b, before, which = [], [], [], []
    done = 0.0
    for j, pts in enumerate(strokes.points):
        if len(pts) < 2:
            continue
        seg = np.hypot(*np.diff(pts, axis=0).T)
        a.append(pts[:-1])
        b.append(pts[1:])
        before.append(done + np.concatenate([[0.0], np.cumsum(seg)[:-1]]))
        which.append(np.full(len(seg), j))
        done += float(seg.sum())
    if not a:
        return np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), np.zeros(0, int)
    return np.vstack(a), np.vstack(b), np.concatenate(before), np.concatenate(which)


def advance(strokes: PieceStrokes, done_mm: float, here: np.ndarray | None,
            stroke: int | None = None, most_mm: float = np.inf) -> float:
    """The cut length reached once the head is at ``here``: the first point of the strokes
    (of stroke number ``stroke`` only, if given) at or after ``done_mm``, and at most
    ``most_mm`` beyond it, within `ON_PATH_MM` of the head; ``done_mm`` if none is.

    While cutting, the strokes before the one in progress are known cut from their syncs,
    and matching only that one means a rapid crossing a later stroke never counts; the
    rapid into a closed outline crosses the outline itself near its end, which
    ``most_mm`` (what the feed can have cut since) keeps out.
    """
    if here is None:
        return done_mm
    a, b, before, which = strokes.segments
    d = b - a
    length = np.hypot(*d.T)
    t = np.clip(np.einsum("ij,ij->i", here - a, d) / np.maximum(length ** 2, 1e-12), 0, 1)
    reach = before + t * length
    near = (np.hypot(*(a + t[:, None] * d - here).T) < ON_PATH_MM) & \
        (before + length >= done_mm - 1e-9) & (reach <= done_mm + most_mm)
    if stroke is not None:
        near &= which == stroke
    hits = np.flatnonzero(near)
    if not len(hits):
        return done_mm
    return max(done_mm, float(reach[hits[0]]))


def strokes_before(strokes: PieceStrokes, count: int) -> float:
    """The cut length of the first ``count`` strokes."""
    return float(strokes.lengths[:count].sum())


def stroke_syncs(program: Program) -> dict[str, np.ndarray]:
    """Piece id -> the wire ordinals (counting only blocks that carry code, as the streamer
    sends them) of its stroke syncs, in order: stroke i is cut once ordinal i is answered."""
    wire = np.cumsum([bool(b.code) for b in program.blocks]) - 1
    return {r.id: np.array([wire[k] for k in range(r.first_line, r.sync_line)
                            if program.blocks[k].sync == Sync.STROKE], int)
            for r in program.pieces}


def resumed_toolpath(toolpath: PieceToolpath, strokes: PieceStrokes, done_mm: float,
                     machine: Machine, overlap_mm: float = OVERLAP_MM
                     ) -> tuple[PieceToolpath, int]:
    """The piece from ``overlap_mm`` before ``done_mm`` on: the stroke in progress from
    there, then every later stroke, each as it was (same kind: a mark stays a mark); and
    the number of the first stroke kept."""
    start = max(0.0, done_mm - overlap_mm)
    contours = []
    first: int | None = None
    before = 0.0
    for j, (kind, pts, length) in enumerate(zip(strokes.kinds, strokes.points,
                                                strokes.lengths, strict=True)):
        end = before + length
        keep = before >= start if length == 0.0 else end > start + 1e-9
        if keep:  # a plunge (a knife marking a point) is kept if not yet reached
            contours.append(open_contour(kind, _from(pts, start - before)
                                         if 0.0 < length and before < start else pts, machine))
            first = j if first is None else first
        before = end
    piece = PieceToolpath(toolpath.index, toolpath.id, toolpath.name, contours,
                          toolpath.polygon, list(toolpath.warnings))
    return piece, len(strokes.points) if first is None else first


def _from(pts: np.ndarray, at_mm: float) -> np.ndarray:
    """The polyline ``pts`` from ``at_mm`` along it to its end."""
    seg = np.hypot(*np.diff(pts, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    k = int(np.clip(np.searchsorted(cum, at_mm, side="right") - 1, 0, len(seg) - 1))
    t = (at_mm - cum[k]) / max(seg[k], 1e-12)
    first = pts[k] + (pts[k + 1] - pts[k]) * min(max(t, 0.0), 1.0)
    return np.vstack([first, pts[k + 1:]])
