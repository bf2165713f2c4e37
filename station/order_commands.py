"""`station align ORDER` and `station nest ORDER`: an order's garments, each aligned as its
own garment, then one marker holding every piece of the order.

``align ORDER -o ALIGNED.json`` writes the order's placements (one per garment, every
piece carrying its garment and size); ``nest`` takes that file, or the order itself (then
it aligns with the same defaults first).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import untrusted
from solver.fit import fit_report
from solver.garment import Garment
from solver.nest.regions import load_keepouts
from solver.placement import Placement
from solver.wallpaper import Wallpaper
from station.cliargs import dxf_allowance, fabric_grain_deg, grain_tolerance
from station.cliload import allowance_rules
from station.errors import UserError
from station.order import Order, OrderGarment, is_order_file, read_order
from station.render import draw_fit, draw_marker, fabric_picture
from station.steps.garment import found_pairs
from station.steps.order import (
    ALIGNED_KIND,
    OrderedGarment,
    align_order,
    load_order_garment,
    nest_order,
    order_problem,
    pieces_per_garment,
    write_aligned,
)
from station.steps.place import align_garment, plain_placement


def is_order_input(path: str | Path) -> bool:
    """An order file, or what `align ORDER` wrote."""
    return is_order_file(path) or _aligned_order(path) is not None


def _aligned_order(path: str | Path) -> dict[str, Any] | None:
    path = Path(path)
    if path.suffix.lower() != ".json" or not path.is_file():
        return None
    try:
        data = untrusted.read_json(path, what="aligned order")
    except untrusted.InputError:
        return None
    return data if isinstance(data, dict) and data.get("kind") == ALIGNED_KIND else None


def aligner(command: str, fabric: Wallpaper, grain_deg: float, *, grain_tol: float | None,
            nap: bool = False, method: str = "paper", restarts: int = 15, seed: int = 0,
            symmetry: bool = True):
    """The alignment of one garment, as `station align` does it for a single garment
    (left/right pairs found and mirrored unless ``symmetry`` is off)."""

    def align_one(garment: Garment, item: OrderGarment) -> Placement:
        print(f"station {command}: aligning {item.label} ({garment.n_pieces} pieces)",
              file=sys.stderr, flush=True)
        pairs = found_pairs(garment) if symmetry else []
        return align_garment(garment, fabric, pairs, grain_deg=grain_deg, nap=nap,
                             method=method, restarts=restarts, seed=seed,
                             grain_tol_deg=grain_tol)
    return align_one


def read_aligned(path: str | Path, inset: tuple[float, str] | None = None
                 ) -> tuple[Order, list[OrderedGarment]]:
    """The order and its aligned garments back from `align ORDER`'s file; the order file
    is read again (with all its checks) and every placement must match its garment."""
    data = _aligned_order(path)
    if data is None:
        raise untrusted.InputError(path, "not an aligned order written by `station align`")
    order = read_order(untrusted.text(data["order"]["source"], path, "order.source"))
    got = data.get("garments")
    if not isinstance(got, list) or len(got) != len(order.garments):
        raise untrusted.InputError(path, f"holds {len(got or [])} garments; the order "
                                   f"{order.source} has {len(order.garments)}")
    out, loaded = [], {}
    for item, entry in zip(order.garments, got, strict=True):
        key = (item.pattern, item.size, item.units)
        if key not in loaded:
            loaded[key] = load_order_garment(item, inset)
        try:
            placement = Placement.from_dict(entry["placement"])
        except (KeyError, TypeError, ValueError) as exc:
            raise untrusted.InputError(path, f"{item.label}: bad placement ({exc})") from None
        if placement.n_pieces != loaded[key].n_pieces:
            raise untrusted.InputError(path, f"{item.label}: {placement.n_pieces} placed "
                                       f"pieces, the pattern has {loaded[key].n_pieces}")
        out.append(OrderedGarment(item, loaded[key], placement))
    return order, out


#: `station align` options that name one garment's pieces or files: an order refuses them
#: rather than apply them to every garment or drop them without a word
SINGLE_GARMENT_OPTIONS = ("size", "units", "weights", "fix", "init", "pairs", "grain_line",
                          "bias", "up", "symmetrise", "reflect", "no_rotation",
                          "no_translation", "pattern_frames")


def run_align(args: argparse.Namespace) -> int:
    """`station align ORDER`: each garment aligned, reported under ``garments``; with
    ``--png OUT.png`` one picture per garment (OUT-<garment>.png)."""
    given = [o for o in SINGLE_GARMENT_OPTIONS if getattr(args, o, None)]
    if given:
        raise UserError(f"{args.garment}: --{given[0].replace('_', '-')} is for one garment; "
                        "an order's file gives its sizes and units")
    order = read_order(args.garment)
    fabric = Wallpaper.load(args.fabric)
    t0 = time.monotonic()
    if not 1 <= args.restarts <= 10_000:
        raise ValueError(f"--restarts must be 1 to 10,000, got {args.restarts}")
    align_one = aligner("align", fabric, fabric_grain_deg(args.fabric),
                        grain_tol=grain_tolerance(args.grain), nap=args.nap,
                        method=args.method, restarts=args.restarts, seed=args.seed,
                        symmetry=not args.no_symmetry)
    aligned = align_order(order, align_one, dxf_allowance(args))
    write_aligned(order, aligned, args.output)
    rep = {"order": order.name, "ratio": order.ratio(), "fabric": fabric.group,
           "garments": [a.report() for a in aligned], "output": str(args.output),
           "seconds": round(time.monotonic() - t0, 3)}
    if args.png:
        rep["png"] = _draw_fits(aligned, args, fabric)
    if args.json:
        print(json.dumps(rep))
        return 0
    print(f"order {order.name} ({order.ratio_text()}) under {fabric.group}: "
          f"{len(aligned)} garments aligned in {rep['seconds']:.1f} s; wrote {args.output}")
    for g in rep["garments"]:
        print(f"  {g['garment']:<28s} E_fit {g['e_fit_random_mm2']:10.1f} mm² (random) -> "
              f"{g['e_fit_aligned_mm2']:10.1f} mm² (ratio {g['ratio_aligned_random']:.2f})")
    return 0


def _draw_fits(aligned: list[OrderedGarment], args: argparse.Namespace, fabric: Wallpaper
               ) -> list[str]:
    """Each garment's pieces over the print, seams coloured by mismatch, one file each."""
    out, colour_of = Path(args.png), fabric_picture(args.fabric, fabric)
    paths = []
    for a in aligned:
        path = out.with_name(f"{out.stem}-{a.item.label}{out.suffix}")
        draw_fit(a.garment, a.placement, fit_report(a.garment, a.placement), path,
                 colour_of=colour_of, title=f"{a.item.label} on {fabric.group}")
        paths.append(str(path))
    return paths


