"""Symmetric placement: the print on a left/right pair mirrors, as a tailor cuts "a pair".

For a mirror pair (i, j) with ``q = M p`` (``M = R_m FLIP p + t_m``, from
`solver.garment.symmetry`), the print on j at ``M p`` must equal the print on i at ``p``.
With ``w_c(p) = R_c^T (p - t_c)`` (the placement's wallpaper coordinates) that means

    w_j(q) = h(w_i(M^-1 q))        h(w) = G w + tau, an opposite isometry,

which holds for every point exactly when h is an operation of the print's group: then
piece j's placement follows from piece i's,

    R_j = R_m FLIP R_i G^T,        t_j = t_m + R_j (G R_i^T t_i - tau),

and E_fit of the garment equals E_fit of a *quotient* garment in which j's pattern is
mapped back onto i (``M^-1``) and shares i's placement: the pair shares its unknowns, so
the search has fewer of them, and every method of `solver.align` runs on it unchanged.
The grain rule asks for ``G`` to keep the fabric's grain (a mirror or glide along it, or
across it where the print has no nap).

A piece cut on the fold (`solver.garment.symmetry.fold_pairs`) is the same idea with
``j = i``: its mirror across the fold takes it onto itself, and its print must mirror about
the fold as a pair's prints mirror about their centre seam, i.e. the fold lies on a mirror
axis of the print. It keeps its own unknowns; `PairTie` projects them onto the constraint
(angle fixed, translation free along the fold only). With a glide and no mirror along the
grain the fold lies on the glide axis: the print mirrored across it, shifted along it.

Where the group has no such operation (p1, p2, p3, p4, p6, or mirrors off grain) the pair
is kept "same": ``G`` is the reflection along the grain and ``tau = 0``, so the print's
lattice sits at the same place relative to the flipped outline, but the motif is not
mirrored. The quotient's E_fit then measures j's seams as if its print were mirrored,
which is not the garment cut: the quotient's answer only starts `search_tied`, which
minimises the garment's own E_fit over the same unknowns, j following i (`PairTie`).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from solver.align.driver import align, grain_report, parse_fix
from solver.align.grain import GrainRule
from solver.align.problem import AlignProblem
from solver.align.refine import _energy_grad, bfgs_refine
from solver.fit import fit_report
from solver.garment.grain import paired_grains
from solver.garment.model import Garment
from solver.garment.symmetry import MirrorPair, fold_pairs
from solver.geometry import FLIP, rotation_matrices
from solver.placement import Placement
from solver.wallpaper import Wallpaper

MODES = ("mirror", "same")
GLIDE_MM = 0.1  # a fold's print mismatch above this: its operation is a glide
_NEIGHBOURS = np.array([(a, b) for a in (-1, 0, 1) for b in (-1, 0, 1)], float)


@dataclass(frozen=True)
class PairRule:
    """How the pair (first, second) is kept: ``mode`` and the opposite isometry ``op``
    (3x3 homogeneous, wallpaper mm) taking the first piece's print to the second's."""

    pair: MirrorPair
    mode: str
    op: np.ndarray

    @property
    def first(self) -> int:
        return self.pair.first

    @property
    def second(self) -> int:
        return self.pair.second


def _reflection_along(axis: np.ndarray) -> np.ndarray:
    """Linear reflection that keeps ``axis`` and reverses its normal."""
    a = axis / np.linalg.norm(axis)
    return 2.0 * np.outer(a, a) - np.eye(2)


def pair_rule(pair: MirrorPair, fabric: Wallpaper, *, grain_deg: float = 0.0,
              nap: bool = False, grain_tol_deg: float | None = 1.0) -> PairRule:
    """The rule for one pair: an opposite operation of the print whose mirror axis keeps
    the grain ("mirror"), else "same".

    The second piece's grain is the first's reflected across the operation's axis, so an
    axis ``b`` degrees off the grain turns it ``2 b`` off: the axis must lie within half
    the grain tolerance of the grain (along it preferred, across it allowed without nap;
    a detected print is never exactly square to the roll). Without a grain rule any
    mirror or glide will do, the one closest to the grain first.
    """
    half = np.inf if grain_tol_deg is None else 0.5 * grain_tol_deg + 1e-9
    best, best_off = None, np.inf
    for op in fabric.cartesian_ops():
        lin = op[:2, :2]
        if np.linalg.det(lin) > 0:
            continue
        axis = 0.5 * np.degrees(np.arctan2(lin[1, 0], lin[0, 0]))
        off = abs((axis - grain_deg + 90.0) % 180.0 - 90.0)  # along the grain
        across = abs((axis - grain_deg) % 180.0 - 90.0)
        if not nap:  # across the grain, ranked after any axis along it
            off = min(off, across + 180.0)
        if off < best_off:
            best, best_off = op, off
    if best is not None and best_off % 180.0 <= half:
        return PairRule(pair, "mirror", best.copy())
    same = np.eye(3)
    same[:2, :2] = _reflection_along(np.array([np.cos(np.radians(grain_deg)),
                                               np.sin(np.radians(grain_deg))]))
    return PairRule(pair, "same", same)


def expand(quotient: Placement, rules: Sequence[PairRule], keep: np.ndarray,
           n_pieces: int) -> tuple[np.ndarray, np.ndarray]:
    """Angles (P,) and translations (P,2) of the whole garment from the quotient's.

    ``keep`` (P,) gives each piece's index in the quotient (the second piece of a pair
    maps to its first piece's index).
    """
    return PairTie(tuple(rules), keep, quotient.fabric).expand(quotient.angles,
                                                              quotient.translations)


@dataclass(frozen=True)
class PairTie:
    """The whole garment's placement as a function of the quotient's unknowns: the
    second piece of a pair follows its first (``R_j = R_m FLIP R_i G^T``,
    ``t_j = t_m + R_m FLIP t_i - R_j tau``), batched, with the chain rule back.

    A fold is a pair of a piece with itself (``i == j``): the same map, met halfway. The
    angle becomes the fixed point of ``theta -> const - theta`` nearest the piece's (the
    fold onto the operation's axis); the translation moves across the fold by half the gap
    between the placement and its mirror image, that gap first reduced by the print's
    lattice (``fabric``), so the fold lands on the nearest mirror line of that direction
    (not a glide line of a centred lattice), and stays free along it. Rules run in order:
    a fold before a pair that copies its piece."""

    rules: tuple[PairRule, ...]
    keep: np.ndarray  # (P,) each piece's index in the quotient
    fabric: Wallpaper | None = None  # needed for folds only

    def expand(self, q_angles: np.ndarray, q_trans: np.ndarray):
        """(..., Q) angles, (..., Q, 2) translations -> (..., P), (..., P, 2)."""
        angles = np.array(np.asarray(q_angles, float)[..., self.keep])
        trans = np.array(np.asarray(q_trans, float)[..., self.keep, :])
        for rule in self.rules:
            i, j = rule.first, rule.second
            mirror = rule.pair.rotation @ FLIP
            r_j = mirror @ rotation_matrices(angles[..., i]) @ rule.op[:2, :2].T
            a_j = np.arctan2(r_j[..., 1, 0], r_j[..., 0, 0])
            if i == j:
                a_j = angles[..., i] + 0.5 * ((a_j - angles[..., i] + np.pi) % (2 * np.pi) - np.pi)
                r_j = rotation_matrices(a_j)
            t_j = rule.pair.translation + trans[..., i, :] @ mirror.T - r_j @ rule.op[:2, 2]
            if i == j:
                gap = np.einsum("...ji,...j->...i", r_j, trans[..., i, :] - t_j)
                gap = np.einsum("...ij,...j->...i", r_j, self._least_glide(rule, gap))
                t_j = trans[..., i, :] - 0.25 * gap @ (np.eye(2) - mirror).T
            angles[..., j], trans[..., j, :] = a_j, t_j
        return angles, trans

    def _least_glide(self, rule: PairRule, gap: np.ndarray) -> np.ndarray:
        """The representative of each ``gap`` (..., 2) (wallpaper mm, a fold's placement
        minus its mirror image) modulo the print's lattice with the least residue along
        the operation's axis (a mirror line rather than a glide line of a centred
        lattice), then the least across it (the nearest such line)."""
        half = 0.5 * np.arctan2(rule.op[1, 0], rule.op[0, 0])
        axis = np.array([np.cos(half), np.sin(half)])
        cand = (self.fabric.lattice_residual(gap)[..., None, :]
                + _NEIGHBOURS @ self.fabric.basis.T)
        along, across = np.abs(cand @ axis), np.abs(cand @ np.array([-axis[1], axis[0]]))
        best = np.argmin(np.round(along, 6) * 1e6 + across, axis=-1)
        return np.take_along_axis(cand, best[..., None, None], axis=-2)[..., 0, :]

    def pull_back(self, angles: np.ndarray, g_angles: np.ndarray, g_trans: np.ndarray):
        """Gradient in the garment's angles (P,) and translations (P,2), at the garment's
        ``angles``, -> gradient in the quotient's unknowns (Q,), (Q,2)."""
        g_a, g_t = np.array(g_angles, float), np.array(g_trans, float)
        turn = np.array([[0.0, -1.0], [1.0, 0.0]])  # dR/dtheta = R turn
        for rule in reversed(self.rules):
            i, j = rule.first, rule.second
            mirror = rule.pair.rotation @ FLIP
            if i == j:  # a fold: the angle is fixed, t -> (I + mirror) t / 2 + const
                g_a[i] = 0.0
                g_t[i] = 0.5 * (g_t[i] + mirror.T @ g_t[i])
                continue
            r_j = rotation_matrices(angles[j:j + 1])[0]
            # theta_j = const - theta_i; t_j depends on theta_i through -R_j tau
            g_a[i] += -g_a[j] + g_t[j] @ (r_j @ turn @ rule.op[:2, 2])
            g_t[i] += mirror.T @ g_t[j]
        lead = np.ones(len(self.keep), bool)
        lead[[r.second for r in self.rules if r.first != r.second]] = False
        q = int(self.keep.max()) + 1
        gq_a, gq_t = np.zeros(q), np.zeros((q, 2))
        np.add.at(gq_a, self.keep[lead], g_a[lead])
        np.add.at(gq_t, self.keep[lead], g_t[lead])
        return gq_a, gq_t


