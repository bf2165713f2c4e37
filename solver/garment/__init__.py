"""The garment model and its importers/exporters (OBJ with UVs, OBJ pairs, JSON specs, DXF).

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
    size: str | None = None,
    seam_allowance_mm: float | None = None,
    allowance_from: str = "--seam-allowance",
) -> Garment:
    """Load a garment from OBJ (single file or -m/-w pair), a JSON pattern specification or
    a DXF-AAMA/ASTM pattern (its seams inferred, :mod:`solver.seams`).

    ``units`` are the units of the file's coordinates (m, cm, mm, in); by default what the
    file says, else mm. ``world`` names the world-space OBJ of a pattern/world pair (found
    automatically beside ``name-m.obj``). ``resolution_mm`` is the target edge length when
    a JSON specification is triangulated. ``size`` picks a graded DXF's size (default: its
    sample size); a DXF's sew line where the file gives neither layer 14 nor its allowance
    is its cut line inset by ``seam_allowance_mm`` (default 10), whose origin
    ``allowance_from`` names in the pattern's notes.
    """
    path = Path(path)
    if units is not None:
        mm_per_unit(units)  # validate early, with the list of accepted units
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such garment file")
    suffix = path.suffix.lower()
    if size is not None and not isinstance(size, str):
        raise GarmentError(path, f"a size is a name such as '50' or 'M', got {size!r}")
    if size is not None and suffix != ".dxf":
        raise GarmentError(path, f"--size {size!r} is for a graded DXF pattern; this is {suffix}")
    if suffix == ".json":
        return load_spec(path, units=units, resolution_mm=resolution_mm)
    if suffix == ".obj":
        if world is None:
            partner = pair_partner(path)
            if partner is not None:
                pattern, world = (path, partner) if path.stem.endswith("-m") else (partner, path)
                return load_obj(pattern, units=units, world=world)
        return load_obj(path, units=units, world=world)
    if suffix == ".dxf":  # DXF-AAMA / ASTM D6673: seams inferred (solver.seams)
        from solver.garment.dxf_garment import load_dxf  # ezdxf: 0.3-0.6 s, DXF only

        return load_dxf(path, units=units, size=size, allowance_mm=seam_allowance_mm,
                        allowance_from=allowance_from)
    raise GarmentError(path, f"unknown garment format {suffix!r} (expected .obj, .json or .dxf)")
