"""`station fit`: E_fit of a garment under a print, with an optional picture."""

from __future__ import annotations

import argparse
import json
import sys
import time

from solver.fit import fit_report
from solver.garment.notches import cut_ready
from solver.garment.symmetry import mirror_pairs
from solver.placement import Placement
from station.cliargs import (
    add_allowance_arguments,
    add_config_argument,
    add_fabric_argument,
    add_garment_arguments,
    add_grain_arguments,
    add_symmetrise_argument,
    load_fabric,
    picture_path,
)
from station.cliload import (
    allowance_rules,
    garment_with_grain,
    load_garment_arg,
    symmetrised_garment,
)
from station.front_view import draw_front_view
from station.render import draw_fit, fabric_picture


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "fit",
        help="measure how well the print matches across the seams (paper Eq. 1)",
        description="Compute E_fit = sum over seam edges of weight x length x mismatch, "
        "for the print FABRIC placed on each piece as PLACEMENT says (identity if omitted).",
    )
    add_garment_arguments(p)
    add_fabric_argument(p)
    p.add_argument("--placement", metavar="PLACEMENT.json",
                   help="per-piece rotation and translation of the print (default: identity)")
    add_grain_arguments(p)
    add_symmetrise_argument(p)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--png", metavar="OUT.png", type=picture_path,
                   help="draw the pieces over the print, seams coloured by mismatch, with "
                   "the cut line (solid), the sew line (dashed) and the notches")
    p.add_argument("--front-view", metavar="OUT.png", type=picture_path,
                   help="draw left/right pairs side by side as worn, grain up, print on")
    add_allowance_arguments(p)
    add_config_argument(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    start = time.perf_counter()
    fabric = load_fabric(args.fabric)  # the small files first: fail fast
    rules = allowance_rules(args)
    if not args.png and (args.allowance or args.seam_allowance is not None):
        print("station fit: warning: the allowance only changes the --png picture (the fit "
              "is measured on the sew line)", file=sys.stderr)
    garment = load_garment_arg(args)
    if args.placement:
        placement = Placement.load(args.placement)
        if placement.n_pieces != garment.n_pieces:
            raise ValueError(f"{args.placement}: placement has {placement.n_pieces} pieces, "
                             f"{args.garment} has {garment.n_pieces}")
        placement.fabric = fabric
    else:
        placement = Placement.identity(garment.n_pieces, fabric)
    garment, symmetrised = symmetrised_garment(args, garment, placement)
    garment = garment_with_grain(garment, args)
    report = fit_report(garment, placement)
    result = {
        "garment": str(args.garment),
        "group": fabric.group,
        "pieces": garment.n_pieces,
        "seam_lines": len(garment.seam_lines),
        "seam_edges": len(garment.seam_edges),
        **report.summary(),
        "seconds": time.perf_counter() - start,
    }
    if symmetrised is not None:
        result["symmetrise"] = symmetrised.to_dict()
    if args.png:
        cuts, notches = cut_ready(garment, rules, placement)
        draw_fit(garment, placement, report, args.png, cuts=cuts, notches=notches,
                 colour_of=fabric_picture(args.fabric, placement.fabric))
        result["png"] = str(args.png)
    if args.front_view:
        draw_front_view(garment, placement, symmetrised.pairs if symmetrised is not None
                        else mirror_pairs(garment), args.front_view)
        result["front_view"] = str(args.front_view)
    if args.json:
        print(json.dumps(result))
    else:
        print(f"{args.garment}: {garment.n_pieces} pieces, {len(garment.seam_edges)} seam edges "
              f"under {fabric.group}: E_fit = {report.e_fit_mm2:.1f} mm² "
              f"({report.e_fit_cm2:.2f} cm²), mean mismatch "
              f"{result['mismatch_mean_mm']:.2f} mm, worst {result['mismatch_max_mm']:.2f} mm")
    return 0
