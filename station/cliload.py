"""Loaders shared by the `station` commands that read garments: the garment with its
repairs, grain, allowance rules and symmetrised pairs, each told on stderr in one line.

Apart from `station.cliargs` (the arguments, which every command imports, the console's
too) because this one imports the garment stack: SciPy and Shapely.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import warnings
from pathlib import Path

import numpy as np

import untrusted
from solver.garment import load_garment
from solver.garment.grain import parse_grain_lines
from solver.garment.symmetrise import symmetrise_as_recorded
from solver.garment.symmetry import read_pairs_file
from station.allowance import name_key, rules_for
from station.cliargs import dxf_allowance, load_config_arg
from station.steps.garment import found_pairs, symmetrised


def load_garment_arg(args: argparse.Namespace, **options):
    """The command's GARMENT, with repairs and a units slip told on stderr, one line each.

    Repair warnings (duplicate vertices, slivers) go to stderr so ``--json`` stays clean;
    a whole garment under a centimetre across was almost surely read in the wrong units
    (the Berkeley files are in metres and do not say so).
    """

    path = Path(args.garment)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such garment file")
    if path.suffix.lower() == ".dxf":  # a sew line the file lacks: inset by this
        options["seam_allowance_mm"], options["allowance_from"] = dxf_allowance(args)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        garment = load_garment(path, units=args.units, size=getattr(args, "size", None),
                               **options)
    for w in caught:
        print(f"station {args.command}: warning: {w.message}", file=sys.stderr)
    extent = float(np.ptp(garment.uv, axis=0).max()) if garment.n_vertices else 0.0
    if args.units is None and extent < 10:
        print(f"station {args.command}: warning: {path}: read in {garment.units_in_file}, the "
              f"whole pattern spans only {extent:.3g} mm; if the file is in metres pass "
              "--units m", file=sys.stderr)
    return garment

def garment_with_grain(garment, args: argparse.Namespace):
    """``garment`` with the grain the command line asks for; a guessed grain is told on
    stderr (one line) so that ``--json`` stays clean."""

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = garment.with_grain(lines=parse_grain_lines(getattr(args, "grain_line", None)),
                                 bias=getattr(args, "bias", None) or (),
                                 up=getattr(args, "up", None))
    for w in caught:
        print(f"station {args.command}: warning: {w.message}", file=sys.stderr)
    return out

def read_name_map(path: str | Path, what: str, *, hi: float = untrusted.limits.MAX_GARMENT_MM
                  ) -> dict[int | str, float]:
    """A JSON object {"seam line name or index": number in 0..``hi``} (weights, allowances)
    from a file; every fault names it.

    Keys that are digits become indices, as ``--weights`` and ``--allowance`` take them.
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"{p}: no such {what} file")
    data = untrusted.read_json(p, what=f"{what} file")
    if not isinstance(data, dict):
        raise ValueError(f'{p}: expected an object {{"seam line": {what}}}')
    return {name_key(key): untrusted.number(value, p, f"{what} of {key[:40]!r}", lo=0.0, hi=hi)
            for key, value in data.items()}

def allowance_rules(args: argparse.Namespace, config=None):
    """The job's allowance rules: station.toml [allowance], then the command line."""
    if args.seam_allowance is not None and args.seam_allowance < 0:
        raise ValueError(f"--seam-allowance must be >= 0, got {args.seam_allowance:g}")
    more = read_name_map(args.allowance, "allowance") if args.allowance else None
    rules = rules_for(config or load_config_arg(args), args.seam_allowance, more,
                      source=args.allowance or "")
    return dataclasses.replace(rules, notch_on_print=bool(getattr(args, "match_notches", False)))

def symmetrised_garment(args: argparse.Namespace, garment, placement=None, pairs=None):
    """``garment`` and its `Symmetrised` record (None when nothing asks for it): as the
    placement recorded it, else with ``--symmetrise`` on ``pairs`` (default: the pairs
    found, with the command's ``--pairs`` file). How far each piece moved goes to stderr."""

    record = placement.report.get("symmetrise") if placement is not None else None
    if record:
        try:
            sym = symmetrise_as_recorded(garment, record)
        except ValueError as exc:
            raise ValueError(f"{args.placement}: {exc}") from None
        why = "as the placement was made"
    elif getattr(args, "symmetrise", False):
        _, sym = symmetrised(garment, cli_pairs(args, garment) if pairs is None else pairs)
        why = "--symmetrise"
    else:
        return garment, None
    kept = ", ".join(f"{p.first}~{p.second}" for p in sym.pairs) or "none"
    print(f"station {args.command}: symmetrised pairs ({why}): {kept}", file=sys.stderr)
    for line in sym.lines():
        print(f"  {line}", file=sys.stderr)
    return sym.garment, sym

def cli_pairs(args: argparse.Namespace, garment) -> list:
    """The garment's left/right pairs: found, with the command's ``--pairs`` file heard."""
    path = getattr(args, "pairs", None)
    return found_pairs(garment, read_pairs_file(path, garment) if path else ([], []))