def quotient_garment(garment: Garment, rules: Sequence[PairRule]) -> tuple[Garment, np.ndarray]:
    """The garment with the second piece of every pair mapped onto the first (``M^-1``)
    and merged into it, and ``keep`` (P,): each piece's index in the quotient."""
    p = garment.n_pieces
    owner = np.arange(p)
    uv = garment.uv.copy()
    faces = garment.faces.copy()
    face_piece = garment.piece_of_face()
    for rule in rules:
        i, j = rule.first, rule.second
        if i == j:
            continue  # a fold: the piece stays whole, its tie is PairTie's
        owner[j] = i
        on = garment.piece_of_vertex == j
        uv[on] = (garment.uv[on] - rule.pair.translation) @ rule.pair.rotation @ FLIP
        mirrored = face_piece == j
        faces[mirrored] = faces[mirrored][:, [0, 2, 1]]  # keep triangles counter-clockwise
    kept = np.flatnonzero(owner == np.arange(p))
    index = np.full(p, -1)
    index[kept] = np.arange(len(kept))
    keep = index[owner]
    lines = [dataclasses.replace(s, piece_a=int(keep[s.piece_a]), piece_b=int(keep[s.piece_b]))
             for s in garment.seam_lines]
    q = garment.copy()
    q.uv, q.faces = uv, faces
    q.piece_of_vertex = keep[garment.piece_of_vertex]
    q.piece_names = [garment.piece_names[k] for k in kept]
    q.seam_lines = lines
    q.grainlines = {int(keep[k]): v for k, v in garment.grainlines.items() if k in kept}
    q.grain = tuple(garment.grains()[k] for k in kept)  # a pair takes its first's grain
    q.notches = {int(keep[k]): v for k, v in garment.notches.items() if k in kept}
    q.folds = {int(keep[k]): v for k, v in garment.folds.items() if k in kept}
    q._loops = None
    return q, keep


