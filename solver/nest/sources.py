"""Turn the station's inputs into a :class:`NestProblem`: instances, DXF, PLACEMENT.json.

The DXF reader's stack is imported where a DXF is read: ezdxf costs 0.3-0.6 s, measured
against ``--time``, which instances and placements need not pay. The garment stack
(0.16 s on top of the nesting imports) is imported with the module.
"""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import numpy as np
import shapely

from solver.garment import load_garment
from solver.garment.allowance import AllowanceRules
from solver.garment.grain import grain_lines
from solver.garment.notches import cut_ready, dart_marks
from solver.garment.symmetrise import symmetrise_as_recorded
from solver.garment.symmetry import fit_pairs
from solver.geometry import FLIP, rotation_matrix
from solver.jsonfile import read_json
from solver.nest.instance import NestProblem, Piece, PiecePair, load_esicup
from solver.placement import Placement
from solver.units import mm_per_unit
from untrusted import limits


def kind_of(path: str | Path) -> str:
    """"dxf", "instance" (ESICUP strip packing) or "placement" (PLACEMENT.json)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file")
    if path.suffix.lower() == ".dxf":
        return "dxf"
    if path.suffix.lower() == ".json":
        d = read_json(path)
        if isinstance(d, dict) and "strip_height" in d:
            return "instance"
        if isinstance(d, dict) and "pieces" in d and "fabric" in d:
            return "placement"
    raise ValueError(f"{path}: not a DXF-AAMA file, a strip-packing instance or a PLACEMENT.json")


def garment_pieces(garment, rules=None, names: list[str] | None = None,
                   placement=None) -> list[Piece]:
    """One nesting piece per garment piece: cut line, sew line, allowances, notches, grain.

    The outline to place and cut is the cut line (the sew line plus its allowance, see
    :mod:`solver.garment.allowance`); the sew line travels along for pictures and DXF.
    Notches: the seam notches (with ``placement``, on the print's lattice lines), plus any
    the file gives (moved out to the cut line); marks: a drill mark near each dart's point.
    """
    rules = rules or AllowanceRules()
    cuts, notches = cut_ready(garment, rules, placement)
    names = names or list(garment.piece_names)
    grains = getattr(garment, "grainlines", None) or {}
    pieces = []
    for i, cut in enumerate(cuts):
        slits = [slit for q in notches[i] for slit in q.slits()]
        for at in garment.notches.get(i, []):  # the file's notches sit on the sew line
            at = np.asarray(at, float)
            ring = cut.cut.exterior
            edge = np.asarray(ring.interpolate(ring.project(shapely.Point(at))).coords[0])
            d = at - edge
            dist = float(np.linalg.norm(d))
            if dist > 1e-9:
                depth = min(rules.notch_depth_mm, dist / 2)
                slits.append((edge, d / dist, depth))
        grain = grains.get(i)
        pieces.append(Piece(str(names[i]), cut.outline, holes=cut.holes, notches=slits,
                            grainline=None if grain is None else np.asarray(grain, float),
                            marks=dart_marks(garment, i), sew_line=cut.sew_outline,
                            allowance=cut.sew_outline_allowance))
    return pieces


def placement_pairs(garment, placement) -> list[PiecePair]:
    """The placement's left/right pairs with their mirror maps (pattern coordinates), so
    that a layout can be checked to keep each "mirror" pair's print mirrored: the maps
    the alignment recorded, else fitted on ``garment``."""
    modes = {(int(i), int(j)): str(m) for i, j, m in placement.pairs}
    maps = (placement.report.get("symmetry") or {}).get("mirror_maps")
    if maps is not None and len(maps) == len(placement.pairs):
        # the maps the alignment kept the pairs by (a refit on a reshaped pattern differs)
        return [PiecePair(int(i), int(j), str(m), np.asarray(mm, float).reshape(2, 3))
                for (i, j, m), mm in zip(placement.pairs, maps)]
    return [PiecePair(p.first, p.second,
                      modes.get((p.first, p.second), modes.get((p.second, p.first), "same")),
                      np.column_stack([p.rotation @ FLIP, p.translation]))
            for p in fit_pairs(garment, list(modes))]


def pieces_from_placement(path: str | Path, **options):
    """(pieces, print) of `placement_input` (its pairs left out)."""
    pieces, fabric, _ = placement_input(path, **options)
    return pieces, fabric


def placement_input(path: str | Path, *, orientations=None, units: str | None = None,
                    allowance=None, fabric=None, plain: bool = False):
    """Garment pieces at their aligned position on the print, that print and the pieces'
    left/right pairs, read from a PLACEMENT.json and the garment file it names (see
    :func:`placed_pieces`).

    ``units`` are the garment file's (Berkeley OBJ files are in metres and do not say so).
    """
    path = Path(path)
    placement = Placement.load(path)
    if not placement.garment:
        raise ValueError(f"{path}: the placement names no garment file")
    gpath = Path(placement.garment)
    if not gpath.is_absolute() and (path.parent / gpath).exists():
        gpath = path.parent / gpath
    garment = load_garment(gpath, units=units or placement.garment_units)
    if garment.n_pieces != placement.n_pieces:
        raise ValueError(f"{path}: {placement.n_pieces} placed pieces but garment {gpath} has "
                         f"{garment.n_pieces}")
    if placement.report.get("symmetrise"):  # aligned on the symmetrised pattern: cut that
        try:
            garment = symmetrise_as_recorded(garment, placement.report["symmetrise"]).garment
        except ValueError as exc:
            raise ValueError(f"{path}: {exc}") from None
    return placed_pieces(garment, placement, orientations=orientations, allowance=allowance,
                         fabric=fabric, plain=plain)


def placed_pieces(garment, placement, *, orientations=None, allowance=None, fabric=None,
                  plain: bool = False):
    """Garment pieces at their aligned position on the print, that print, and the pieces'
    left/right pairs (:func:`placement_pairs`).

    The placement gives per piece ``p2D = R p_wp + t``; the piece's reference frame is
    wallpaper (= fabric) space, so ``base = [R^T | -R^T t]``: the same rigid map carries
    the sew line and the cut line, so the print along the sew lines (E_fit) is unchanged.
    ``allowance`` (:class:`solver.garment.allowance.AllowanceRules`, default: the defaults)
    makes the cut lines; ``fabric`` (a Wallpaper) replaces the placement's print, which the
    balance notches follow (``plain``: no print, notches by spacing alone). The turns
    allowed on the fabric follow the placement's grain rule: 0 and 180 degrees (keeps the
    grain), 0 only with a nap, any with the grain off; ``orientations`` overrides it.
    ``placement`` is not changed.
    """
    if orientations is None:
        rule = placement.grain_rule
        orientations = ((0.0,) if rule.get("nap") else
                        None if "tolerance_deg" in rule and rule["tolerance_deg"] is None
                        else (0.0, 180.0))
    if fabric is not None:
        placement = dataclasses.replace(placement, fabric=fabric)
    pieces = garment_pieces(garment, allowance, placement.piece_names or None,
                            None if plain else placement)
    for i, piece in enumerate(pieces):
        a = placement.angles[i]
        r = rotation_matrix(a)
        piece.base = np.column_stack([r.T, -r.T @ placement.translations[i]])
        piece.orientations = (None if orientations is None
                              else tuple(float(o) % 360.0 for o in orientations))
    if placement.grains:  # the grain the alignment kept, drawn where the file has none
        lines = grain_lines(garment, [g["grain_deg"] for g in placement.grains])
        for i, piece in enumerate(pieces):
            if piece.grainline is None:
                piece.grainline = lines[i]
    return pieces, placement.fabric, placement_pairs(garment, placement)


def placement_problem(garment, placement, *, width: float, length: float | None = None,
                      gap: float = 0.0, allowance=None, plain: bool = False) -> NestProblem:
    """The marker problem of one aligned garment, from the objects alignment handed over
    (the station's plan: no trip through PLACEMENT.json and the garment file)."""
    pieces, fabric, pairs = placed_pieces(garment, placement, allowance=allowance, plain=plain)
    return assemble_problem(pieces, width=width, length=length, gap=gap,
                            fabric=None if plain else fabric, what="the garment",
                            allowance=(allowance or AllowanceRules()).to_dict(),
                            piece_pairs=pairs)


def load_problem(paths: list[str | Path], *, width: float | None = None,
                 length: float | None = None, gap: float = 0.0, fabric=None,
                 sizes: list[str] | None = None, units: str | None = None,
                 quantity: int = 1, pairs: bool = False,
                 keepouts: list[np.ndarray] | None = None, allowance=None,
                 default_width: float | None = None, plain: bool = False) -> NestProblem:
    """Several inputs (garments, sizes) in one marker; ``fabric`` overrides any given print.

    ``units`` are those of a DXF or garment file that does not state them; ``allowance``
    (AllowanceRules) makes garments' cut lines, and a DXF's sew line where it has none.
    The width is ``width``, else the input's, else ``default_width`` (the station's roll).
    ``plain``: nest on plain cloth whatever print the inputs name.
    """
    pieces: list[Piece] = []
    piece_pairs: list[PiecePair] = []
    found_width, found_fabric = None, None
    for path in paths:
        kind = kind_of(path)
        if kind == "instance":  # coordinates in --units when given (never ignored)
            inst = load_esicup(path)
            k = 1.0 if units is None else mm_per_unit(units)
            for p in inst.pieces:
                p.outline = p.outline * k
            pieces += inst.pieces
            found_width = found_width or inst.width * k
        elif kind == "dxf":
            from solver.nest.dxf_aama import read_dxf_aama  # ezdxf: 0.3-0.6 s, DXF only

            seam = None if allowance is None else allowance.seam_mm
            pieces += read_dxf_aama(path, size=sizes, units=units, allowance_mm=seam)
            if fabric is not None and not plain:  # said, never silent (issue 34)
                warnings.warn(f"{path}: a DXF's pieces are nested as the file turns them, "
                              "not matched to the print; for a print-matched marker run "
                              "`station align` on it and nest its PLACEMENT.json",
                              stacklevel=2)
        else:
            got, wp, got_pairs = placement_input(path, units=units, allowance=allowance,
                                                 fabric=fabric, plain=plain)
            piece_pairs += [dataclasses.replace(p, first=p.first + len(pieces),
                                                second=p.second + len(pieces))
                            for p in got_pairs]
            pieces += got
            found_fabric = found_fabric or wp
    width = width if width is not None else found_width or default_width
    if width is None:
        raise ValueError("give the fabric width with --width (the input does not say it)")
    rules = None  # reported where this run made cut lines (garments), not a DXF's own
    if any(kind_of(p) == "placement" for p in paths):
        rules = (allowance or AllowanceRules()).to_dict()
    return assemble_problem(pieces, width=width, length=length, gap=gap,
                            fabric=None if plain else fabric or found_fabric,
                            quantity=quantity, pairs=pairs, keepouts=keepouts, allowance=rules,
                            what=", ".join(map(str, paths)), piece_pairs=piece_pairs)


def assemble_problem(pieces: list[Piece], *, width: float, length: float | None, gap: float,
                     fabric, quantity: int = 1, pairs: bool = False,
                     keepouts: list[np.ndarray] | None = None, allowance: dict | None = None,
                     what: str = "the input",
                     piece_pairs: list[PiecePair] | None = None) -> NestProblem:
    """One marker problem from pieces gathered from any inputs: copies counted against the
    demand limit (``what`` names the inputs in the refusal), names made unique;
    ``piece_pairs`` are the left/right pairs a layout must keep (indices into ``pieces``)."""
    for p in pieces:
        p.quantity *= quantity
        p.mirrored_pair = p.mirrored_pair or pairs
    copies = sum(p.quantity * (2 if p.mirrored_pair else 1) for p in pieces)
    if copies > limits.MAX_DEMAND:
        raise ValueError(f"{what}: {copies:,} copies to nest; at most "
                         f"{limits.MAX_DEMAND:,} are nested at once")
    names = [p.name for p in pieces]
    for k, p in enumerate(pieces):  # several inputs may reuse names: keep ids unique
        if names.count(p.name) > 1:
            p.name = f"{p.name}.{names[:k].count(names[k]) + 1}"
    return NestProblem(pieces, float(width), length, gap, fabric, list(keepouts or []),
                       allowance=allowance, pairs=list(piece_pairs or []))