def run_nest(args: argparse.Namespace, config) -> int:
    """`station nest ORDER` (or its aligned file): one verified marker of the order."""
    if len(args.inputs) != 1 or args.size or args.quantity != 1 or args.pairs:
        raise UserError("an order is nested alone: its file gives the sizes and quantities "
                        "(drop other inputs, --size, --quantity and --pairs)")
    path = args.inputs[0]
    t0 = time.monotonic()
    fabric = Wallpaper.load(args.fabric) if args.fabric else None
    if is_order_file(path):
        if fabric is None and not args.plain:
            raise UserError(f"{path}: an order is aligned to its print first: give --fabric "
                            "(or --plain)")
        order = read_order(path)
        align_one = (aligner("nest", fabric, fabric_grain_deg(args.fabric),
                             grain_tol=None if args.grain == "off" else 1.0, nap=args.nap,
                             seed=args.seed) if fabric is not None else
                     lambda garment, _: plain_placement(garment, config, 0.0))
        aligned = align_order(order, align_one, dxf_allowance(args))
    else:
        order, aligned = read_aligned(path, dxf_allowance(args))
    problem = order_problem(aligned, width=args.width or config["nest"]["width_mm"],
                            length=args.length, gap=args.gap,
                            allowance=order.rules(allowance_rules(args, config)),
                            fabric=fabric,
                            plain=args.plain,
                            keepouts=load_keepouts(args.keepout) if args.keepout else None)
    try:
        layout = nest_order(problem, seconds=args.time, seed=args.seed, method=args.method)
    except ValueError as exc:
        raise UserError(f"{path}: {exc}") from None
    layout.save(args.output)
    counts = pieces_per_garment(layout.pieces)
    if args.png:
        draw_marker(layout, args.png,
                    title=f"order {order.name}, sizes {order.ratio_text()}")
    summary = {"order": order.name, "ratio": order.ratio(), "length": round(layout.length, 6),
               "width": layout.width, "density": round(layout.density, 6),
               "pieces": len(layout.pieces), "garments": counts,
               "seconds": round(time.monotonic() - t0, 3), "output": str(args.output)}
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"order {order.name} ({order.ratio_text()}): {summary['pieces']} pieces of "
              f"{len(counts)} garments, length {layout.length:.1f} mm, density "
              f"{layout.density:.1%} -> {args.output}")
        for name, c in counts.items():
            print(f"  {name:<28s} size {c['size'] or '-':<6s} {c['pieces']} pieces")
    return 0
