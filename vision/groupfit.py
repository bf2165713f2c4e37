"""Each of the 17 wallpaper groups read on a mean cell: in each basis of the lattice that
fits its convention (``solver.wallpaper`` ops conjugated by a unimodular ``U``), every
operation's translation part follows from one origin; the origin is found by summing
the scores of all the group's operations over every grid origin at once, then refined
to sub-grid precision. A group's likelihood: its operations should hold, every other
isometry class of the lattice should not, and the strain its lattice needs costs a prior.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from functools import lru_cache
from typing import NamedTuple

import numpy as np

from solver.wallpaper import GROUP_NAMES, GROUPS, Wallpaper
from vision.isometries import (
    correlation_at_shifts,
    isometry_key,
    isometry_label,
    reflection_classes,
    rounded_score,
)

__all__ = ["GroupFit", "fit_groups", "isometry_scores", "lattice_strain"]

def lattice_strain(measured: np.ndarray, ideal: np.ndarray) -> float:
    """Largest principal strain of the affine map taking ``ideal`` (2,2) onto
    ``measured`` (columns w1, w2): 0.1 is a 10 % stretch."""
    f = measured @ np.linalg.inv(ideal)
    return float(np.abs(np.linalg.svd(f, compute_uv=False) - 1.0).max())


@lru_cache(maxsize=1)
def _unimodular() -> tuple[tuple[np.ndarray, np.ndarray], ...]:
    """Unimodular integer matrices with entries in {-1, 0, 1}, with their inverses."""
    out = []
    for e in np.array(np.meshgrid(*[(-1, 0, 1)] * 4, indexing="ij")).reshape(4, -1).T:
        u = e.reshape(2, 2)
        if abs(round(np.linalg.det(u))) == 1:
            out.append((u.astype(int), np.rint(np.linalg.inv(u)).astype(int)))
    return tuple(out)


@lru_cache(maxsize=32)
def _group_ops(name: str) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
    info = GROUPS[name]
    return tuple((np.rint(op[:, :2]).astype(int), op[:, 2].copy()) for op in info.ops[1:])


def _log_sig(x: np.ndarray | float) -> np.ndarray:
    return -np.logaddexp(0.0, -np.asarray(x, float))


class GroupFit(NamedTuple):
    """A group's best reading of the motif: its log-likelihood, the unimodular ``u``
    taking the lattice basis to the group's conventional one, its origin (cell
    fractions), its operations with their translation parts on the grid, and the
    isometry classes (``(key, "rot" | "mirror" | "glide")``) those operations are."""

    score: float
    u: np.ndarray
    origin: np.ndarray
    ops: list[tuple[np.ndarray, np.ndarray]]
    present: frozenset


def isometry_scores(motif: np.ndarray, holo: list[np.ndarray], basis: np.ndarray,
                    ceiling: float, rounding: np.ndarray | None
                    ) -> tuple[dict, dict[tuple, float], dict[str, float]]:
    """Every lattice isometry scored at every translation part: the correlations by
    isometry key (raw; with what pixel ``rounding`` explains given back), the best
    score relative to ``ceiling`` of each isometry and class (rotation, mirror, glide:
    the "forbidden" terms of the groups without it), and the same by readable name."""
    n = motif.shape[0]
    corr = {isometry_key(a): correlation_at_shifts(motif, a) for a in holo}
    forb: dict[tuple, float] = {}
    op_scores: dict[str, float] = {}
    for a in holo:
        t = corr[isometry_key(a)] / ceiling
        classes = ([("rot", "", np.ones((n, n), bool))] if round(np.linalg.det(a)) == 1
                   else [(kind, tag, mask) for kind, tag, mask in
                         zip(("mirror", "glide"), "mg", reflection_classes(a, n),
                             strict=True) if mask.any()])
        for kind, tag, mask in classes:
            at = np.unravel_index(int(np.argmax(np.where(mask, t, -np.inf))), t.shape)
            if rounding is not None:
                # What rounding explains, measured at the class's best shift, is
                # given back at every shift of the class (the decision reads them all).
                gain = rounded_score(motif, a, np.array(at), rounding) - float(
                    corr[isometry_key(a)][at])
                corr[isometry_key(a)][mask] += gain
                t = corr[isometry_key(a)] / ceiling
            forb[(isometry_key(a), kind)] = float(t[at])
            op_scores[isometry_label(a, basis) + tag] = float(t[at])
    return corr, forb, op_scores


def _conventions(name: str, holo_keys: set, n: int
                 ) -> Iterator[tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]]]]:
    """The group's operations in each basis of the lattice that fits its convention
    (``solver.wallpaper`` ops conjugated by a unimodular ``u``), each distinct set
    once: ``(u, [(A, s on the grid), ...])``."""
    seen = set()
    for u, uinv in _unimodular():
        ops = []
        for a0, b0 in _group_ops(name):
            a = u @ a0 @ uinv
            b = u @ b0 * n
            if isometry_key(a) not in holo_keys or np.abs(b - np.rint(b)).max() > 1e-6:
                break
            ops.append((a, np.rint(b).astype(int) % n))
        else:
            sig = frozenset((isometry_key(a), tuple(b)) for a, b in ops)
            if sig not in seen:
                seen.add(sig)
                yield u, ops


def _origin_likelihood(ops: list[tuple[np.ndarray, np.ndarray]], corr: dict,
                       ceiling: float, tau: float, kappa: float
                       ) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]], set]:
    """Log-likelihood that every operation holds, at every grid origin at once (each
    operation's translation part follows from the origin); with each operation's
    translation part per origin and the isometry classes present."""
    n = next(iter(corr.values())).shape[0]
    g = np.arange(n)
    oa, ob = np.meshgrid(g, g, indexing="ij")
    total = np.zeros((n, n))
    present = set()
    shifts = []
    for a, b in ops:
        ia = (b[0] + (1 - a[0, 0]) * oa - a[0, 1] * ob) % n
        ib = (b[1] - a[1, 0] * oa + (1 - a[1, 1]) * ob) % n
        total += _log_sig((corr[isometry_key(a)][ia, ib] / ceiling - tau) / kappa)
        shifts.append((ia, ib))
        if round(np.linalg.det(a)) == 1:
            present.add((isometry_key(a), "rot"))
        else:
            mir, _ = reflection_classes(a, n)
            present.add((isometry_key(a), "mirror" if mir[b[0], b[1]] else "glide"))
    return total, shifts, present


def fit_groups(corr: dict, forb: dict[tuple, float], holo: list[np.ndarray],
               basis: np.ndarray, ceiling: float, *, tau: float, kappa: float,
               snap_tol: float, strain_sigma: float
               ) -> tuple[dict[str, GroupFit], dict[str, tuple[float, float]]]:
    """Each of the 17 groups' best reading (over its conventions and origins): its
    operations should hold, every other isometry class of the lattice should not, and
    the strain its lattice needs costs a prior. Groups whose lattice is beyond
    ``snap_tol`` come apart, as ``(score, strain)``: never the answer, but their
    operations holding is evidence against every answer that forbids them."""
    n = next(iter(corr.values())).shape[0]
    holo_keys = {isometry_key(a) for a in holo}
    best: dict[str, GroupFit] = {}
    beyond: dict[str, tuple[float, float]] = {}
    for name in GROUP_NAMES:
        for u, ops in _conventions(name, holo_keys, n):
            conv = basis @ u  # the group's conventional basis, working px
            try:
                ideal = Wallpaper.snapped(name, conv[:, 0], conv[:, 1],
                                          snap_tol=snap_tol).basis
                within = True
            except ValueError:
                ideal = Wallpaper.snapped(name, conv[:, 0], conv[:, 1],
                                          snap_tol=math.inf).basis
                within = False
            strain_needed = lattice_strain(conv, ideal)
            prior = -0.5 * (strain_needed / strain_sigma) ** 2
            total, shifts, present = _origin_likelihood(ops, corr, ceiling, tau, kappa)
            ka, kb = divmod(int(np.argmax(total)), n)
            absent = sum(float(_log_sig((tau - v) / kappa)) for key, v in forb.items()
                         if key not in present)
            score = float(total[ka, kb]) + absent + prior
            if not within:
                if score > beyond.get(name, (-np.inf,))[0]:
                    beyond[name] = (score, strain_needed)
            elif name not in best or score > best[name].score:
                at = [(a, np.array([ia[ka, kb], ib[ka, kb]]))
                      for (a, _), (ia, ib) in zip(ops, shifts, strict=True)]
                best[name] = GroupFit(score, u, _refine_origin(total, ka, kb) / n, at,
                                      frozenset(present))
    return best, {k: v for k, v in beyond.items() if k not in best}


def _refine_origin(total: np.ndarray, ka: int, kb: int) -> np.ndarray:
    """Sub-grid maximum of the periodic origin score by a parabola along each axis."""
    n = total.shape[0]

    def para(cm, c0, cp):
        den = cm - 2 * c0 + cp
        return 0.0 if abs(den) < 1e-12 else float(np.clip(0.5 * (cm - cp) / den, -0.5, 0.5))

    da = para(total[(ka - 1) % n, kb], total[ka, kb], total[(ka + 1) % n, kb])
    db = para(total[ka, (kb - 1) % n], total[ka, kb], total[ka, (kb + 1) % n])
    return np.array([ka + da, kb + db])
