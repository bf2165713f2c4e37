"""DXF-AAMA / ASTM D6673 pattern files: read pieces for nesting, and write them back.

A cutting room receives its pieces from pattern CAD (Gerber AccuMark, Lectra, CLO) as
AutoCAD R12 DXF where every piece is a BLOCK (placed by one INSERT) and the meaning of an
entity is its layer number (AAMA/ASTM D6673):

    1 boundary (cut line; often split in several open POLYLINEs), 4 notches,
    6 mirror line (the block holds half the piece), 7 grain line, 8 internal lines,
    11 internal cut-outs, 13 drill holes, 14 sew line (stitch line),
    84 ASTM boundary curve (duplicate of 1)

and TEXT entities in the block say ``Piece Name:``, ``Size:``, ``Quantity:``; the
modelspace says ``Units: ENGLISH`` (inches) or ``METRIC`` (mm). ezdxf does the file
format; :mod:`solver.garment.dxf` interprets the layers (sizes, grading, quantities, folds)
and this module makes nesting pieces of them.
"""

from __future__ import annotations

import math
import re
import warnings
from pathlib import Path

import ezdxf
import numpy as np

from solver.garment.dxf import DxfPattern, read_dxf_pattern
from solver.garment.dxf_file import read_blocks, texts
from solver.nest.instance import Piece, affine, rotation

__all__ = ["dxf_sizes", "pieces_of_pattern", "read_dxf_aama", "write_dxf_aama"]


def dxf_sizes(path: str | Path) -> list[str]:
    """The sizes present in a graded file, in file order."""
    _, _, blocks = read_blocks(path)
    return [s for s in dict.fromkeys(texts(ents).get("size") for _, ents in blocks) if s]


def pieces_of_pattern(pattern: DxfPattern, *, name_sizes: bool = False) -> list[Piece]:
    """The nesting pieces of a read pattern: ``Quantity: 0`` left out (told once), an even
    quantity cut as left/right pairs (``mirrored_pair``), an odd one as that many copies.
    ``name_sizes`` appends the size to each name (several sizes in one marker)."""
    pieces = []
    for p in pattern.pieces:
        if p.quantity == 0:
            warnings.warn(f"{pattern.source}: piece {p.name!r} size {p.size}: Quantity 0, "
                          "not cut", stacklevel=2)
            continue
        paired = p.in_pairs
        piece = Piece(f"{p.name} {p.size}" if name_sizes and p.size else p.name, p.cut,
                      quantity=p.quantity // 2 if paired else p.quantity,
                      mirrored_pair=paired, grainline=p.grain,
                      notches=list(p.notches), marks=p.drills, holes=list(p.holes),
                      size=p.size, sew_line=p.sew)
        if p.grain is not None:  # reference frame: the grain along the roll (+x)
            d = p.grain[1] - p.grain[0]
            if np.linalg.norm(d) > 0:
                piece.base = rotation(-math.degrees(math.atan2(d[1], d[0])))
        pieces.append(piece)
    return pieces


def read_dxf_aama(path: str | Path, *, size: str | list[str] | None = None,
                  units: str | None = None, unfold: bool = True,
                  allowance_mm: float | None = None) -> list[Piece]:
    """Pieces (mm) of a DXF-AAMA/ASTM file to nest: outline = the cut line (layer 1).

    The sew line is layer 14 where the piece has one, else the cut line moved inward by
    ``allowance_mm`` (None or 0: the piece has no sew line). ``size`` picks the size(s)
    of a graded file (default: its sample size, else its first); ``unfold`` makes whole
    pieces of half pieces that carry a mirror line (layer 6). Each piece's ``base`` turns
    its grain line along +x. What the reader decided is in :func:`read_dxf_pattern`.
    """
    pattern = read_dxf_pattern(path, size=size, units=units, allowance_mm=allowance_mm,
                               unfold_folds=unfold)
    many = size is not None and not isinstance(size, str) and len(size) > 1
    return pieces_of_pattern(pattern, name_sizes=many)


def write_dxf_aama(pieces: list[Piece], path: str | Path, *, style: str = "station") -> None:
    """Write pieces (mm, input coordinates) as DXF-AAMA R12: one BLOCK + INSERT per piece.

    Each block holds the outline = cut line (layer 1, closed), the sew line (14, closed,
    where the piece has one), cut-outs (11), the grain line (7),
    notches as POINTs with their direction angle (4), drill holes (13) and the TEXTs
    ``Piece Name``, ``Size``, ``Quantity``; it round-trips through :func:`read_dxf_aama`.
    """
    doc = ezdxf.new("R12")
    msp = doc.modelspace()
    for k, line in enumerate([f"Style Name: {style}", "Units: METRIC"]):
        msp.add_text(line, dxfattribs={"layer": "1", "height": 5.0, "insert": (0, -10 * k)})
    used = set()
    for p in pieces:
        bname = re.sub(r"[^A-Za-z0-9_ -]", "_", f"{p.name}_{p.size}" if p.size else p.name)
        while bname in used:
            bname += "_"
        used.add(bname)
        blk = doc.blocks.new(name=bname)
        blk.add_polyline2d([tuple(map(float, q)) for q in p.outline], close=True,
                           dxfattribs={"layer": "1"})
        if p.sew_line is not None:
            blk.add_polyline2d([tuple(map(float, q)) for q in p.sew_line], close=True,
                               dxfattribs={"layer": "14"})
        for h in p.holes:
            blk.add_polyline2d([tuple(map(float, q)) for q in h], close=True,
                               dxfattribs={"layer": "11"})
        if p.grainline is not None:
            blk.add_line(tuple(map(float, p.grainline[0])), tuple(map(float, p.grainline[1])),
                         dxfattribs={"layer": "7"})
        for at, d, _ in p.notches:
            blk.add_point(tuple(map(float, at)), dxfattribs={
                "layer": "4", "angle": math.degrees(math.atan2(d[1], d[0])) % 360.0})
        for m in np.asarray(p.marks, float).reshape(-1, 2):
            blk.add_point(tuple(map(float, m)), dxfattribs={"layer": "13"})
        texts = [f"Piece Name: {p.name}", f"Quantity: {p.quantity}"]
        if p.size:
            texts.insert(1, f"Size: {p.size}")
        x0, y0 = p.outline.min(0)
        for k, line in enumerate(texts):
            blk.add_text(line, dxfattribs={"layer": "1", "height": 3.0,
                                           "insert": (float(x0), float(y0) - 5.0 * (k + 1))})
        msp.add_blockref(bname, (0, 0), dxfattribs={"layer": "1"})
    doc.saveas(Path(path))


def transformed(piece: Piece, m: np.ndarray) -> Piece:
    """A copy of ``piece`` with every geometric part mapped by the (2, 3) affine ``m``."""
    lin = m[:, :2]
    return Piece(piece.name, affine(m, piece.outline), piece.quantity, piece.orientations,
                 piece.mirrored_pair, holes=[affine(m, h) for h in piece.holes],
                 grainline=None if piece.grainline is None else affine(m, piece.grainline),
                 notches=[(affine(m, a)[0], lin @ d, h) for a, d, h in piece.notches],
                 marks=affine(m, piece.marks), size=piece.size,
                 sew_line=None if piece.sew_line is None else affine(m, piece.sew_line),
                 allowance=piece.allowance)
