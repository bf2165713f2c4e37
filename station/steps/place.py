"""Step 3 of a job: where the print lies on every piece (a `Placement`).

`align_garment` is the one alignment of the station: left/right pairs kept as mirror
images (`solver.align.symmetric`) when there are any, else each piece on its own
(`solver.align`). `station align` calls it with the command line's options, the daemon
through `align_job` with the station's configuration and the job's options. On plain
cloth, or stripes the job does not match, `plain_placement` only turns each piece onto
the grain. `reshape_placed` nudges the aligned outlines (`solver.reshape`) when asked.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np

from solver.align import align
from solver.align.symmetric import align_symmetric
from solver.garment import Garment
from solver.garment.symmetry import MirrorPair, fit_pairs
from solver.placement import Placement
from solver.reshape import ReshapeOptions, reshape
from solver.reshape.report import ReshapeReport
from solver.wallpaper import Wallpaper
from station.config import Config
from station.steps.garment import job_pairs

Progress = Callable[[int, int, float, float], None]  # (k, n, e_random, e_aligned)


def align_garment(garment: Garment, wallpaper: Wallpaper, pairs: list[MirrorPair], *,
                  grain_deg: float, nap: bool, folds: bool = True, **options: Any) -> Placement:
    """The best placement of the print on every piece; ``pairs`` mirror each other, and
    so does a piece cut on the fold about its fold, unless ``folds`` is off (no symmetry).

    ``options`` are `solver.align.align`'s (method, restarts, seed, grain_tol_deg,
    reflect, progress, ...); ``grain_deg`` is the fabric's grain in fabric space.
    """
    if not folds and garment.folds:
        garment = dataclasses.replace(garment, folds={})
    if pairs or garment.folds:
        return align_symmetric(garment, wallpaper, pairs, grain_deg=grain_deg, nap=nap,
                               **options)
    return align(garment, wallpaper, nap=nap, fabric_grain_deg=grain_deg, **options)


def align_job(garment: Garment, wallpaper: Wallpaper, config: Config, options: dict[str, Any],
              progress: Progress | None = None, fabric_grain_deg: float | None = None
              ) -> Placement:
    """`align_garment` on grain as the configuration says, with the job's options (method,
    restarts, seed, symmetry, pairs); ``fabric_grain_deg`` (FABRIC.json's) wins over the
    station's. ``progress`` is called as each random restart finishes."""
    a = config["align"]
    grain = a["grain_tolerance_deg"]
    symmetry = options.get("symmetry", a["symmetry"])
    pairs = job_pairs(garment, options) if symmetry else []
    return align_garment(
        garment, wallpaper, pairs, folds=bool(symmetry),
        grain_deg=a["fabric_grain_deg"] if fabric_grain_deg is None else fabric_grain_deg,
        nap=a["nap"], method=options.get("method", a["method"]),
        restarts=int(options.get("restarts", a["restarts"])),
        seed=int(options.get("seed", a["seed"])), reflect=a["reflect"],
        grain_tol_deg=grain if grain >= 0 else None, progress=progress)


def plain_placement(garment: Garment, config: Config, cloth_grain_deg: float) -> Placement:
    """Each piece turned so that its grain runs along the cloth's (``cloth_grain_deg``);
    the print is a stand-in that plain nesting drops. The grain rule goes with it, so
    nesting keeps the grain."""
    a = config["align"]
    grain_deg = np.array([g.deg for g in garment.grains()])
    return Placement(np.radians(grain_deg - cloth_grain_deg),
                     np.zeros((garment.n_pieces, 2)), Wallpaper("p1", (1, 0), (0, 1)),
                     piece_names=list(garment.piece_names),
                     grains=[g.to_dict() for g in garment.grains()],
                     grain_rule={"tolerance_deg": a["grain_tolerance_deg"]
                                 if a["grain_tolerance_deg"] >= 0 else None,
                                 "nap": a["nap"], "fabric_grain_deg": cloth_grain_deg})


def reshape_placed(garment: Garment, placement: Placement, config: Config
                   ) -> tuple[Garment, ReshapeReport]:
    """The garment with its outlines nudged so the print fits across the seams, within the
    station's move bound; the placement's pairs move as mirror images."""
    return reshape(garment, placement, options=ReshapeOptions(
        max_move_mm=config["reshape"]["max_move_mm"]),
        pairs=fit_pairs(garment, [p[:2] for p in placement.pairs]))