def pair_mismatch_mm(garment: Garment, placement: Placement, rule: PairRule,
                     samples: int = 64) -> float:
    """Largest print mismatch (mm) between points of the first piece and their mirror
    images on the second: 0 when the pair is mirrored exactly ("mirror" rules)."""
    outline = garment.piece_outline(rule.first)
    pts = outline[np.linspace(0, len(outline) - 1, min(samples, len(outline))).astype(int)]
    inside = np.vstack([pts, 0.5 * (pts + pts.mean(axis=0))])
    w_i = placement.to_wallpaper(inside, np.full(len(inside), rule.first))
    w_j = placement.to_wallpaper(rule.pair.map_first_to_second(inside),
                                 np.full(len(inside), rule.second))
    return float(placement.fabric.mismatch_distance(w_j, w_i).max())


def align_symmetric(garment: Garment, fabric: Wallpaper, pairs: Sequence[MirrorPair], *,
                    compare: bool = True, grain_deg: float = 0.0, nap: bool = False,
                    fix: list[str] | None = None, init: Placement | None = None,
                    **options) -> Placement:
    """`solver.align.align` with every mirror pair kept as a hard constraint.

    The search runs on the quotient garment (one set of unknowns per pair). With
    ``compare`` the unconstrained alignment is run too, so that the report shows the
    constraint's price: ``symmetry.e_fit_unconstrained_mm2`` beside ``e_fit_aligned_mm2``.
    ``fix`` names pieces as `align` does; the second piece of a pair follows its first.
    """
    start = time.perf_counter()
    garment = garment.copy()  # the pairs' two pieces take mirrored grains
    copied = {p.second for p in pairs}  # a second piece's fold follows its first's
    folds = [f for f in fold_pairs(garment) if f.first not in copied]
    garment.grain = paired_grains(garment.grains(), [*folds, *pairs])
    # a fold's axis must run along the fold: one across the grain would turn the piece
    # a quarter off it (``nap`` allows only the axes along)
    rules = [pair_rule(p, fabric, grain_deg=grain_deg + _fold_to_grain_deg(garment, p),
                       nap=nap or p.first == p.second,
                       grain_tol_deg=options.get("grain_tol_deg", 1.0))
             for p in [*folds, *pairs]]
    quotient, keep = quotient_garment(garment, rules)
    seconds = {"symmetric": 0.0, "unconstrained": 0.0}
    q_init = None
    if init is not None:
        if init.n_pieces != garment.n_pieces:
            raise ValueError(f"initial placement has {init.n_pieces} pieces, the garment "
                             f"{garment.n_pieces}")
        first_of = _first_of(keep)
        q_init = Placement(init.angles[first_of], init.translations[first_of], fabric)
    q_fix = [_fix_in_quotient(spec, garment, quotient, keep) for spec in fix or []]
    options = dict(options, nap=nap, fabric_grain_deg=grain_deg)
    q_options = _quotient_options(garment, fabric, rules, keep, options)
    t0 = time.perf_counter()
    q_place = align(quotient, fabric, fix=q_fix or None, init=q_init, **q_options)
    tie = PairTie(tuple(rules), keep, fabric)
    angles, trans = tie.expand(q_place.angles, q_place.translations)
    tied = None
    if any(r.mode == "same" or r.first == r.second for r in rules):
        q_angles, q_trans, tied = search_tied(garment, quotient, fabric, tie, q_place,
                                              fix=q_fix, init=q_init, **q_options)
        angles, trans = tie.expand(q_angles, q_trans)
    seconds["symmetric"] = time.perf_counter() - t0
    placement = Placement(angles, trans, fabric, garment=garment.source or None,
                          garment_units=q_place.garment_units,
                          piece_names=list(garment.piece_names),
                          grains=[g.to_dict() for g in garment.grains()],
                          grain_rule=dict(q_place.grain_rule))
    fit = fit_report(garment, placement)
    report = _expanded_report(q_place.report, garment, fit, angles, nap, grain_deg,
                              options.get("grain_tol_deg", 1.0))
    placement.grain_rule["tolerance_deg"] = report["grain_tol_deg"]
    symmetry = _symmetry_section(garment, quotient, placement, rules, fit, tied)
    if compare:
        t0 = time.perf_counter()
        free = align(garment, fabric, fix=fix, init=init, **options)
        seconds["unconstrained"] = time.perf_counter() - t0
        e_free = free.report["e_fit_aligned_mm2"]
        symmetry["e_fit_unconstrained_mm2"] = e_free
        symmetry["price_ratio"] = fit.e_fit_mm2 / e_free if e_free > 0 else 1.0
    symmetry["seconds"] = seconds
    report["symmetry"] = symmetry
    report["seconds"] = time.perf_counter() - start
    placement.report = report
    placement.pairs = symmetry["pairs"]
    return placement


