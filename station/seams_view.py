"""`station inspect PATTERN.dxf`: the seams the station found, listed and drawn.

A CAD pattern carries no seams, so the station infers them (:mod:`solver.seams`); an operator
confirms them by looking: every seam drawn on both of its pieces in its own colour with its
number, so a wrong pair stands out in a glance, and ``--seams S.json`` corrects it.
"""

from __future__ import annotations

import argparse
import colorsys
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import shapely

from solver.garment.dxf import DxfPattern, read_dxf_pattern
from solver.garment.dxf_garment import DEFAULT_ALLOWANCE_MM, garment_of_pattern
from solver.garment.model import Garment
from solver.seams import Seam, SewPiece
from solver.seams.outline import point_at, sub_loop
from station.cliargs import dxf_allowance

__all__ = ["DxfInspection", "add_dxf_arguments", "draw_seams", "inspect_dxf"]

PIECE_GAP_MM = 60.0
UNSURE = 0.5  # a seam less confident than this is marked "?" (station.toml seams.confirm_below)


@dataclass
class DxfInspection:
    """What reading a DXF pattern found: the garment, its seams and the reader's notes."""

    pattern: DxfPattern
    garment: Garment
    seams: list[Seam]
    pieces: list[SewPiece]

    def folds(self) -> list[tuple[int, np.ndarray]]:
        """(piece, (2,2) line) of each piece cut on the fold: its mirror line (layer 6)
        across its sew line, the piece's centre seam with itself."""
        out = []
        for i, (p, sew) in enumerate(zip(self.pattern.cut_list(), self.pieces, strict=True)):
            if p.fold is None or not np.ptp(p.fold, axis=0).any():
                continue
            d = (p.fold[1] - p.fold[0]) / np.linalg.norm(p.fold[1] - p.fold[0])
            reach = float(np.ptp(sew.loop, axis=0).sum())  # the line, long enough to cross
            across = shapely.LineString([p.fold[0] - reach * d, p.fold[0] + reach * d])
            inside = shapely.Polygon(sew.loop).intersection(across)
            if not inside.is_empty and inside.length > 0:
                ends = np.asarray(shapely.get_coordinates(inside))[[0, -1]]
                out.append((i, ends))
        return out

    def unsure(self, below: float) -> list[int]:
        """The numbers (1..) of the seams less confident than ``below``."""
        return [k + 1 for k, s in enumerate(self.seams) if s.confidence < below]

    def annotate(self, summary: dict) -> None:
        """Add each seam line's confidence and source, and the DXF's own facts, to
        ``summary`` (:func:`station.commands.inspect.garment_summary`)."""
        for line in summary["seam_line_list"]:
            seam = self._seam_of(line)
            line["confidence"] = seam.confidence if seam else 0.0
            line["source"] = seam.source if seam else "inferred"
        summary["dxf"] = self._facts()

    def _seam_of(self, line: dict) -> Seam | None:
        """The seam a garment seam line was made of: between the same two pieces, the one
        of the closest length (a seam line is one seam unless two seams meet end to end)."""
        pair = {line["piece_a"], line["piece_b"]}
        return _closest([s for s in self.seams if {s.piece_a, s.piece_b} == pair],
                        line["length_mm"])

    def _facts(self) -> dict:
        """The DXF's own facts: sizes, units, the reader's notes, pieces, inferred seams."""
        return {
            "sizes": self.pattern.sizes, "sample_size": self.pattern.sample_size,
            "units": self.pattern.units, "notes": self.pattern.notes,
            "pieces": [{"name": p.name, "size": p.size, "quantity": p.quantity,
                        "sew_line": p.sew_source, "cut_on_fold": p.fold is not None,
                        "notches": len(p.notches), "turn_points": len(p.turns),
                        "drill_holes": len(p.drills), "internal_lines": len(p.internal),
                        "carried_from_sample_size": list(p.carried)}
                       for p in self.pattern.pieces],
            "seams": [{"number": k + 1, "piece_a": self.pieces[s.piece_a].name,
                       "piece_b": self.pieces[s.piece_b].name,
                       "length_mm": round(s.length_mm, 1), "confidence": s.confidence,
                       "source": s.source} for k, s in enumerate(self.seams)],
            "centre_seams": [{"piece": self.pieces[i].name,
                              "line": np.round(line, 3).tolist(),
                              "length_mm": round(float(np.linalg.norm(line[1] - line[0])), 1),
                              "source": "fold (layer 6): the piece mirrored onto itself"}
                             for i, line in self.folds()],
        }


