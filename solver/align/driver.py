"""``align``: garment + print -> Placement with its report (what `station align` runs)."""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping

import numpy as np

from solver.align.global_ import align_global
from solver.align.grain import GrainRule
from solver.align.problem import AlignProblem
from solver.align.restarts import align_paper
from solver.fit import fit_report
from solver.placement import Placement
from solver.units import MM_PER_UNIT
from solver.wallpaper import Wallpaper

METHODS = ("paper", "global")
FIX_KINDS = ("both", "rot", "trans")


def parse_fix(garment, specs: list[str] | None) -> tuple[np.ndarray, np.ndarray]:
    """``["front", "2:rot", "back:trans"]`` -> (fix_rot, fix_trans) bool arrays (P,).

    A piece is named by its name or index; ``:rot`` fixes only its rotation, ``:trans``
    only its translation, nothing after the name fixes both.
    """
    p = garment.n_pieces
    fix_rot, fix_trans = np.zeros(p, bool), np.zeros(p, bool)
    names = {n: i for i, n in enumerate(garment.piece_names)}
    for spec in specs or []:
        name, _, kind = spec.rpartition(":") if spec.endswith((":rot", ":trans")) else (
            spec, "", "both")
        if name in names:
            i = names[name]
        elif name.lstrip("-").isdigit() and 0 <= int(name) < p:
            i = int(name)
        else:
            raise ValueError(f"--fix {spec}: no piece {name!r}; pieces are "
                             f"{', '.join(garment.piece_names)} (or 0..{p - 1})")
        fix_rot[i] |= kind in ("both", "rot")
        fix_trans[i] |= kind in ("both", "trans")
    return fix_rot, fix_trans


def align(garment, fabric: Wallpaper, *, method: str = "paper", restarts: int = 15,
          seed: int = 0, weights: Mapping[int | str, float] | None = None,
          fix: list[str] | None = None, grain_tol_deg: float | None = 1.0,
          nap: bool = False, fabric_grain_deg: float = 0.0, reflect: bool = False,
          rotation: bool = True, translation: bool = True,
          init: Placement | None = None, use_drape: bool = True,
          progress: Callable[[int, int, float, float], None] | None = None) -> Placement:
    """Align ``fabric`` on every piece of ``garment`` (paper Sec. 4, or the global method).

    ``weights`` maps seam-line names or indices to w_S (0 ignores a seam); ``fix`` lists
    pieces that keep the rotation and/or translation of ``init`` (identity if None);
    ``grain_tol_deg``: each piece's grain (``garment.grains()``) within this many degrees
    of the fabric's grain (at ``fabric_grain_deg`` in fabric space), at 0 or 180 degrees,
    only 0 with ``nap``, 45 degrees more for bias pieces; None turns pieces freely;
    ``rotation``/``translation`` False keep that part at ``init``.
    The report's ``e_fit_*`` figures use the garment's own seam weights, as `station fit`
    does; with ``weights`` the optimised objective is reported as ``objective_mm2``.
    """
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; expected one of {', '.join(METHODS)}")
    start = time.perf_counter()
    weighted = garment.with_seam_weights(weights) if weights else garment
    fix_rot, fix_trans = parse_fix(garment, fix)
    if init is not None and init.n_pieces != garment.n_pieces:
        raise ValueError(f"initial placement has {init.n_pieces} pieces, the garment "
                         f"{garment.n_pieces}")
    grain = None if grain_tol_deg is None else GrainRule.from_garment(
        garment, grain_tol_deg, nap=nap, fabric_grain_deg=fabric_grain_deg)
    problem = AlignProblem.build(
        weighted, fabric, fix_rot=fix_rot, fix_trans=fix_trans,
        init_angles=None if init is None else init.angles,
        init_translations=None if init is None else init.translations,
        grain=grain, reflect=reflect, use_drape=use_drape)
    run = align_paper if method == "paper" else align_global
    res = run(problem, restarts=restarts, seed=seed, rotation=rotation,
              translation=translation, progress=progress)
    placement = Placement(res.angles, res.translations, fabric,
                          garment=getattr(garment, "source", None) or None,
                          garment_units=_named_units(garment),
                          piece_names=list(garment.piece_names),
                          grains=[g.to_dict() for g in garment.grains()],
                          grain_rule={"tolerance_deg": grain_tol_deg, "nap": bool(nap),
                                      "fabric_grain_deg": float(fabric_grain_deg)})
    placement.report = {
        "method": method,
        "restarts": int(restarts),
        "seed": int(seed),
        "group": fabric.group,
        **_fit_figures(garment, placement, problem, res),
        "rotation": bool(rotation),
        "translation": bool(translation),
        "reflect": bool(reflect),
        "grain_tol_deg": grain_tol_deg,
        **grain_report(garment, res.angles, nap=nap, fabric_grain_deg=fabric_grain_deg),
        "fixed": {garment.piece_names[i]: ("both" if fix_rot[i] and fix_trans[i]
                                           else "rot" if fix_rot[i] else "trans")
                  for i in np.flatnonzero(fix_rot | fix_trans)},
    }
    if "paper_energy" in res.info:
        placement.report["e_fit_paper_objective_mm2"] = float(res.info["paper_energy"])
    if weights:
        placement.report["weights"] = {str(k): float(v) for k, v in weights.items()}
        placement.report["objective_mm2"] = float(res.energy)
    placement.report["seconds"] = time.perf_counter() - start
    return placement


