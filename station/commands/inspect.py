"""`station inspect`: what the station sees in a garment file (pieces, seams, units, sizes)."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from gcode.layout import load_layout
from solver.garment.allowance import open_edges
from solver.garment.grain import paired_grains
from solver.garment.symmetry import centre_seams, mirror_pairs
from station.cliargs import add_garment_arguments, add_grain_arguments
from station.cliload import cli_pairs, garment_with_grain, load_garment_arg
from station.commands.gcode import bites_beside
from station.errors import UserError
from station.seams_view import add_dxf_arguments, draw_seams, inspect_dxf
from station.steps.garment import symmetrised


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "inspect",
        help="show a garment's pieces, seam lines, seam edges, units and piece sizes",
        description="Import GARMENT (OBJ with v = drape and vt = pattern, a -m/-w OBJ pair, "
        "or a GarmentCode / Garment-Pattern-Generator JSON specification) and report what "
        "the station will cut and align: pieces with their size, seam lines and seam edges.",
    )
    add_garment_arguments(p)
    p.add_argument("--resolution-mm", type=float, metavar="MM",
                   help="target edge length when meshing a JSON specification (default 20)")
    add_grain_arguments(p)
    p.add_argument("--pairs", metavar="P.json",
                   help='declare or veto mirror pairs: {"pairs": [[i, j]], "not_pairs": [[k, l]]} '
                   "(indices or piece names)")
    p.add_argument("--symmetrise", action="store_true",
                   help="also say what --symmetrise would do: the pairs made one pattern and "
                   "how far each piece moves")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    add_dxf_arguments(p)
    p.set_defaults(func=run)


def garment_summary(g, pairs=None) -> dict:
    """Plain-JSON description of a garment: counts, units, per-piece sizes in mm, and its
    left/right pairs (``pairs``: MirrorPair list, found when not given)."""
    if pairs is None:
        pairs = mirror_pairs(g)
    grains = g.grains()
    return {
        "opening_list": openings(g),
        "garment": g.source,
        "kind": g.kind,
        "units_in_file": g.units_in_file,
        "scale_recovered": g.scale_recovered,
        "has_3d": g.xyz is not None,
        "vertices": g.n_vertices,
        "faces": int(len(g.faces)),
        "pieces": g.n_pieces,
        "seam_lines": len(g.seam_lines),
        "seam_edges": int(len(g.seam_edges)),
        "boundary_edges_3d": int(g.boundary_3d_edges),
        "seam_weight_total": float(g.seam_weights().sum()),
        "grainlines": len(g.grainlines),
        "notches": sum(len(v) for v in g.notches.values()),
        "grain_guessed": [g.piece_names[i] for i, gr in enumerate(grains) if gr.guessed],
        "piece_list": _pieces(g, grains),
        "seam_line_list": _seam_lines(g),
        "mirror_pairs": [[p.first, p.second] for p in pairs],
        "mirror_pair_fits": [p.to_dict() for p in pairs],
        "centre_seams": centre_seams(g, pairs),
    }


def _pieces(g, grains) -> list[dict]:
    """Per piece: its size in mm, vertices, holes and grain."""
    bbox = g.piece_bboxes()
    area = g.piece_areas()
    return [
        {
            "index": i,
            "name": g.piece_names[i],
            "vertices": int(np.sum(g.piece_of_vertex == i)),
            "bbox_mm": [round(float(x), 3) for x in bbox[i]],
            "width_mm": round(float(bbox[i, 2] - bbox[i, 0]), 3),
            "height_mm": round(float(bbox[i, 3] - bbox[i, 1]), 3),
            "area_mm2": round(float(area[i]), 3),
            "area_cm2": round(float(area[i]) / 100.0, 3),
            "holes": len(g.piece_holes(i)),
            **grains[i].to_dict(),
        }
        for i in range(g.n_pieces)
    ]


def _seam_lines(g) -> list[dict]:
    """Per seam line: its pieces, weight, seam edges and length in mm."""
    seam_count = np.bincount(g.seam_line_of_edge, minlength=len(g.seam_lines))
    uv_len = np.linalg.norm(g.uv[g.seam_edges[:, 1]] - g.uv[g.seam_edges[:, 0]], axis=1)
    seam_len = np.bincount(g.seam_line_of_edge, weights=uv_len, minlength=len(g.seam_lines))
    return [
        {
            "index": k,
            "name": s.name,
            "piece_a": s.piece_a,
            "piece_b": s.piece_b,
            "weight": s.weight,
            "seam_edges": int(seam_count[k]),
            "length_mm": round(float(seam_len[k]), 3),
        }
        for k, s in enumerate(g.seam_lines)
    ]


def openings(g) -> list[dict]:
    """The garment's openings (open edges chained through the seams), named as
    ``--allowance`` takes them, with their kind (hem or opening) and length."""
    edges, opening, is_hem = open_edges(g)
    length = np.bincount(opening, weights=np.linalg.norm(
        g.uv[edges[:, 1]] - g.uv[edges[:, 0]], axis=1), minlength=len(is_hem))
    return [{"name": f"open#{k}", "kind": "hem" if is_hem[k] else "opening",
             "pieces": sorted({int(p) for p in g.piece_of_vertex[edges[opening == k, 0]]}),
             "length_mm": round(float(length[k]), 3)} for k in range(len(is_hem))]


def _print_text(s: dict, out) -> None:
    scale = ""
    if s["scale_recovered"] is not None:
        scale = f", vt scale recovered x{s['scale_recovered']:.6g}"
    print(f"{s['garment']}: {s['kind']}, file units {s['units_in_file']}{scale}, "
          f"{'3D drape' if s['has_3d'] else '2D only'}", file=out)
    print(f"  {s['vertices']} pattern vertices, {s['faces']} faces, {s['pieces']} pieces, "
          f"{s['seam_lines']} seam lines, {s['seam_edges']} seam edges, "
          f"{s['boundary_edges_3d']} open boundary edges", file=out)
    print("  pieces:", file=out)
    for p in s["piece_list"]:
        holes = f", {p['holes']} holes" if p["holes"] else ""
        size = f"{p['width_mm']:8.1f} x {p['height_mm']:7.1f} mm"
        bias = ", bias" if p["bias"] else ""
        print(f"    {p['index']:3d} {p['name']:<20s} {size}  area {p['area_cm2']:9.1f} cm2"
              f"  ({p['vertices']} vertices{holes})  grain {p['grain_deg']:7.1f} deg "
              f"({p['grain_source']}{bias})", file=out)
    if s["grain_guessed"]:
        print(f"  warning: grain guessed from the outline for {', '.join(s['grain_guessed'])}"
              " (give it with --grain-line PIECE=DEG)", file=out)
    print("  seam lines:", file=out)
    for ln in s["seam_line_list"]:
        sure = f"  {ln['source']} {ln['confidence']:.2f}" if "confidence" in ln else ""
        print(f"    {ln['index']:3d} {ln['name']:<40s} pieces {ln['piece_a']}-{ln['piece_b']}"
              f"  {ln['seam_edges']:4d} edges  {ln['length_mm']:8.1f} mm  weight {ln['weight']:g}"
              f"{sure}", file=out)
    print("  openings (edges sewn to nothing; allowance by kind):", file=out)
    for op in s["opening_list"]:
        pieces = ",".join(map(str, op["pieces"]))
        print(f"    {op['name']:<8s} {op['kind']:<8s} pieces {pieces:<12s} "
              f"{op['length_mm']:8.1f} mm", file=out)
    if s["mirror_pair_fits"]:
        print("  mirror pairs (left/right):", file=out)
        for p in s["mirror_pair_fits"]:
            i, j = p["pieces"]
            how = "declared" if p["declared"] else "found"
            print(f"    {i:3d} ~ {j:<3d} outline RMS {p['rms_mm']:.2f} mm "
                  f"({100 * p['rms_mm'] / p['size_mm']:.2f} % of size, {how})", file=out)
    else:
        print("  mirror pairs: none", file=out)
    names = [s["seam_line_list"][k]["name"] for k in s["centre_seams"]]
    print(f"  centre seams: {', '.join(names) if names else 'none'}", file=out)
    if "symmetrise" in s:
        print("  --symmetrise would make one pattern of pairs "
              f"{', '.join(f'{i}~{j}' for i, j in s['symmetrise']['pairs']) or 'none'}:",
              file=out)
        for m in s["symmetrise"]["moves"]:
            print(f"    piece {m['piece']:3d} moves {m['max_mm']:.2f} mm at most, "
                  f"{m['rms_mm']:.2f} mm RMS, area {m['area_change_pct']:+.2f} %", file=out)
        for i, j, why in s["symmetrise"]["skipped"]:
            print(f"    pair {i}~{j} left as it is: {why}", file=out)


def refuse_marker(path: Path) -> None:
    """A marker (LAYOUT.json) given for a garment: say so, and how to cut it, in one line."""
    try:
        load_layout(path)
    except ValueError:
        return  # not a marker: the garment's own loader says what is wrong
    bites = bites_beside(path)
    how = (f"it is cut in {len(bites.bites)} bites: `station gcode {path} --bite K -o "
           f"BITE.nc` makes bite K's program" if bites is not None
           else f"`station gcode {path} -o JOB.nc` makes its program")
    raise UserError(f"{path}: a marker (LAYOUT.json), not a garment; {how}")


def run(args: argparse.Namespace) -> int:
    start = time.perf_counter()
    if str(args.garment).lower().endswith(".json"):
        refuse_marker(Path(args.garment))
    dxf = inspect_dxf(args) if str(args.garment).lower().endswith(".dxf") else None
    g = garment_with_grain(dxf.garment if dxf else
                           load_garment_arg(args, resolution_mm=args.resolution_mm), args)
    pairs = cli_pairs(args, g)
    g.grain = paired_grains(g.grains(), pairs)  # as `station align` cuts them
    summary = garment_summary(g, pairs)
    if dxf:  # issue 34: the inferred seams' confidences, the file's facts, the picture
        dxf.annotate(summary)
        if args.png:
            draw_seams(dxf.pieces, dxf.seams, args.png, folds=dxf.folds())
    if args.symmetrise:
        summary["symmetrise"] = symmetrised(g, pairs)[1].to_dict()
    summary["seconds"] = round(time.perf_counter() - start, 4)
    if args.json:
        print(json.dumps(summary))
    else:
        _print_text(summary, sys.stdout)
    return 0
