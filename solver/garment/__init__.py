"""The garment model and its importers/exporters (OBJ with UVs, OBJ pairs, JSON specs).

    g = load_garment("pants.obj", units="m")
    g.uv, g.faces, g.seam_edges, g.seam_lines, g.piece_outline(0)
"""

from __future__ import annotations

from pathlib import Path

from solver.garment.errors import GarmentError
from solver.garment.model import Garment, SeamLine, build_garment
from solver.garment.obj import load_obj, pair_partner, save_obj
from solver.garment.spec import load_spec
from solver.garment.spec_save import save_spec
from solver.units import MM_PER_UNIT, UNIT_CHOICES, mm_per_unit

__all__ = [
    "Garment",
    "GarmentError",
    "MM_PER_UNIT",
    "SeamLine",
    "UNIT_CHOICES",
    "build_garment",
    "load_garment",
    "save_obj",
    "save_spec",
]


def load_garment(
    path: str | Path,
    *,
    units: str | None = None,
    world: str | Path | None = None,
    resolution_mm: float | None = None,
) -> Garment:
    """Load a garment from OBJ (single file or -m/-w pair) or a JSON pattern specification.

    ``units`` are the units of the file's coordinates (m, cm, mm, in); by default what the
    file says, else mm. ``world`` names the world-space OBJ of a pattern/world pair (found
    automatically beside ``name-m.obj``). ``resolution_mm`` is the target edge length when
    a JSON specification is triangulated.
    """
    path = Path(path)
    if units is not None:
        mm_per_unit(units)  # validate early, with the list of accepted units
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such garment file")
    suffix = path.suffix.lower()
    if suffix == ".json":
        return load_spec(path, units=units, resolution_mm=resolution_mm)
    if suffix == ".obj":
        if world is None:
            partner = pair_partner(path)
            if partner is not None:
                pattern, world = (path, partner) if path.stem.endswith("-m") else (partner, path)
                return load_obj(pattern, units=units, world=world)
        return load_obj(path, units=units, world=world)
    raise GarmentError(path, f"unknown garment format {suffix!r} (expected .obj or .json)")
