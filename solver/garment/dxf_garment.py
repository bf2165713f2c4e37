"""A DXF-AAMA / ASTM pattern as a :class:`Garment`: pieces cut, seams inferred, meshed.

The pattern's cut list (:meth:`DxfPattern.cut_list`: quantities, left/right pairs, folds
unfolded) gives the pieces; their sew lines give the seams (:mod:`solver.seams`, or the
operator's ``--seams`` file); each piece's sew line is then sampled so that the two sides of
every seam have the same number of points, those twins share a 3D point id, and each piece
is triangulated (Shewchuk's Triangle, boundary kept as sampled). The common topology pass
(:func:`solver.garment.model.build_garment`) makes the seam lines of it, as for any garment.
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import shapely

from solver.garment.dxf import DxfPattern, DxfPiece, read_dxf_pattern
from solver.garment.errors import GarmentError
from solver.garment.model import Garment, build_garment
from solver.garment.spec import _triangulate
from solver.seams import Seam, SewPiece, infer_seams
from solver.seams.darts import open_darts
from solver.seams.declared import SeamsWord, read_seams_file
from solver.seams.outline import point_at
from solver.seams.readings import infer_on_either

__all__ = ["garment_of_pattern", "infer_pattern_seams", "load_dxf", "sew_pieces"]

RESOLUTION_MM = 20.0  # boundary sample spacing of the mesh
DEFAULT_ALLOWANCE_MM = 10.0  # a sew line the file lacks: its cut line inset by this
SEW_INSIDE_MM = 0.5  # a sew line may touch its cut line (no allowance), not cross it
GAP_MM = 100.0  # between pieces laid side by side in the pattern plane


def sew_pieces(pieces: list[DxfPiece], *, drawn: bool = False) -> list[SewPiece]:
    """The pieces as the seam inference reads them: sew line (else the cut line), the
    file's turn points and notches; names with their spaces made ``_`` (G-code piece
    markers and job files carry a name as one word). ``drawn``: a sew line that is a guess
    (`DxfPiece.sew_guessed_mm`) replaced by the drawn line, its darts opened, the other
    reading of :mod:`solver.seams.readings`."""
    return [SewPiece(re.sub(r"\s+", "_", p.name.strip()), _line(p, drawn), p.turns,
                     _notch_points(p), p.grain, p.family)
            for p in pieces]


def _notch_points(p: DxfPiece) -> np.ndarray:
    return np.array([a for a, _ in p.notches], float).reshape(-1, 2)


def _line(p: DxfPiece, drawn: bool) -> np.ndarray:
    if p.sew is None:
        return p.cut
    if drawn and p.sew_guessed_mm:
        return open_darts(p.cut, _notch_points(p), p.drills)[0]
    return p.sew


def infer_pattern_seams(cut: list[DxfPiece], word: SeamsWord | None = None
                        ) -> tuple[list[Seam], list[SewPiece], str | None]:
    """(the seams of the cut list's pieces, those pieces as sewn, a note when the seams
    were read on the drawn line): what the operator's ``word`` declares, vetoes, and the
    rest inferred, on the drawn line too where the sew line is a guess."""
    pieces = sew_pieces(cut)
    word = word if word is not None else SeamsWord()
    if not word.infer_others:
        return list(word.declared), pieces, None
    if not any(p.sew_guessed_mm for p in cut):
        return infer_seams(pieces, declared=word.declared, vetoed=word.vetoed), pieces, None
    seams, on_drawn = infer_on_either(pieces, sew_pieces(cut, drawn=True),
                                      declared=word.declared, vetoed=word.vetoed)
    inset = max(p.sew_guessed_mm for p in cut)
    note = (f"seams read on the drawn line: they agree there, not {inset:g} mm inside it "
            "(the pattern may be net, drawn on its sew line: then its cut line carries no "
            "allowance)")
    return seams, pieces, note if on_drawn else None


def _boundary_samples(piece: SewPiece, spans: list[tuple[float, float, np.ndarray]]
                      ) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """Arc positions sampling the loop: each seam span (start, end, its count + 1 sample
    positions, ends included), the rest at :data:`RESOLUTION_MM`; and each span's first
    sample index and count. Spans are disjoint intervals on the loop."""
    spans = sorted(spans, key=lambda span: span[0])
    s: list[float] = []
    firsts = []
    cursor = spans[0][0] if spans else 0.0
    origin = cursor
    for start, end, positions in spans:
        if start > cursor + 1e-6:
            n = max(int(np.ceil((start - cursor) / RESOLUTION_MM)), 1)
            s += list(np.linspace(cursor, start, n + 1)[:-1])
        firsts.append(len(s))
        s += list(positions[:-1])
        cursor = end
    end_all = origin + piece.length
    if end_all > cursor + 1e-6:
        n = max(int(np.ceil((end_all - cursor) / RESOLUTION_MM)), 1)
        s += list(np.linspace(cursor, end_all, n + 1)[:-1])
    return np.array(s), [(k, len(spans[j][2]) - 1) for j, k in enumerate(firsts)]


def _mesh(pieces: list[SewPiece], seams: list[Seam], source: Path):
    """(uv, faces, point ids, grain lines, each piece's shift into the pattern plane) of
    the pieces with the seams' twins shared."""
    spans: list[list[tuple[float, float, np.ndarray]]] = [[] for _ in pieces]
    for s in seams:  # B's samples are those sewn to A's (through its matched notches)
        on_a = np.linspace(s.a_start, s.a_end, max(int(np.ceil(s.length_mm / RESOLUTION_MM)),
                                                   1) + 1)
        spans[s.piece_a].append((s.a_start, s.a_end, on_a))
        spans[s.piece_b].append((s.b_start, s.b_end, s.b_at(on_a)[::-1]))
    uv, faces, point_ids, offset, first_of, grains, shifts = [], [], [], 0, {}, {}, []
    x = 0.0
    for i, p in enumerate(pieces):
        s, firsts = _boundary_samples(p, spans[i])
        loop = point_at(p, s)
        shift = np.array([x - loop[:, 0].min(), -loop[:, 1].min()])
        shifts.append(shift)
        tri = _triangulate(source, p.name, loop + shift, RESOLUTION_MM)
        if p.grain is not None:
            grains[i] = tuple(map(tuple, (p.grain + shift).tolist()))
        verts, tris = tri["vertices"], tri["triangles"]
        uv.append(verts)
        faces.append(tris + offset)
        point_ids.append(np.arange(offset, offset + len(verts)))
        for (start, _, _), (k, _) in zip(sorted(spans[i], key=lambda span: span[0]), firsts,
                                         strict=True):
            first_of[(i, round(start, 6))] = (offset, k, len(s))
        offset += len(verts)
        x += float(np.ptp(loop[:, 0])) + GAP_MM
    ids = np.concatenate(point_ids)
    for seam in seams:  # a_start meets b_end: A's k-th sample is B's (count - k)-th
        count = max(int(np.ceil(seam.length_mm / RESOLUTION_MM)), 1)
        oa, ka, na = first_of[(seam.piece_a, round(seam.a_start, 6))]
        ob, kb, nb = first_of[(seam.piece_b, round(seam.b_start, 6))]
        for k in range(count + 1):
            va = oa + (ka + k) % na
            vb = ob + (kb + count - k) % nb
            ids[ids == ids[vb]] = ids[va]
    return np.vstack(uv), np.vstack(faces), ids, grains, shifts


def garment_of_pattern(pattern: DxfPattern, seams_file: str | Path | None = None
                       ) -> tuple[Garment, list[Seam], list[SewPiece]]:
    """The garment of a read pattern (its cut list, seams inferred with what the operator's
    ``seams_file`` declares or vetoes), the seams with their confidences and the pieces
    they refer to (for the report and pictures)."""
    cut = pattern.cut_list()
    if not cut:
        raise GarmentError(pattern.source, "no piece to cut (every Quantity is 0)")
    word = read_seams_file(seams_file, sew_pieces(cut)) if seams_file else None
    seams, pieces, note = infer_pattern_seams(cut, word)
    if note and note not in pattern.notes:  # said where the reader's warnings go too (the
        pattern.notes.append(note)  # job log, the command's stderr): the cut may lack allowance
        warnings.warn(f"{pattern.source}: {note}", stacklevel=2)
    uv, faces, ids, grains, shifts = _mesh(pieces, seams, Path(pattern.source))
    g = build_garment(uv, faces, ids, xyz=None, source=pattern.source, kind="dxf",
                      units_in_file=pattern.units,
                      piece_names=[p.name for p in pieces],
                      grainlines=grains)
    g.cut_outlines = _file_cut_lines(cut, pieces, shifts)
    g.folds = {i: p.fold + shifts[i] for i, p in enumerate(cut)
               if p.fold is not None and np.ptp(p.fold, axis=0).any()}
    return g, seams, pieces


def _file_cut_lines(cut: list[DxfPiece], pieces: list[SewPiece], shifts: list[np.ndarray]
                    ) -> dict[int, np.ndarray]:
    """Each piece's cut line as the file draws it (layer 1), laid where its piece lies: the
    station cuts there, not on an offset of the sew line. A cut line that does not hold
    its sew line (a file whose layer 14 strays outside layer 1) is not used, and said."""
    out = {}
    for i, (p, sew, shift) in enumerate(zip(cut, pieces, shifts, strict=True)):
        ring = np.asarray(p.cut, float) + shift
        if not shapely.Polygon(ring).buffer(SEW_INSIDE_MM).contains(
                shapely.Polygon(sew.loop + shift)):
            warnings.warn(f"piece {p.name!r}: its sew line crosses its cut line (layer 1); "
                          "cut on the station's allowance instead", stacklevel=3)
            continue
        out[i] = ring
    return out


def load_dxf(path: str | Path, *, units: str | None = None, size: str | None = None,
             allowance_mm: float | None = None, allowance_from: str = "--seam-allowance"
             ) -> Garment:
    """A DXF-AAMA/ASTM file as a garment (sample size unless ``size``), seams inferred; a
    sew line the file lacks is its cut line inset by ``allowance_mm`` (default
    :data:`DEFAULT_ALLOWANCE_MM`), whose origin ``allowance_from`` names."""
    if allowance_mm is None:
        allowance_mm, allowance_from = DEFAULT_ALLOWANCE_MM, "the default seam allowance"
    pattern = read_dxf_pattern(path, size=size, units=units, allowance_mm=allowance_mm,
                               allowance_from=allowance_from)
    return garment_of_pattern(pattern)[0]
