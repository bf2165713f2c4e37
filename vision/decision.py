"""The answer among the likely groups: the likeliest one whose operations hold on the
single repeats as on the mean cell, and none of which leaves a residual shared all over
the cloth; else its likeliest subgroup that does (the safe side), with the reason the
likelier group was refused, for the operator."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from vision.consistency import SAMPLE, RepeatSpectra, asymmetry
from vision.groupfit import GroupFit
from vision.isometries import isometry_key, isometry_name
from vision.neighbours import neighbour_correlation
from vision.subgroups import is_subgroup

__all__ = ["ADDED_OPERATION_LAG", "OWN_ASYMMETRY", "REPEAT_SUPPORT", "SHARED_ASYMMETRY",
           "Refusal", "invents", "lagging_subgroup", "repeat_support", "supported_winner"]

#: An operation the mean cell shows must also hold on the single repeats, at least this
#: well relative to how well one repeat matches the next; else it is an artefact of
#: averaging (blur from misregistered, distorted repeats makes any cell symmetric).
REPEAT_SUPPORT = 0.5

#: How far the operations a group adds to its subgroup (or to the translations, which
#: every group has) may all score below the subgroup's own (reliability-normalised)
#: before the group is not taken. On 240 small
#: synthetic prints under blur up to 3 px and noise, the operations of true groups spread
#: by at most 0.030; symmetries made by blur (p6 as p6m, p31m as p6m) lag by 0.064 or more.
ADDED_OPERATION_LAG = 0.045

#: An operation leaves the print's own asymmetry, not the cloth's, when the residual
#: the two outer thirds of the cloth share is more than this much of the motif (about
#: 1 - the motif's correlation with its image, noise and local distortion removed):
#: the pick of leave-one-source-out over 0.002-0.04 for every held-out source; a faint
#: layer of a subgroup leaves 0.004-0.07, true operations on stretched, wrinkled,
#: misregistered cloth up to 0.0036 where their residual is shared at all (share >
#: 0.4; BENCHMARKS.md) ...
OWN_ASYMMETRY = 0.004

#: ... and more than this part of a single repeat's residual, i.e. what every repeat
#: shares clearly outweighs what noise, wrinkles and local stretch add (the training
#: sources are indifferent between 0.5 and 0.6; lower values cost stretched and
#: misregistered cloth its group; a labelled photograph's true mirror has 0.56).
SHARED_ASYMMETRY = 0.6


def repeat_support(cells: np.ndarray, ops: list[tuple[np.ndarray, np.ndarray]]
                   ) -> np.ndarray:
    """Per operation (A, s): the median over repeats of corr(c_r, c_r(A f + s)) divided
    by the median of corr(c_r, c_r+1) (whole-cell correlations of single repeats, so
    noise lowers both alike). About 1 for a symmetry of the print, near 0 otherwise.
    The operations are checked on a sample of ``SAMPLE`` repeats spread over all: on
    fine prints of 400 repeats every one cost 0.4 s."""
    n = cells.shape[-1]
    base = max(neighbour_correlation(cells), 1e-3)
    pick = np.linspace(0, len(cells) - 1, min(len(cells), SAMPLE)).round().astype(int)
    flat = cells[pick].reshape(len(pick), -1)
    energy = np.maximum(np.einsum("ij,ij->i", flat, flat), 1e-12)
    g = np.arange(n)
    fa, fb = np.meshgrid(g, g, indexing="ij")
    out = np.empty(len(ops))
    for k, (a, sh) in enumerate(ops):
        ia = (a[0, 0] * fa + a[0, 1] * fb + sh[0]) % n
        ib = (a[1, 0] * fa + a[1, 1] * fb + sh[1]) % n
        sym = np.einsum("ij,ij->i", flat, flat[:, (ia * n + ib).ravel()]) / energy
        out[k] = float(np.median(sym)) / base
    return out


class Refusal(NamedTuple):
    """A group likelier than the answer that was not taken, and why (for the operator)."""

    group: str
    why: str


def supported_winner(names: list[str], ll: np.ndarray, best: dict[str, GroupFit],
                     cells: np.ndarray, scores: dict, basis: np.ndarray, *,
                     translation: float = 1.0, lag: float = ADDED_OPERATION_LAG,
                     spectra: RepeatSpectra | None = None,
                     asym: tuple[float, float] | None = None) -> tuple[str, Refusal | None]:
    """The likeliest group whose added operations hold like its subgroups', that holds
    on the single repeats and none of whose operations leaves a consistent residual;
    else its likeliest subgroup that does (the safe side). With it, the likeliest group
    refused on the way and why, or None: the operator confirming the answer sees why a
    likelier group was not taken.

    Added operations: blur, noise and distortion lower every symmetry of a print
    together (blur not at all), while one that blur has half-made (the chiral detail of
    a p6 print blurred away reads as p6m's mirrors) lags behind the print's true ones.
    A group is not taken when every operation it adds to a maximal subgroup scores
    (best per class, ``scores``) below every operation of that subgroup by more than
    ``ADDED_OPERATION_LAG``. Single repeats: see :func:`repeat_support` (needs three
    repeats; with fewer the mean cell decides). Consistent residuals: see
    :func:`invents` (needs ``spectra``, three repeats or more). ``basis`` (working px)
    names the operations."""
    order = [names[k] for k in np.argsort(-ll)]
    top = order[0]
    seen: dict = {}
    first: Refusal | None = None
    for name in order:
        if not is_subgroup(name, top):
            continue
        why = _refusal(name, best, cells, scores, basis, translation=translation, lag=lag,
                       spectra=spectra, seen=seen, asym=asym)
        if not why:
            return name, first
        first = first or Refusal(name, why)
    return top, None


def _refusal(name: str, best: dict[str, GroupFit], cells: np.ndarray, scores: dict,
             basis: np.ndarray, *, translation: float, lag: float,
             spectra: RepeatSpectra | None, seen: dict, asym: tuple[float, float] | None
             ) -> str:
    """Why ``name`` cannot be the answer (see :func:`supported_winner`); empty when it
    can."""
    lagging = lagging_subgroup(name, best, scores, translation, lag)
    if lagging:
        sub, behind = lagging
        ref = "the translations" if sub == "p1" else f"{sub}'s"
        return (f"the operations it adds to {sub} score {behind:.2f} below {ref}, as blur or "
                "distortion half-making a symmetry leaves them")
    ops = best[name].ops
    if len(cells) >= 3 and ops:
        support = repeat_support(cells, ops)
        k = int(np.argmin(support))
        if support[k] < REPEAT_SUPPORT:
            return (f"the {isometry_name(ops[k][0], basis)} holds on the mean cell but not on "
                    f"single repeats (support {support[k]:.2f}, under {REPEAT_SUPPORT:g})")
    broken = None if spectra is None else invents(ops, spectra, seen, *(asym or ()))
    if broken is not None:
        return (f"the {isometry_name(broken, basis)} leaves the same residual all over the "
                "cloth: a part of the print it does not map onto itself")
    return ""


def invents(ops: list[tuple[np.ndarray, np.ndarray]], spectra: RepeatSpectra,
            seen: dict | None = None, own: float = OWN_ASYMMETRY,
            shared: float = SHARED_ASYMMETRY) -> np.ndarray | None:
    """The matrix A of the first operation (A, s) that leaves the same residual all over
    the cloth (:func:`vision.consistency.asymmetry`): a faint stroke of the print that
    the operation does not map onto itself, however small its lag: more than ``own`` of
    the motif, more than ``shared`` of a single repeat's residual. None when no
    operation does. ``seen`` caches operations shared by several groups."""
    seen = {} if seen is None else seen
    for a, s in ops:
        key = (isometry_key(a), int(s[0]), int(s[1]))
        if key not in seen:
            asym = asymmetry(spectra, a, s)
            seen[key] = asym.own > own and asym.share > shared
        if seen[key]:
            return a
    return None


def lagging_subgroup(name: str, best: dict[str, GroupFit], scores: dict,
                     translation: float = 1.0, lag: float = ADDED_OPERATION_LAG
                     ) -> tuple[str, float] | None:
    """The maximal subgroup (half its point group, as found in this print) whose
    operations all score above every operation ``name`` adds to it by more than
    ``lag``, with that lag; None when there is none. p1's operations are the
    translations, scoring ``translation`` (the motif's reliability over the score
    ceiling, 1 unless the cell is very noisy, less the single repeats' disagreement):
    so a group over p1 is measured against them, the way a near-symmetric print (a bold
    bar that is its own half turn, thin strokes that are not) shows its lag."""
    have = best[name].present
    for sub, entry in best.items():
        own = entry.present
        if sub == name or not own < have or 2 * (len(own) + 1) != len(have) + 1:
            continue
        added = have - own
        ref = min(scores[k] for k in own) if own else translation
        behind = ref - max(scores[k] for k in added)
        if behind > lag:
            return sub, behind
    return None