def _closest(seams: list[Seam], length: float) -> Seam | None:
    return min(seams, key=lambda s: abs(s.length_mm - length), default=None)


def add_dxf_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of a command that reads a DXF-AAMA/ASTM pattern as a garment."""
    parser.add_argument("--seams", metavar="S.json",
                        help='declare or veto a DXF\'s seams: {"seams": [{"a": PIECE, '
                        '"a_ends": [[x, y], [x, y]], "b": PIECE, "b_ends": [...]}], '
                        '"not_seams": [[PIECE, PIECE]]}')
    parser.add_argument("--png", metavar="SEAMS.png",
                        help="draw a DXF's seams, numbered, each in its own colour on both "
                        "pieces")


def read_dxf(path: str | Path, *, size: str | None = None, units: str | None = None,
             allowance_mm: float = DEFAULT_ALLOWANCE_MM,
             allowance_from: str = "the default seam allowance",
             seams: str | Path | None = None) -> DxfInspection:
    """A DXF pattern as a garment with its seams inferred (with what the ``seams`` file
    declares or vetoes); a sew line the file lacks is its cut line inset by
    ``allowance_mm``, whose origin ``allowance_from`` names in the pattern's notes."""
    pattern = read_dxf_pattern(path, size=size, units=units, allowance_mm=allowance_mm,
                               allowance_from=allowance_from)
    return DxfInspection(pattern, *garment_of_pattern(pattern, seams))


def inspect_dxf(args: argparse.Namespace) -> DxfInspection:
    """Read ``args.garment`` (a DXF) at ``args.size``, infer its seams with ``args.seams``
    (a sew line the file lacks: inset by `station.cliargs.dxf_allowance`); the reader's
    warnings go to stderr, one line each, so ``--json`` stays clean."""
    allowance_mm, allowance_from = dxf_allowance(args)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        found = read_dxf(args.garment, size=getattr(args, "size", None), units=args.units,
                         allowance_mm=allowance_mm, allowance_from=allowance_from,
                         seams=getattr(args, "seams", None))
    for w in caught:
        print(f"station {args.command}: warning: {w.message}", file=sys.stderr)
    return found


def seams_document(found: DxfInspection) -> dict:
    """The seams found, as a ``--seams`` file declares them (each piece by name, each end
    a point of its sew line), with the pieces and each seam's confidence beside them: the
    file an operator confirms as it is, or edits."""
    def ends(i: int, start: float, end: float) -> list[list[float]]:
        return np.round(point_at(found.pieces[i], np.array([start, end])), 3).tolist()

    return {"pieces": [p.name for p in found.pieces],
            "seams": [{"number": k + 1, "a": found.pieces[s.piece_a].name,
                       "a_ends": ends(s.piece_a, s.a_start, s.a_end),
                       "b": found.pieces[s.piece_b].name,
                       "b_ends": ends(s.piece_b, s.b_start, s.b_end),
                       "length_mm": round(s.length_mm, 1),
                       "confidence": round(s.confidence, 3), "source": s.source}
                      for k, s in enumerate(found.seams)],
            "not_seams": []}


