"""Arguments shared by the `station` commands, and the light loaders (config, fabric).

Every command imports this module, the console's (`station status`, `pause`, ...) too, so
it imports no garment stack (SciPy, Shapely: about 0.4 s on this machine under load); the
garment loaders are in `station.cliload`.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from solver.jsonfile import read_json
from solver.units import UNIT_CHOICES
from solver.wallpaper import Wallpaper
from station.config import load_config
from station.stripes import stripe_print


def add_garment_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("garment", metavar="GARMENT",
                        help="garment: OBJ (v = drape, vt = pattern), JSON pattern spec or "
                        "DXF-AAMA/ASTM pattern (seams inferred)")
    parser.add_argument("--units", choices=UNIT_CHOICES,
                        help="units of the file's coordinates (default: what the file says, "
                        "else mm)")
    parser.add_argument("--size", help="the size of a graded DXF (default: its sample size)")


def add_fabric_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--fabric", required=True, metavar="FABRIC.json",
                        help='the print: {"group", "w1", "w2", "origin", "units"}')


def dxf_allowance(args: argparse.Namespace) -> tuple[float, str]:
    """(mm, where from) a DXF's cut line is inset by where the file gives no sew line nor
    allowance: the command's --seam-allowance, else station.toml's allowance.seam_mm."""
    given = getattr(args, "seam_allowance", None)
    if given is not None and not given >= 0:
        raise ValueError(f"--seam-allowance must be >= 0, got {given:g}")
    if given is not None:
        return float(given), "--seam-allowance"
    return float(load_config_arg(args)["allowance"]["seam_mm"]), "station.toml allowance.seam_mm"


def load_fabric(path: str | Path) -> Wallpaper:
    """The print of a FABRIC.json; a stripe print (``kind: stripes``, as `station detect`
    writes it) as the 1-D lattice that matches stripes across the seams."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such fabric file")
    doc = read_json(path)
    if isinstance(doc, dict) and doc.get("kind") == "stripes" and doc.get("group") is None:
        doc = stripe_print(doc, 0.0, str(path))
    return Wallpaper.from_dict(doc, str(path))


def add_config_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config", metavar="station.toml",
                        help="station configuration (default: $STATION_CONFIG, else "
                        "./station.toml if present, else the built-in defaults)")


def load_config_arg(args: argparse.Namespace, overrides=None):
    path = getattr(args, "config", None) or os.environ.get("STATION_CONFIG")
    if path is None and Path("station.toml").is_file():
        path = "station.toml"
    return load_config(path, overrides)


def add_grain_arguments(parser: argparse.ArgumentParser, *, rule: bool = False) -> None:
    """Where each piece's grain comes from; with ``rule`` also how strictly to keep it."""
    parser.add_argument("--grain-line", action="append", metavar="PIECE=DEG",
                        help="the grain direction of a piece (name or index) in pattern "
                        "space, degrees, where the file has no grain line; repeatable")
    parser.add_argument("--bias", action="append", metavar="PIECE",
                        help="cut this piece on the bias (grain at 45 degrees); repeatable")
    parser.add_argument("--up", metavar="AXIS",
                        help="the drape's up axis: x, y, z, -x, -y or -z (default: detected)")
    if rule:
        parser.add_argument("--grain", nargs="?", const="1", default="1", metavar="TOL|off",
                            help="keep each piece's grain within TOL degrees (default 1) of "
                            "the fabric's grain at 0 or 180 degrees; off: turn freely")
        parser.add_argument("--nap", action="store_true",
                            help="one-way print or napped fabric: every grain at 0 degrees")


def grain_tolerance(text: str) -> float | None:
    """``--grain`` value: degrees >= 0, or None for ``off``."""
    if str(text).strip().lower() == "off":
        return None
    try:
        tol = float(text)
    except ValueError:
        tol = float("nan")
    if not tol >= 0 or tol == float("inf"):
        raise ValueError(f"--grain must be a tolerance in degrees >= 0 or off, got {text!r}")
    return tol


def fabric_grain_deg(path: str | Path) -> float:
    """The fabric's grain direction in fabric space: FABRIC.json ``grain_deg``, else 0
    (the roll's length, fabric x)."""
    doc = read_json(Path(path))
    value = doc.get("grain_deg", 0.0) if isinstance(doc, dict) else 0.0
    if isinstance(value, bool) or not isinstance(value, (int, float)) or value != value:
        raise ValueError(f"{path}: grain_deg must be a number of degrees")
    return float(value)


def add_allowance_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seam-allowance", type=float, metavar="MM",
                        help="seam allowance on every sewn edge (default: station.toml "
                        "[allowance] seam_mm, 10)")
    parser.add_argument("--allowance", metavar="A.json",
                        help='allowances per seam line or opening: {"front~back": 15, '
                        '"3": 12, "hem": 30, "opening": 8, "open#2": 25, "PIECE/open": 0}')
    parser.add_argument("--match-notches", action="store_true",
                        help="on a print, put the balance notches where its lattice lines "
                        "cross each seam (the plaid's match points), not every ~200 mm")


def add_symmetrise_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--symmetrise", action="store_true",
                        help="replace each near left/right pair by one pattern cut twice, "
                        "the average of the two (a placement made so is followed anyway)")


#: what the pictures can be written as (OpenCV's writers; anything else failed at the end)
PICTURE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp")


def picture_path(text: str) -> str:
    """An ``OUT.png`` option: refused at once unless it names a picture format, rather
    than after the work, when the writer finds no format for ``x.json``."""
    if not text.lower().endswith(PICTURE_SUFFIXES):
        raise argparse.ArgumentTypeError(f"{text}: a picture is written as "
                                         f"{', '.join(PICTURE_SUFFIXES)}")
    return text