def _fit_figures(garment, placement: Placement, problem: AlignProblem, res) -> dict:
    """The report's size, E_fit (aligned, and of the random starts, with the garment's own
    seam weights) and iteration figures."""
    fit = fit_report(garment, placement)
    e_random = problem.energy(res.info["random_angles"], res.info["random_translations"],
                              weight=garment.seam_weights())
    return {
        "pieces": int(garment.n_pieces),
        "seam_edges": int(len(garment.seam_edges)),
        "frames": "drape" if problem.frames.drape else "pattern",
        **fit.summary(),
        "e_fit_aligned_mm2": fit.e_fit_mm2,
        "e_fit_aligned_cm2": fit.e_fit_cm2,
        "e_fit_random_mm2": float(e_random.mean()),
        "e_fit_random_cm2": float(e_random.mean()) / 100.0,
        "ratio_aligned_random": (fit.e_fit_mm2 / float(e_random.mean())
                                 if e_random.mean() > 0 else 0.0),
        "rotation_iterations_mean": float(np.mean(res.rotation_iterations)),
        "translation_iterations_mean": float(np.mean(res.translation_iterations)),
    }


def grain_report(garment, angles: np.ndarray, *, nap: bool = False,
                 fabric_grain_deg: float = 0.0) -> dict:
    """Per piece its grain and how far (degrees) the placement turns it off grain: from
    the nearest allowed turn (straight, or bias), whatever tolerance was asked for."""
    rule = GrainRule.from_garment(garment, 0.0, nap=nap, fabric_grain_deg=fabric_grain_deg)
    off = np.degrees(rule.violation(np.asarray(angles, float)))
    turn = rule.relative_deg(np.asarray(angles, float))
    grains = garment.grains()
    return {
        "grain": [{"piece": garment.piece_names[i], **g.to_dict(),
                   "turn_deg": round(float(turn[i]), 4), "off_grain_deg": round(float(off[i]), 4)}
                  for i, g in enumerate(grains)],
        "grain_guessed": [garment.piece_names[i] for i, g in enumerate(grains) if g.guessed],
        "off_grain_max_deg": float(off.max()) if len(off) else 0.0,
    }


def _named_units(garment) -> str | None:
    """The garment file's units when they have a name (they go into PLACEMENT.json)."""
    units = getattr(garment, "units_in_file", None)
    return units if units in MM_PER_UNIT else None
