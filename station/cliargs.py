"""Arguments and loaders shared by the `station` commands that read garments and fabrics."""

from __future__ import annotations

import argparse
from pathlib import Path

from solver.units import UNIT_CHOICES
from solver.wallpaper import Wallpaper


def add_garment_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("garment", metavar="GARMENT",
                        help="garment: OBJ (v = drape, vt = pattern) or JSON pattern spec")
    parser.add_argument("--units", choices=UNIT_CHOICES,
                        help="units of the file's coordinates (default: what the file says, "
                        "else mm)")


def add_fabric_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--fabric", required=True, metavar="FABRIC.json",
                        help='the print: {"group", "w1", "w2", "origin", "units"}')


def load_garment_arg(args: argparse.Namespace, **options):
    """The command's GARMENT, with repairs and a units slip told on stderr, one line each.

    Repair warnings (duplicate vertices, slivers) go to stderr so ``--json`` stays clean;
    a whole garment under a centimetre across was almost surely read in the wrong units
    (the Berkeley files are in metres and do not say so).
    """
    import sys
    import warnings

    import numpy as np

    from solver.garment import load_garment

    path = Path(args.garment)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such garment file")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        garment = load_garment(path, units=args.units, **options)
    for w in caught:
        print(f"station {args.command}: warning: {w.message}", file=sys.stderr)
    extent = float(np.ptp(garment.uv, axis=0).max()) if garment.n_vertices else 0.0
    if args.units is None and extent < 10:
        print(f"station {args.command}: warning: {path}: read in {garment.units_in_file}, the "
              f"whole pattern spans only {extent:.3g} mm; if the file is in metres pass "
              "--units m", file=sys.stderr)
    return garment


def load_fabric(path: str | Path) -> Wallpaper:
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such fabric file")
    return Wallpaper.load(path)


def add_config_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config", metavar="station.toml",
                        help="station configuration (default: $STATION_CONFIG, else "
                        "./station.toml if present, else the built-in defaults)")


def load_config_arg(args: argparse.Namespace, overrides=None):
    import os

    from station.config import load_config

    path = args.config or os.environ.get("STATION_CONFIG")
    if path is None and Path("station.toml").is_file():
        path = "station.toml"
    return load_config(path, overrides)
