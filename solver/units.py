"""Length units of input files (garments, fabrics); everything inside is in millimetres.

Kept free of heavy imports: `solver.wallpaper` (used by vision and the simulators) needs it.
"""

from __future__ import annotations

#: millimetres per unit of each accepted file unit
MM_PER_UNIT: dict[str, float] = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4}

UNIT_CHOICES: tuple[str, ...] = ("m", "cm", "mm", "in")


def mm_per_unit(units: str) -> float:
    """Millimetres per unit; raises ValueError naming the accepted units otherwise."""
    try:
        return MM_PER_UNIT[units]
    except KeyError:
        raise ValueError(f"unknown units {units!r}: use one of {', '.join(UNIT_CHOICES)}") from None


def units_from_meter_fraction(units_in_meter: float) -> tuple[str | None, float]:
    """Map a JSON ``units_in_meter`` value to (unit name or None, mm per unit).

    The Garment-Pattern-Generator uses odd values (300 = a third of a centimetre), so the
    scale is exact even where no named unit matches.
    """
    mm = 1000.0 / float(units_in_meter)
    for name, value in MM_PER_UNIT.items():
        if abs(value - mm) <= 1e-9 * value:
            return name, value
    return None, mm
