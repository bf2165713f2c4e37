"""Turn the station's inputs into a :class:`NestProblem`: instances, DXF, PLACEMENT.json."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from solver.jsonfile import read_json
from solver.nest.instance import NestProblem, Piece, load_esicup
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


def pieces_from_placement(path: str | Path, *, orientations=None,
                          units: str | None = None):
    """Garment pieces at their aligned position on the print, and that print.

    PLACEMENT.json gives per piece ``p2D = R p_wp + t``; the piece's reference frame is
    wallpaper (= fabric) space, so ``base = [R^T | -R^T t]``. ``units`` are the garment
    file's (Berkeley OBJ files are in metres and do not say so). The turns allowed on the
    fabric follow the placement's grain rule: 0 and 180 degrees (keeps the grain), 0 only
    with a nap, any with the grain off; ``orientations`` overrides it.
    """
    from solver.garment import load_garment
    from solver.placement import Placement

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
    names = placement.piece_names or list(garment.piece_names)
    if orientations is None:
        rule = placement.grain_rule
        orientations = ((0.0,) if rule.get("nap") else
                        None if "tolerance_deg" in rule and rule["tolerance_deg"] is None
                        else (0.0, 180.0))
    grains = dict(getattr(garment, "grainlines", None) or {})
    if placement.grains:  # the grain the alignment kept, drawn where the file has none
        from solver.garment.grain import grain_lines

        lines = grain_lines(garment, [g["grain_deg"] for g in placement.grains])
        grains = {i: grains.get(i, lines[i]) for i in range(garment.n_pieces)}
    notch_pts = getattr(garment, "notches", None) or {}
    pieces = []
    for i in range(garment.n_pieces):
        a = placement.angles[i]
        r = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        base = np.column_stack([r.T, -r.T @ placement.translations[i]])
        outline = garment.piece_outline(i)
        grain = grains.get(i)
        centre = outline.mean(0)
        notches = []
        for at in notch_pts.get(i, []):  # the garment gives positions: point them inwards
            at = np.asarray(at, float)
            d = centre - at
            notches.append((at, d / max(float(np.linalg.norm(d)), 1e-12)))
        pieces.append(Piece(str(names[i]), outline, orientations=orientations, base=base,
                            holes=list(garment.piece_holes(i)), notches=notches,
                            grainline=None if grain is None else np.asarray(grain, float)))
    return pieces, placement.fabric


def load_problem(paths: list[str | Path], *, width: float | None = None,
                 length: float | None = None, gap: float = 0.0, fabric=None,
                 sizes: list[str] | None = None, units: str | None = None,
                 quantity: int = 1, pairs: bool = False,
                 keepouts: list[np.ndarray] | None = None) -> NestProblem:
    """Several inputs (garments, sizes) in one marker; ``fabric`` overrides any given print.

    ``units`` are those of a DXF or garment file that does not state them.
    """
    pieces: list[Piece] = []
    found_width, found_fabric = None, None
    for path in paths:
        kind = kind_of(path)
        if kind == "instance":
            inst = load_esicup(path)
            pieces += inst.pieces
            found_width = found_width or inst.width
        elif kind == "dxf":
            from solver.dxf_aama import read_dxf_aama

            pieces += read_dxf_aama(path, size=sizes, units=units)
        else:
            got, wp = pieces_from_placement(path, units=units)
            pieces += got
            found_fabric = found_fabric or wp
    for p in pieces:
        p.quantity *= quantity
        p.mirrored_pair = p.mirrored_pair or pairs
    copies = sum(p.quantity * (2 if p.mirrored_pair else 1) for p in pieces)
    if copies > limits.MAX_DEMAND:
        raise ValueError(f"{', '.join(map(str, paths))}: {copies:,} copies to nest; at most "
                         f"{limits.MAX_DEMAND:,} are nested at once")
    names = [p.name for p in pieces]
    for k, p in enumerate(pieces):  # several inputs may reuse names: keep ids unique
        if names.count(p.name) > 1:
            p.name = f"{p.name}.{names[:k].count(names[k]) + 1}"
    width = width if width is not None else found_width
    if width is None:
        raise ValueError("give the fabric width with --width (the input does not say it)")
    return NestProblem(pieces, float(width), length, gap, fabric or found_fabric,
                       list(keepouts or []))