def _quotient_options(garment: Garment, fabric: Wallpaper, rules: Sequence[PairRule],
                      keep: np.ndarray, options: dict) -> dict:
    """`align`'s options for the quotient: the second piece inherits the first's angle to
    the grain, plus the pair's own small disagreement of grain lines, so the first is
    kept that much closer to grain."""
    q_options = dict(options)
    if options.get("grain_tol_deg", 1.0) is not None:
        slack = _pair_grain_disagreement(garment, fabric, rules, keep)
        q_options["grain_tol_deg"] = max(options.get("grain_tol_deg", 1.0) - slack, 0.0)
    return q_options


def _expanded_report(q_report: dict, garment: Garment, fit, angles: np.ndarray, nap: bool,
                     grain_deg: float, grain_tol_deg: float | None) -> dict:
    """The quotient's report with the whole garment's figures (E_fit, grain, sizes)."""
    report = dict(q_report)
    report.update(fit.summary())
    report.update(grain_report(garment, angles, nap=nap, fabric_grain_deg=grain_deg))
    report["grain_tol_deg"] = grain_tol_deg
    report.update(pieces=int(garment.n_pieces), seam_edges=int(len(garment.seam_edges)),
                  e_fit_aligned_mm2=fit.e_fit_mm2, e_fit_aligned_cm2=fit.e_fit_cm2)
    if report.get("e_fit_random_mm2"):
        report["ratio_aligned_random"] = fit.e_fit_mm2 / report["e_fit_random_mm2"]
    return report


