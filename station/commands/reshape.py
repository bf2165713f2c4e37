"""`station reshape`: nudge the pattern pieces' shapes so the print matches across seams."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from solver.fit import fit_report
from solver.garment import save_obj, save_spec
from solver.garment.symmetry import fit_pairs
from solver.nest.dxf_aama import write_dxf_aama
from solver.nest.sources import garment_pieces
from solver.placement import Placement
from solver.reshape import ReshapeOptions, reshape
from station.cliargs import (
    add_allowance_arguments,
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
from station.errors import UserError
from station.render import draw_fit, fabric_picture

FORMATS = (".obj", ".json", ".dxf")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "reshape",
        help="deform the pattern so the print fits perfectly along the seams (paper Sec. 5)",
        description="Keep the print's placement and move each seam towards its ideal line "
        "(conformal, flip-free, every seam keeping its ease, outlines kept fair). Writes the "
        "reshaped garment as OBJ (3D kept, pattern replaced), JSON specification (if the "
        "input was one) or "
        "DXF-AAMA.",
    )
    add_garment_arguments(p)
    add_fabric_argument(p)
    p.add_argument("--placement", required=True, metavar="PLACEMENT.json",
                   help="per-piece rotation and translation of the print (from `station align`)")
    p.add_argument("-o", "--output", required=True, metavar="OUT.(obj|json|dxf)",
                   help="reshaped garment; the suffix picks the format")
    p.add_argument("--fix", action="append", default=[], metavar="PIECE",
                   help="piece (name or index) that must keep its shape; repeatable")
    p.add_argument("--method", choices=("ours", "paper"), default="ours",
                   help="ours (default): bounded moves and areas, fair outlines, seams keep "
                   "their ease; paper: Sec. 5 as written (Eq. 10, unbounded, twins pulled to "
                   "equal lengths), to compare side by side")
    p.add_argument("--max-move", type=float, default=None, metavar="MM",
                   help="no pattern vertex moves farther than MM (default 10; not with "
                   "--method paper); each piece's area also stays within 1 %%")
    add_grain_arguments(p)
    add_symmetrise_argument(p)
    p.add_argument("--no-symmetry", action="store_true",
                   help="reshape every piece on its own (default: the placement's left/right "
                   "pairs move as mirror images)")
    add_allowance_arguments(p)  # a DXF output carries the cut lines
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--png", metavar="OUT.png", type=picture_path,
                   help="draw the reshaped pieces over the print, seams coloured by mismatch")
    p.set_defaults(func=run)


def _fixed_mask(garment, names: list[str]):
    mask = np.zeros(garment.n_pieces, bool)
    for name in names:
        if name in garment.piece_names:
            mask[garment.piece_names.index(name)] = True
        elif name.isdigit() and int(name) < garment.n_pieces:
            mask[int(name)] = True
        else:
            raise UserError(f"--fix {name}: no such piece (pieces: "
                            f"{', '.join(garment.piece_names)})")
    return mask


def write_garment(garment, path: Path, rules=None) -> None:
    """Write the reshaped garment in the format its suffix names (``rules``: the seam
    allowances a DXF's cut lines get; default the built-in ones)."""
    suffix = path.suffix.lower()
    if suffix == ".obj":
        save_obj(garment, path)
    elif suffix == ".json":
        if garment.kind != "spec":
            raise UserError(f"{path}: JSON output needs a JSON specification as input "
                            f"(this garment came from {garment.kind}); write .obj or .dxf")

        save_spec(garment, path)
    elif suffix == ".dxf":
        # layer 1 the cut line (it follows the reshaped sew line), layer 14 the sew line
        write_dxf_aama(garment_pieces(garment, rules), path)
    else:
        raise UserError(f"{path}: unknown output format {suffix!r} "
                        f"(expected one of {', '.join(FORMATS)})")


def _print_round(record: dict) -> None:
    """One stderr line per gamma round, so a long reshape shows it is getting on."""
    print(f"  round {record['round']} ({record['targets']} targets): "
          f"L {record['L_mm']:.2f} mm, E_fit {record['e_fit_mm2'] / 100:.1f} cm², "
          f"{record['iterations']} iterations", file=sys.stderr)


def _print_changes(report) -> None:
    """Per piece and per seam what a pattern maker checks before signing off."""
    print(f"  outlines: unexplained displacement {report.roughness_p95_mm:.2f} mm (95th "
          f"percentile), {report.roughness_max_mm:.2f} mm at most; seams: ease changed "
          f"{report.ease_change_max_mm:.2f} mm, notches drifted {report.sewn_drift_max_mm:.2f}"
          " mm at most")
    for p in report.pieces:
        print(f"  {p['piece']:<20s} largest move {p['max_move_mm']:6.2f} mm  area "
              f"{p['area_change_pct']:+.2f} %  seam length {p['seam_length_change_mm']:+.2f}"
              f" mm ({p['seam_length_change_pct']:+.2f} %)")
    for s in report.seams:
        a, b = s["side_change_mm"]
        print(f"  seam {s['seam']:<28s} sides {a:+.2f} / {b:+.2f} mm  ease "
              f"{s['ease_change_mm']:+.2f} mm  notches drift {s['sewn_drift_mm']:.2f} mm")


def _options(args: argparse.Namespace) -> ReshapeOptions:
    """The reshape options the command line asks for, checked before any work is done."""
    if args.method == "paper":
        if args.max_move is not None:
            raise UserError("--max-move: the paper's method has no move bound "
                            "(drop --max-move or use --method ours)")
        return ReshapeOptions.paper()
    max_move = 10.0 if args.max_move is None else args.max_move
    if not max_move > 0 or max_move == float("inf"):
        raise ValueError(f"--max-move must be a positive number of mm, got {max_move}")
    return ReshapeOptions(max_move_mm=max_move)


def run(args: argparse.Namespace) -> int:
    out = Path(args.output)
    if out.suffix.lower() not in FORMATS:
        raise UserError(f"{out}: unknown output format {out.suffix!r} "
                        f"(expected one of {', '.join(FORMATS)})")
    options = _options(args)
    garment = load_garment_arg(args)
    fabric = load_fabric(args.fabric)
    placement = Placement.load(args.placement)
    if placement.n_pieces != garment.n_pieces:
        raise ValueError(f"{args.placement}: placement has {placement.n_pieces} pieces, "
                         f"{args.garment} has {garment.n_pieces}")
    garment, symmetrised = symmetrised_garment(args, garment, placement, pairs=fit_pairs(
        garment, [p[:2] for p in placement.pairs]) if placement.pairs else None)
    garment = garment_with_grain(garment, args)
    placement.fabric = fabric
    fixed = _fixed_mask(garment, args.fix)
    print(f"station reshape: {garment.n_pieces} pieces, {len(garment.faces)} faces, "
          f"{len(garment.seam_edges)} seam edges under {fabric.group}", file=sys.stderr)
    tied = [tuple(p[:2]) for p in placement.pairs]
    if symmetrised is not None:  # one pattern stays one pattern, whatever the print did
        taken = {k for p in tied for k in p}
        tied += [(p.first, p.second) for p in symmetrised.pairs
                 if not {p.first, p.second} & taken]
    pairs = [] if args.no_symmetry else fit_pairs(garment, tied)
    if pairs:
        print(f"station reshape: pairs {', '.join(f'{p.first}~{p.second}' for p in pairs)} "
              "(from the placement) move as mirror images", file=sys.stderr)
    new, report = reshape(garment, placement, fixed=fixed, progress=_print_round, pairs=pairs,
                          options=options)
    if report.subdivisions:
        print(f"station reshape: seam edges too long for a {fabric.covering_radius:.0f} mm "
              f"covering radius: the mesh was subdivided {report.subdivisions}x "
              f"({report.faces} faces), and {out} has the finer mesh", file=sys.stderr)
    write_garment(new, out, allowance_rules(args) if out.suffix.lower() == ".dxf" else None)
    result = {"garment": str(args.garment), "output": str(out), "group": fabric.group,
              "method": args.method,
              **report.to_dict()}
    if symmetrised is not None:
        result["symmetrise"] = symmetrised.to_dict()
    if args.png:
        draw_fit(new, placement, fit_report(new, placement), args.png, original=garment,
                 colour_of=fabric_picture(args.fabric, placement.fabric))
        result["png"] = str(args.png)
    if args.json:
        print(json.dumps(result))
    else:
        print(f"{out}: E_fit {report.e_fit_before_mm2:.1f} -> {report.e_fit_after_mm2:.1f} mm² "
              f"({report.e_fit_ratio:.3f}), L {report.length_mismatch_initial_mm:.2f} -> "
              f"{report.length_mismatch_final_mm:.2f} mm, largest move "
              f"{report.max_displacement_mm:.2f} mm, {report.flipped_triangles} flipped "
              f"triangles, {report.iterations} iterations in {report.gamma_rounds} rounds, "
              f"{report.seconds:.2f} s")
        _print_changes(report)
    return 0