def _dashed(image: np.ndarray, ends: np.ndarray, colour: tuple[int, int, int],
            dash_px: float = 8.0) -> None:
    """A dashed straight line between the two pixel points ``ends``."""
    n = max(int(np.linalg.norm(ends[1] - ends[0]) / dash_px), 1)
    pts = ends[0] + np.linspace(0.0, 1.0, n + 1)[:, None] * (ends[1] - ends[0])
    for a, b in zip(pts[:-1:2], pts[1::2], strict=False):
        cv2.line(image, tuple(int(v) for v in a), tuple(int(v) for v in b), colour, 2,
                 cv2.LINE_AA)


def _colour(k: int) -> tuple[int, int, int]:
    r, g, b = colorsys.hsv_to_rgb((k * 0.618034) % 1.0, 0.85, 0.85)
    return int(255 * b), int(255 * g), int(255 * r)


def draw_seams(pieces: list[SewPiece], seams: list[Seam], path: str | Path, *,
               width_px: int = 1800, unsure_below: float = UNSURE,
               folds: list[tuple[int, np.ndarray]] = ()) -> None:
    """Every piece in a row (sew line in grey) and every seam in its own colour on both of
    its pieces, numbered at its middle on each, as the ``seams`` list numbers them (1..);
    the number of a seam less confident than ``unsure_below`` carries a "?". A piece cut on
    the fold shows its centre line (``folds``: `DxfInspection.folds`) dashed."""
    shifts, x = [], 0.0
    for p in pieces:
        lo = p.loop.min(0)
        shifts.append(np.array([x, 0.0]) - lo)
        x += float(np.ptp(p.loop[:, 0])) + PIECE_GAP_MM
    height = max(float(np.ptp(p.loop[:, 1])) for p in pieces)
    scale = (width_px - 40) / max(x, 1.0)
    h_px = int(height * scale) + 80
    image = np.full((h_px, width_px, 3), 255, np.uint8)

    def px(q: np.ndarray, i: int) -> np.ndarray:
        q = (q + shifts[i]) * scale
        return np.column_stack([q[:, 0] + 20, h_px - 40 - q[:, 1]]).astype(np.int32)

    for i, p in enumerate(pieces):
        cv2.polylines(image, [px(p.loop, i)], True, (150, 150, 150), 1, cv2.LINE_AA)
        at = px(p.loop.mean(0, keepdims=True), i)[0]
        cv2.putText(image, p.name[:24], (int(at[0]) - 40, int(at[1])),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.4, (60, 60, 60), 1, cv2.LINE_AA)
    for i, line in folds:
        _dashed(image, px(line, i), (160, 90, 0))
        at = px(line.mean(0, keepdims=True), i)[0]
        cv2.putText(image, "fold", (int(at[0]) + 4, int(at[1])), cv2.FONT_HERSHEY_SIMPLEX,
                    0.45, (160, 90, 0), 1, cv2.LINE_AA)
    for k, s in enumerate(seams):
        for i, span in ((s.piece_a, (s.a_start, s.a_end)), (s.piece_b, (s.b_start, s.b_end))):
            line = px(sub_loop(pieces[i], *span), i)
            cv2.polylines(image, [line], False, _colour(k), 3, cv2.LINE_AA)
            mid = line[len(line) // 2]
            label = f"{k + 1}{'?' if s.confidence < unsure_below else ''}"
            cv2.putText(image, label, (int(mid[0]) + 4, int(mid[1]) - 4),
                        cv2.FONT_HERSHEY_SIMPLEX, 0.5, _colour(k), 2, cv2.LINE_AA)
    unsure = sum(s.confidence < unsure_below for s in seams)
    cv2.putText(image, f"{len(seams)} seams, {unsure} unsure (?: confidence under "
                f"{unsure_below:g}); "
                "number = the seam's index in --json 'dxf.seams'",
                (20, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 1, cv2.LINE_AA)
    if not cv2.imwrite(str(path), image):
        raise OSError(f"{path}: cannot write the picture")