def _symmetry_section(garment: Garment, quotient: Garment, placement: Placement,
                      rules: Sequence[PairRule], fit, tied: float | None) -> dict:
    """The report's ``symmetry`` entry: the pairs, their mirrors and print mismatch."""
    folds = [r for r in rules if r.first == r.second]
    rules = [r for r in rules if r.first != r.second]
    symmetry = {
        "pairs": [[r.first, r.second, r.mode] for r in rules],
        # the pattern mirror each pair was kept by (p_second = M [p_first; 1]): reshaping
        # moves the second piece by it, and a layout's check of the print must use it
        "mirror_maps": [np.column_stack([r.pair.rotation @ FLIP, r.pair.translation]).tolist()
                        for r in rules],
        "unknowns_pieces": int(quotient.n_pieces),
        "pair_print_mismatch_mm": [pair_mismatch_mm(garment, placement, r) for r in rules],
        "e_fit_symmetric_mm2": fit.e_fit_mm2,
    }
    if folds:  # a piece cut on the fold: its print mirrored about the fold
        symmetry["folds"] = [{"piece": garment.piece_names[r.first], "mode": r.mode,
                              "outline_rms_mm": r.pair.rms_mm,
                              "print_mismatch_mm": pair_mismatch_mm(garment, placement, r)}
                             for r in folds]
    if tied is not None:
        symmetry["e_fit_quotient_search_mm2"] = tied
    same = [f"{r.first}-{r.second}" for r in rules if r.mode == "same"]
    group = placement.fabric.group
    if any(r.mode == "same" for r in folds):
        symmetry["fold_note"] = (f"{group} has no mirror or glide along the fold: the "
                                 "print's lattice is centred on it, the motif not mirrored")
    elif any(f["print_mismatch_mm"] > GLIDE_MM for f in symmetry.get("folds", [])):
        symmetry["fold_note"] = (f"{group} has a glide, not a mirror, along the fold: the "
                                 "fold lies on the glide's axis, the print mirrored across "
                                 "it and shifted along it by the glide")
    if same:
        symmetry["note"] = (f"{placement.fabric.group} has no mirror or glide along the "
                            f"grain: pairs {', '.join(same)} keep the same print position "
                            "on the flipped outline, but their print is not mirrored")
    return symmetry


