"""Stripe prints (a 1-D repeat): the grain they set, and the lattice that matches them
across the seams. Used by the daemon's plan and by the commands that read FABRIC.json."""

from __future__ import annotations

import numpy as np

import untrusted
from solver.units import mm_per_unit


def stripe_grain(fabric: dict, fabric_grain_deg: float) -> dict:
    """The grain stripes set, with what the report says about the cloth.

    Every piece is turned so that its grain runs along the stripe axis nearest the roll's
    grain (stripes along or across the grain), so the stripes cross every piece at the
    same angle. In plain nesting their positions across the seams are left as they
    fall; :func:`stripe_print` matches them.
    """
    if fabric.get("kind") != "stripes" or fabric.get("direction_deg") is None:
        return {"kind": "plain", "grain_deg": float(fabric_grain_deg)}
    along = float(fabric["direction_deg"])
    turn = (along - fabric_grain_deg + 45.0) % 90.0 - 45.0  # to the nearest stripe axis
    grain = float(fabric_grain_deg + turn)
    return {"kind": "stripes", "grain_deg": round(grain, 3),
            "period_mm": fabric.get("period"), "direction_deg": round(along, 3),
            "note": (f"stripes every {float(fabric.get('period') or 0):.3g} mm at "
                     f"{along:.1f} deg: nested on grain as plain fabric with the pieces' "
                     f"grain at {grain:.1f} deg (on the stripes); the stripes are not "
                     "matched across the seams")}


#: Step along the stripes of the lattice that stands for a stripe print (mm; the shortest
#: lattice vector a FABRIC.json may hold): a stripe runs on without end, so a piece may
#: slide along the stripes by any amount; this step is the finest the nesting and the
#: print check distinguish.
STRIPE_SLIDE_MM = 1.0


def stripe_print(fabric: dict, fabric_grain_deg: float,
                 source: str = "fabric description") -> dict:
    """FABRIC.json content that matches a 1-D stripe print across the seams.

    A stripe print repeats every ``period`` across the stripes and not at all along them:
    as a lattice it is ``w1`` = an arbitrarily short step along the stripes
    (:data:`STRIPE_SLIDE_MM`) and ``w2`` = the period across them. Its group is pm with
    the mirror across the stripes (the reflection along them), the one symmetry every
    stripe sequence has besides translations: a mirror along the stripes or a half turn
    needs a symmetric sequence and is not assumed. So a left/right pair on stripes across
    its grain (horizontal stripes on a garment) mirrors its print. The same alignment,
    reshaping and print-aware nesting as for a 2-D print then put the stripes of every
    seam's two sides at one height, and let each piece slide along its stripes freely;
    the grain runs along the stripe axis (:func:`stripe_grain`). The stripes' phase is
    not measured: every piece sees the same print, so a common shift of the pieces across
    the stripes changes nothing at the seams (pm's mirror concerns the along direction).
    """
    units = untrusted.text(fabric.get("units", "mm"), source, "units", max_len=8)
    try:
        scale = mm_per_unit(units)
    except ValueError as exc:
        raise untrusted.InputError(source, str(exc)) from None
    lo, hi = untrusted.limits.MIN_REPEAT_MM, untrusted.limits.MAX_REPEAT_MM
    period = scale * untrusted.number(fabric.get("period"), source, "period", lo=lo / scale,
                                      hi=hi / scale)
    direction = untrusted.number(fabric.get("direction_deg"), source, "direction_deg",
                                 lo=-360.0, hi=360.0)
    fabric = {**fabric, "period": period, "units": "mm"}
    cloth = stripe_grain(fabric, fabric_grain_deg)
    along = np.radians(direction)
    unit = np.array([np.cos(along), np.sin(along)])
    normal = np.array([-unit[1], unit[0]])
    slide = STRIPE_SLIDE_MM
    note = cloth["note"].replace("nested on grain as plain fabric with the pieces'",
                                 "matched across the seams, the pieces'")
    note = note.replace("; the stripes are not matched across the seams",
                        f", free to slide along them ({slide:g} mm steps)")
    return {**fabric, **cloth, "note": note, "group": "pm",
            "w1": [float(v) for v in unit * slide],
            "w2": [float(v) for v in normal * period], "origin": [0.0, 0.0]}
