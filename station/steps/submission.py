"""Step 0 of a job: refuse at submission what could never run (the daemon runs this in a
bounded child process, `station.intake`): the garment and fabric files, the job's
options, and every piece or seam line an option names."""

from __future__ import annotations

import warnings
from typing import Any

import solver.garment as garment_files
from solver.garment.allowance import edge_allowances
from solver.garment.symmetry import pairs_from_dict
from solver.wallpaper import Wallpaper
from station.allowance import rules_for_job
from station.config import Config
from station.order import is_order_file, read_order
from station.seams_confirm import checked_seams
from station.steps.garment import grained

JOB_OPTIONS = frozenset({"units", "size", "reshape", "method", "restarts", "seed", "grain_lines",
                         "bias", "seam_allowance", "allowance", "symmetry", "pairs",
                         "symmetrise", "match_notches", "match_stripes", "seams"})
#: job options that are true or false, and their default
FLAGS = {"symmetry": True, "symmetrise": False, "match_notches": False, "match_stripes": True}


def check_job(garment: str, fabric: str | None, options: dict[str, Any],
              config: Config) -> None:
    """Raise ValueError, naming the file or option, for a job that could never run; an
    order's every garment is checked as one garment is."""
    if is_order_file(garment):
        _check_order(garment, fabric, options, config)
        return
    loaded = garment_files.load_garment(garment, units=options.get("units"),
                                        size=options.get("size"))
    if fabric is not None:
        Wallpaper.load(fabric)
    unknown = set(options) - JOB_OPTIONS
    if unknown:
        raise ValueError(f"unknown job option {sorted(unknown)[0]!r}")
    lines, bias = options.get("grain_lines", {}), options.get("bias", [])
    if not isinstance(lines, dict) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in lines.values()):
        raise ValueError('job option grain_lines must be {"piece": degrees}')
    if not isinstance(bias, list) or not all(isinstance(b, (str, int)) for b in bias):
        raise ValueError("job option bias must be a list of pieces")
    with warnings.catch_warnings():  # a guessed grain is reported when the job runs
        warnings.simplefilter("ignore")
        grained(loaded, config, options)  # names every piece that does not exist
    edge_allowances(loaded, rules_for_job(config, options), ())  # names must exist
    for key, default in FLAGS.items():
        if not isinstance(options.get(key, default), bool):
            raise ValueError(f"job option {key} must be true or false")
    if "pairs" in options:
        pairs_from_dict(options["pairs"], loaded, "job option pairs")  # names must exist
    if "seams" in options:  # the operator's seams of a CAD pattern: pieces must exist
        if loaded.kind != "dxf":
            raise ValueError(f"job option seams is for a DXF pattern; {garment} has its own")
        checked_seams(options["seams"], set(loaded.piece_names), "job option seams")


def _check_order(path: str, fabric: str | None, options: dict[str, Any], config: Config
                 ) -> None:
    """The order read (its checks), then each style and size loaded and checked with the
    job's options; an order's file gives the units and sizes, not the job's options."""
    given = [k for k in ("units", "size") if options.get(k) is not None]
    if given:
        raise ValueError(f"{path}: job option {given[0]} is the order file's to give")
    if options.get("symmetrise"):  # not yet run per garment
        raise ValueError(f"{path}: an order's patterns are not symmetrised: drop job "
                         "option symmetrise")
    if "seams" in options:
        raise ValueError(f"{path}: job option seams names one pattern's pieces; an order's "
                         "patterns each have their own")
    order = read_order(path)
    seen = set()
    for item in order.garments:
        if (item.pattern, item.size) not in seen:
            seen.add((item.pattern, item.size))
            check_job(str(item.pattern), fabric, {**options, "units": item.units,
                                                  "size": item.size}, config)