def search_tied(garment: Garment, quotient: Garment, fabric: Wallpaper, tie: PairTie,
                start: Placement, *, fix: list[str] | None = None,
                init: Placement | None = None, weights=None, grain_tol_deg: float | None = 1.0,
                nap: bool = False, fabric_grain_deg: float = 0.0, use_drape: bool = True,
                rotation: bool = True, translation: bool = True, sweeps: int = 2,
                grid: int = 12, **_) -> tuple[np.ndarray, np.ndarray, float]:
    """The quotient's unknowns that minimise the E_fit of the garment actually cut.

    With a "same" pair the quotient's E_fit is only a stand-in (it measures j's seams as
    if its print were mirrored), so from the quotient's answer ``start`` this searches on
    the garment's own E_fit, j following i through ``tie``: block-coordinate exhaustive
    moves (each quotient piece's print offset over a ``grid`` x ``grid`` cell grid,
    every candidate scored on the whole garment in one batch), then BFGS over angles and
    translations within the grain limits. Returns (angles, translations, E_fit before).
    """
    weighted = garment.with_seam_weights(weights) if weights else garment
    full = AlignProblem.build(weighted, fabric, use_drape=use_drape)
    fix_rot, fix_trans = parse_fix(quotient, fix)
    grain = None if grain_tol_deg is None else GrainRule.from_garment(
        quotient, grain_tol_deg, nap=nap, fabric_grain_deg=fabric_grain_deg)
    unknowns = AlignProblem.build(
        quotient, fabric, fix_rot=fix_rot | (not rotation), fix_trans=fix_trans | (not translation),
        init_angles=None if init is None else init.angles,
        init_translations=None if init is None else init.translations, grain=grain,
        use_drape=use_drape)
    rec = np.arange(full.frames.n_edges)
    w = full.weight * full.frames.length[rec]
    rec, w = rec[w > 0], w[w > 0]

    def objective(q_a: np.ndarray, q_t: np.ndarray):
        a, t = tie.expand(q_a, q_t)
        e, g_a, g_t = _energy_grad(full, a, t, rec, w)
        return e, *tie.pull_back(a, g_a, g_t)

    a, t = np.array(start.angles, float), np.array(start.translations, float)
    before = float(full.energy(*tie.expand(a[None], t[None]))[0])
    f = (np.arange(grid) + 0.5) / grid
    cell = np.stack(np.meshgrid(f, f, indexing="ij"), -1).reshape(-1, 2) @ fabric.basis.T
    for _ in range(sweeps):
        for c in np.flatnonzero(~unknowns.fix_trans):
            cand = np.repeat(t[None], len(cell) + 1, axis=0)
            cand[1:, c] -= cell @ rotation_matrices(a[c:c + 1])[0].T  # print shifted by cell
            e = full.energy(*tie.expand(np.broadcast_to(a, (len(cand), len(a))), cand))
            t = cand[int(np.argmin(e))]
        a, t, _ = bfgs_refine(unknowns, a, t, rotations=rotation, objective=objective)
    return a, t, before


def _fold_to_grain_deg(garment: Garment, pair: MirrorPair) -> float:
    """Degrees from a fold piece's grain to its fold line (0 for a pair of two pieces): the
    print's mirror axis is sought that far from the fabric's grain."""
    if pair.first != pair.second:
        return 0.0
    mirror = pair.rotation @ FLIP  # the reflection across the fold
    axis = 0.5 * np.degrees(np.arctan2(mirror[1, 0], mirror[0, 0]))
    return float((axis - garment.grains()[pair.first].deg + 90.0) % 180.0 - 90.0)


def _first_of(keep: np.ndarray) -> np.ndarray:
    """For each quotient piece, the garment piece it stands for (a pair's first piece)."""
    first_of = np.full(int(keep.max()) + 1, -1)
    first_of[keep[::-1]] = np.arange(len(keep))[::-1]  # the last write is the lowest piece
    return first_of


def _pair_grain_disagreement(garment: Garment, fabric: Wallpaper, rules: Sequence[PairRule],
                             keep: np.ndarray) -> float:
    """Degrees by which a pair's second piece lies off its grain when its first lies
    exactly on grain (0 for a pair whose grain lines mirror each other)."""
    if not rules:
        return 0.0
    grain = GrainRule.from_garment(garment, 0.0)  # the turns, whatever the fabric's grain
    on_grain = Placement(grain.centres[:, 0], np.zeros((garment.n_pieces, 2)), fabric)
    first_of = _first_of(keep)
    angles, _ = expand(Placement(on_grain.angles[first_of], on_grain.translations[first_of],
                                 fabric), rules, keep, garment.n_pieces)
    seconds = [r.second for r in rules]
    return float(np.degrees(grain.violation(angles)[seconds].max()))


def _fix_in_quotient(spec: str, garment: Garment, quotient: Garment, keep: np.ndarray) -> str:
    """A ``--fix`` spec of the garment, in the quotient's piece indices."""
    name, sep, kind = spec.rpartition(":") if spec.endswith((":rot", ":trans")) else (
        spec, "", "")
    names = {n: i for i, n in enumerate(garment.piece_names)}
    if name in names:
        c = names[name]
    elif name.isdigit() and int(name) < garment.n_pieces:
        c = int(name)
    else:
        return spec  # align reports the unknown piece
    return f"{int(keep[c])}{sep}{kind}"
