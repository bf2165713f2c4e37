"""An order through the job's steps: each garment (style, size, copy) loaded and aligned as
its own garment, then every piece of the order in one marker.

The steps take one garment each (`station.steps.__init__`), so an order calls them per
garment. Copies of one style and size are loaded and aligned once: the alignment is
seeded, so a second run would give the same placement; each copy still is its own garment
in the report and the marker, its pieces labelled with its garment and size.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import solver.garment as garment_files
from solver.garment import Garment
from solver.garment.allowance import AllowanceRules
from solver.nest.budget import Deadline
from solver.nest.instance import NestProblem, Piece, PiecePair
from solver.nest.layout import Layout, verify_layout
from solver.nest.solve import nest
from solver.nest.sources import assemble_problem, placed_pieces
from solver.placement import Placement
from solver.wallpaper import Wallpaper
from station.order import Order, OrderGarment

ALIGNED_KIND = "aligned order"  # the "kind" of what `align ORDER` and a job write
AlignOne = Callable[[Garment, OrderGarment], Placement]  # the command's or job's alignment


@dataclass
class OrderedGarment:
    """One garment of an order: what the order asked, the pattern loaded, where the print
    lies on it."""

    item: OrderGarment
    garment: Garment
    placement: Placement

    def report(self) -> dict[str, Any]:
        """The garment's line in ``align ORDER --json``: its E_fit, random and aligned."""
        r = self.placement.report  # on plain cloth nothing was aligned: no E_fit
        return {"garment": self.item.label, "pattern": str(self.item.pattern),
                "size": self.item.size, "copy": self.item.copy,
                "pieces": self.garment.n_pieces,
                **{k: r[k] for k in ("e_fit_random_mm2", "e_fit_aligned_mm2",
                                     "ratio_aligned_random") if k in r}}


def placement_dict(a: OrderedGarment) -> dict[str, Any]:
    """The garment's PLACEMENT, every piece carrying its garment and size."""
    d = a.placement.to_dict()
    for piece in d["pieces"]:
        piece["garment"], piece["size"] = a.item.label, a.item.size
    return d


def write_aligned(order: Order, aligned: list[OrderedGarment], path: str | Path) -> None:
    d = {"kind": ALIGNED_KIND, "order": order.to_dict(),
         "garments": [a.report() | {"placement": placement_dict(a)} for a in aligned]}
    Path(path).write_text(json.dumps(d, indent=1) + "\n")


#: (mm, where from) a DXF pattern's cut line is inset by where the file gives no sew line
Inset = tuple[float, str]


def load_order_garment(item: OrderGarment, inset: Inset | None = None) -> Garment:
    """The garment's pattern in mm, in its size (a DXF's missing sew line: ``inset``, by
    default 10 mm)."""
    more = {} if inset is None else {"seam_allowance_mm": inset[0], "allowance_from": inset[1]}
    return garment_files.load_garment(item.pattern, units=item.units, size=item.size, **more)


def align_order(order: Order, align_one: AlignOne, inset: Inset | None = None,
                loaded: Mapping[tuple, Garment] | None = None) -> list[OrderedGarment]:
    """Every garment of ``order`` aligned by ``align_one`` (once per style and size);
    ``loaded``: patterns already read, by (pattern, size, units) (a job's DXF styles with
    their seams as the operator confirmed them)."""
    done: dict[tuple, tuple[Garment, Placement]] = {}
    out = []
    for item in order.garments:
        key = (item.pattern, item.size, item.units)
        if key not in done:
            garment = (loaded or {}).get(key) or load_order_garment(item, inset)
            done[key] = garment, align_one(garment, item)
        garment, placement = done[key]
        placement = dataclasses.replace(placement, garment=str(item.pattern),
                                        garment_units=item.units or placement.garment_units)
        out.append(OrderedGarment(item, garment, placement))
    return out


def labelled_pieces(aligned: OrderedGarment, *, allowance: AllowanceRules | None,
                    fabric: Wallpaper | None, plain: bool
                    ) -> tuple[list[Piece], Wallpaper, list[PiecePair]]:
    """The garment's pieces on its print position, each named and labelled with its
    garment and size (so LAYOUT, pictures and G-code say whose piece it is)."""
    pieces, wallpaper, pairs = placed_pieces(aligned.garment, aligned.placement,
                                             allowance=allowance, fabric=fabric, plain=plain)
    for p in pieces:
        p.name = f"{aligned.item.label}.{p.name}"
        p.garment = aligned.item.label
        p.size = aligned.item.size
    return pieces, wallpaper, pairs


def order_problem(aligned: list[OrderedGarment], *, width: float, length: float | None = None,
                  gap: float = 0.0, allowance: AllowanceRules | None = None,
                  fabric: Wallpaper | None = None, plain: bool = False,
                  keepouts: list[np.ndarray] | None = None) -> NestProblem:
    """One marker problem holding every piece of the order; each garment's left/right
    pairs kept (indices shifted to the order's piece list); no piece on a keep-out."""
    pieces: list[Piece] = []
    pairs: list[PiecePair] = []
    found = None
    for a in aligned:
        got, wallpaper, got_pairs = labelled_pieces(a, allowance=allowance, fabric=fabric,
                                                    plain=plain)
        pairs += [dataclasses.replace(p, first=p.first + len(pieces),
                                      second=p.second + len(pieces)) for p in got_pairs]
        pieces += got
        found = found or wallpaper
    return assemble_problem(pieces, width=width, length=length, gap=gap,
                            fabric=None if plain else fabric or found,
                            allowance=(allowance or AllowanceRules()).to_dict(),
                            keepouts=keepouts, what="the order", piece_pairs=pairs)


def nest_order(problem: NestProblem, *, seconds: float, seed: int = 0,
               progress: Callable[[str], None] | None = None, method: str = "auto") -> Layout:
    """The verified marker of the order's problem; a fault is a ValueError."""
    layout = nest(problem, time_limit=Deadline(seconds), seed=seed, progress=progress,
                  method=method)
    faults = verify_layout(layout, problem)
    if faults:
        raise ValueError(f"the order's marker failed verification: {faults[0]} "
                         f"({len(faults)} faults)")
    return layout


def pieces_per_garment(pieces: list[Any]) -> dict[str, dict[str, Any]]:
    """``{garment: {"size": s, "pieces": n}}`` of layout pieces (or anything with
    ``garment`` and ``size``), in the order met: how the marker counts per garment."""
    out: dict[str, dict[str, Any]] = {}
    for p in pieces:
        key = p.garment or "-"
        out.setdefault(key, {"size": p.size, "pieces": 0})["pieces"] += 1
    return out
