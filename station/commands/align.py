"""`station align`: place the print on every piece so it runs on across the seams."""

from __future__ import annotations

import argparse
import json
import sys

import untrusted
from solver.fit import fit_report
from solver.placement import Placement
from station import order_commands as order_command
from station.cliargs import (
    add_fabric_argument,
    add_garment_arguments,
    add_grain_arguments,
    add_symmetrise_argument,
    fabric_grain_deg,
    grain_tolerance,
    load_fabric,
    picture_path,
)
from station.cliload import (
    cli_pairs,
    garment_with_grain,
    load_garment_arg,
    read_name_map,
    symmetrised_garment,
)
from station.order import is_order_file
from station.render import draw_fit, fabric_picture
from station.steps.place import align_garment


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "align",
        help="align the print across the seams (paper Sec. 4, or the global method)",
        description="Find per piece the rotation and translation of the print (p2D = R p_wp "
        "+ t) that minimise E_fit: the paper's r-RoSy rotations and Eq. (9) translations "
        "from N seeded random starts, or (--method global) a seam-tree exhaustive search "
        "with E_fit refinement that is never worse than the paper's result.",
    )
    add_garment_arguments(p)
    add_fabric_argument(p)
    p.add_argument("--method", choices=("paper", "global"), default="paper",
                   help="paper: Sec. 4 with restarts; global: closer to the global optimum")
    p.add_argument("--restarts", type=int, default=15, metavar="N",
                   help="random starts (default 15, as in the paper)")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="random seed (default 0)")
    p.add_argument("--weights", metavar="W.json",
                   help='seam weights {"seam line name or index": weight}; 0 ignores a seam')
    p.add_argument("--fix", action="append", metavar="PIECE[:rot|:trans]",
                   help="keep a piece (name or index) where --init puts it (identity if "
                   "no --init); :rot or :trans fixes only that part; repeatable")
    p.add_argument("--init", metavar="PLACEMENT.json",
                   help="placement that fixed pieces (and --no-rotation/--no-translation) keep")
    add_grain_arguments(p, rule=True)
    p.add_argument("--reflect", action="store_true",
                   help="also favour mirror symmetry across seams (paper Eqs. 7-8)")
    p.add_argument("--no-rotation", action="store_true",
                   help="keep the rotations (of --init, else 0) and align translations only")
    p.add_argument("--no-translation", action="store_true",
                   help="keep the translations (of --init, else 0) and align rotations only")
    p.add_argument("--pattern-frames", action="store_true",
                   help="ignore the drape: take seam frames from the twin pattern edges")
    p.add_argument("--pairs", metavar="P.json",
                   help='declare or veto left/right pairs: {"pairs": [[i, j]], "not_pairs": '
                   "[[k, l]]} (indices or piece names); pairs are found by default")
    p.add_argument("--no-symmetry", action="store_true",
                   help="align every piece on its own (default: left/right pairs mirror the "
                   "print, or keep the same print position where the print has no mirror "
                   "along the grain)")
    add_symmetrise_argument(p)
    p.add_argument("-o", "--output", required=True, metavar="PLACEMENT.json",
                   help="where to write the placement (angles in degrees, mm)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--png", metavar="OUT.png", type=picture_path,
                   help="draw the pieces over the print, seams coloured by mismatch")
    p.set_defaults(func=run)


def _load_weights(path: str, garment) -> dict:
    """The seam weights of W.json, their names and indices checked against the garment."""
    weights = read_name_map(path, "weight", hi=1e6)
    try:
        garment.with_seam_weights(weights)
    except ValueError as exc:
        raise untrusted.InputError(path, str(exc)) from None
    return weights


def run(args: argparse.Namespace) -> int:
    if is_order_file(args.garment):  # each garment of the order aligned as its own
        return order_command.run_align(args)
    if not 1 <= args.restarts <= 10_000:  # 10^9 restarts allocated 23 GB
        raise ValueError(f"--restarts must be 1 to 10,000, got {args.restarts}")
    tol = grain_tolerance(args.grain)
    garment, symmetrised = symmetrised_garment(args, load_garment_arg(args))
    garment = garment_with_grain(garment, args)
    fabric = load_fabric(args.fabric)
    weights = _load_weights(args.weights, garment) if args.weights else None
    init = Placement.load(args.init) if args.init else None

    def progress(k: int, n: int, e_random: float, e_aligned: float) -> None:
        print(f"station align: start {k}/{n}: E_fit {e_random:.1f} -> {e_aligned:.1f} mm²",
              file=sys.stderr, flush=True)

    grain_deg = fabric_grain_deg(args.fabric)
    options = dict(
        method=args.method, restarts=args.restarts, seed=args.seed,
        weights=weights, fix=args.fix, grain_tol_deg=tol, reflect=args.reflect,
        rotation=not args.no_rotation, translation=not args.no_translation, init=init,
        use_drape=not args.pattern_frames, progress=progress)
    pairs = [] if args.no_symmetry else cli_pairs(args, garment)
    placement = align_garment(garment, fabric, pairs, grain_deg=grain_deg, nap=args.nap,
                              **options)
    if symmetrised is not None:  # later commands rebuild the same pattern from this
        placement.report["symmetrise"] = symmetrised.to_dict()
    placement.garment = str(args.garment)
    placement.garment_units = args.units or placement.garment_units
    placement.save(args.output)
    rep = dict(placement.report)
    rep["output"] = str(args.output)
    if args.png:
        draw_fit(garment, placement, fit_report(garment, placement), args.png,
                 colour_of=fabric_picture(args.fabric, placement.fabric))
        rep["png"] = str(args.png)
    if args.json:
        print(json.dumps(rep))
    else:
        print(f"{args.garment}: {rep['pieces']} pieces under {fabric.group}, {args.method} "
              f"method, {args.restarts} starts: E_fit {rep['e_fit_random_mm2']:.1f} mm² "
              f"(random) -> {rep['e_fit_aligned_mm2']:.1f} mm² "
              f"({rep['e_fit_aligned_cm2']:.2f} cm², ratio {rep['ratio_aligned_random']:.2f}) "
              f"in {rep['seconds']:.2f} s; wrote {args.output}")
        grain = ("free rotation (--grain off)" if tol is None else
                 f"on grain within {tol:g} deg{' (nap)' if args.nap else ''}")
        print(f"  grain: {grain}, largest off-grain angle {rep['off_grain_max_deg']:.2f} deg",
              file=sys.stdout)
        for g in rep["grain"]:
            print(f"    {g['piece']:<20s} grain {g['grain_deg']:8.2f} deg ({g['grain_source']}"
                  f"{', bias' if g['bias'] else ''})  turn {g['turn_deg']:8.2f}  "
                  f"off grain {g['off_grain_deg']:.2f}")
        sym = rep.get("symmetry")
        if sym:
            kept = ", ".join(f"{i}~{j} {mode}" for i, j, mode in sym["pairs"])
            price = (f"; unconstrained E_fit {sym['e_fit_unconstrained_mm2']:.1f} mm² "
                     f"(price x{sym['price_ratio']:.2f})" if "price_ratio" in sym else "")
            print(f"  pairs: {kept}{price}")
            if "note" in sym:
                print(f"  note: {sym['note']}")
    return 0
