"""The lattice's basis from the autocorrelation's peaks: the densest lattice whose
points all carry strong autocorrelation (:func:`choose_basis`), then both vectors fitted by
weighted least squares on many sub-pixel peaks at once (:func:`refine_basis`)."""

from __future__ import annotations

from functools import cache

import numpy as np
from scipy import ndimage

from solver.wallpaper import gauss_reduce
from vision.autocorrelation import lattice_points, subpixel

__all__ = ["VERIFY_OVERLAP", "choose_basis", "nested", "refine_basis", "right_handed"]

#: Index of the nested lattices tried around the best-supported one: a partial symmetry
#: taken for a repeat, or a fundamental repeat lost in blur, differs from the true
#: lattice by index 2, 3 or 4 (half, third and quarter cells, and their products).
NEST_INDEX = (2, 3, 4)

#: Evidence (:func:`_coset_evidence`) at which a refinement's added lags count as
#: repeats. Calibrated on small blurred prints (seeds 11 and 23 of ``bench.vision``'s
#: ``blurred``, apart from the benchmark's seed 0): 0.85 takes glides' half shifts,
#: 0.95 misses fundamentals that wrinkles lowered.
REFINE_AT = 0.9

#: Evidence below which half of the chosen lattice's lags (an index-2 coset) is no
#: repeat. True lattices of small blurred prints keep 0.81 or more at 99 % (seeds 11
#: and 23); a glide's half shift that blur made look like a repeat scores 0.65.
COARSEN_BELOW = 0.7

#: Fewest lags on each side of an evidence comparison.
MIN_EVIDENCE = 2

#: Lags over which a lattice's support is measured, in its longest basis vector: its
#: shortest repeats (near: w1, w2 and the short diagonal), which blur, wrinkles and
#: perspective lower least and which rank the candidates, and several shells (far).
NEAR_REACH = 1.3
FAR_REACH = 2.6

#: Near support that makes a lattice a print even when its far lags decorrelate (a
#: wrinkled or tilted print); otherwise the far support must reach ``min_strength``.
#: Tilted frames' false fine lattices (partial repeats of motifs) reach 0.53; small
#: blurred prints' true lattices 0.55 and more (seeds 11 and 23, ``blurred``).
NEAR_STRENGTH = 0.55

#: Near supports this close count as equal (then the denser lattice is taken).
TIE = 0.02

#: Window overlap (its own autocorrelation) at the lags where a lattice is verified.
VERIFY_OVERLAP = 0.45


def _support(smooth, center, basis, radius):
    _, pts = lattice_points(basis, radius)
    samp = ndimage.map_coordinates(smooth, [pts[:, 0] + center[0], pts[:, 1] + center[1]],
                                   order=1, cval=np.nan)
    samp = samp[np.isfinite(samp)]
    if len(samp) < 2:
        return -1.0
    # Mean of the lower half: every point of a true lattice is a repeat, while a
    # spurious denser lattice has empty lags among its points.
    return float(np.mean(np.sort(samp)[: max(2, len(samp) // 2)]))


@cache
def _index_matrices(k: int) -> tuple[np.ndarray, ...]:
    """Integer matrices M (Hermite normal form) with det k: ``B M`` runs over every
    sub-lattice of index k of the lattice with basis B, ``B M^-T`` (not ``B M^-1``,
    which misses the centred one) over every lattice that holds it with index k."""
    return tuple(np.array([[a, b], [0, k // a]], float) for a in range(1, k + 1)
                 if k % a == 0 for b in range(a))


def _canonical(basis: np.ndarray) -> np.ndarray:
    r1, r2, _ = gauss_reduce(basis[:, 0], basis[:, 1], obtuse=True)
    if r1[0] < 0 or (r1[0] == 0 and r1[1] < 0):
        r1, r2 = -r1, -r2
    return np.column_stack([r1, r2])


def _key(basis: np.ndarray) -> tuple:
    return tuple(np.round(basis.T.ravel() / 1.5).astype(int))


def _verifiable(reliable: np.ndarray, center: np.ndarray, basis: np.ndarray) -> bool:
    """Whether the lattice's three shortest repeats (w1, w2 and the short diagonal of a
    reduced basis) lie at lags the window overlaps well (``reliable``): a lattice seen
    only at long lags, where the normalised autocorrelation rests on few pixels and
    runs high by chance, cannot be told from a multiple of the true one."""
    pts = np.round(np.stack([basis[:, 0], basis[:, 1], basis[:, 0] + basis[:, 1]])
                   + center).astype(int)
    inside = ((pts >= 0) & (pts < reliable.shape)).all(axis=1)
    return bool(inside.all() and reliable[pts[:, 0], pts[:, 1]].all())


def _coset_evidence(smooth: np.ndarray, center: np.ndarray, fine: np.ndarray,
                    coarse: np.ndarray) -> float:
    """How well the lags of ``fine`` that ``coarse`` (a sub-lattice of it) lacks repeat
    the print: their mean autocorrelation over what the coarse lattice's own points
    carry at the same lags. The autocorrelation falls with lag under blur and wrinkles,
    so the reference is a straight-line fit (never rising) of value against lag over the
    coarse points in the same disc; a true repeat scores about 1, a partial symmetry (a
    glide's half shift, a near-mirror) clearly less."""
    radius = max(2.6 * np.linalg.norm(fine, axis=0).max(),
                 2.2 * np.linalg.norm(coarse, axis=0).max())
    _, pts = lattice_points(fine, radius)
    vals = ndimage.map_coordinates(smooth, (pts + center).T, order=1, cval=np.nan)
    frac = pts @ np.linalg.inv(coarse).T
    on_coarse = np.abs(frac - np.round(frac)).max(axis=1) < 0.1
    lag = np.hypot(pts[:, 0], pts[:, 1])
    ok = np.isfinite(vals)
    ref_v, ref_l = vals[ok & on_coarse], lag[ok & on_coarse]
    new_v, new_l = vals[ok & ~on_coarse], lag[ok & ~on_coarse]
    if min(len(ref_v), len(new_v)) < MIN_EVIDENCE:
        return float("nan")  # too few well-overlapped lags to weigh
    slope = 0.0
    if len(ref_v) >= 3 and np.ptp(ref_l) > 1e-6:
        slope = min(0.0, float(np.polyfit(ref_l, ref_v, 1)[0]))
    expect = float(np.mean(ref_v)) + slope * (float(np.mean(new_l)) - float(np.mean(ref_l)))
    return float(np.mean(new_v)) / max(expect, 1e-6)


def choose_basis(acf: np.ndarray, valid: np.ndarray, reliable: np.ndarray, d: np.ndarray,
                 vals: np.ndarray, min_strength: float) -> tuple[np.ndarray | None, float]:
    """Densest lattice whose points all carry strong autocorrelation (basis columns in
    (row, col) px), with its support; None and the best support seen when none holds.

    Candidates are pairs of peaks (lags ``d``, heights ``vals``); one whose shortest
    repeats lie at poorly overlapped lags gives way to a checkable one that refines it.
    The one with the best near support (its shortest repeats) wins, and is tested
    against its nested lattices: a refinement (its candidates from the peaks, and every
    lattice holding it with index 2-4) is taken when the lags it adds repeat the print
    nearly as well as its own lags do at the same lag (``REFINE_AT``: the winner was a
    multiple whose fundamental peaks blur and wrinkles lowered), and never when they do
    clearly less (a partial symmetry, such as a glide's half shift under blur, is no
    repeat).
    """
    smooth = ndimage.maximum_filter(acf, size=3)
    smooth = np.where(valid, smooth, np.nan)
    center = np.array([acf.shape[0] // 2, acf.shape[1] // 2], float)
    bases = _candidate_bases(d, vals)
    # Lattices whose shortest repeats can be checked, when there are any (a print of
    # fewer than three repeats across offers none: then its lattice is taken as seen,
    # on strong near support only: its far shells lie where the window hardly overlaps,
    # and plain cloth's shading bands reach min_strength there).
    checkable = {k: b for k, b in bases.items() if _verifiable(reliable, center, b)}
    bases = checkable or bases
    current, strength = _best_supported(bases, bool(checkable), smooth, center, min_strength)
    if current is None:
        return None, strength
    current = _refined(current, bases, smooth, center, reliable, d)
    current = _coarsened(current, smooth, center, reliable)
    return current, _support(smooth, center, current,
                             FAR_REACH * np.linalg.norm(current, axis=0).max())


def _candidate_bases(d: np.ndarray, vals: np.ndarray) -> dict[tuple, np.ndarray]:
    """Reduced bases from pairs of peaks, by key: the shortest strong peaks (a fine
    print) and the tallest ones (the true repeats when side lobes of the motif crowd the
    short lags)."""
    vmax = float(vals.max())
    strong = np.flatnonzero(vals >= 0.45 * vmax)
    length = np.hypot(d[:, 0], d[:, 1])
    short = strong[np.argsort(length[strong])[:12]]
    top = np.flatnonzero(vals >= 0.85 * vmax)
    short_top = top[np.argsort(length[top])[:12]]
    cand = d[np.unique(np.concatenate([short, short_top]))]
    bases: dict = {}
    for a in range(len(cand)):
        for b in range(a + 1, len(cand)):
            u, v = cand[a], cand[b]
            cross = abs(u[0] * v[1] - u[1] * v[0])
            if cross < 0.2 * np.hypot(*u) * np.hypot(*v):
                continue
            basis = _canonical(np.column_stack([u, v]))
            bases.setdefault(_key(basis), basis)
    return bases


def _best_supported(bases: dict[tuple, np.ndarray], checkable: bool, smooth: np.ndarray,
                    center: np.ndarray, min_strength: float
                    ) -> tuple[np.ndarray | None, float]:
    """The candidate with the best near support, or one within ``TIE`` of it and denser
    (a multiple shares the true lattice's strongest lags and can tie with it), among
    those whose near support reaches ``NEAR_STRENGTH`` or (``checkable``) whose far
    support reaches ``min_strength``. None when no candidate is eligible, with the best
    far support (0 without candidates)."""
    if not bases:
        return None, 0.0
    scored = [tuple(_support(smooth, center, basis, reach * np.linalg.norm(basis, axis=0).max())
                    for reach in (NEAR_REACH, FAR_REACH)) for basis in bases.values()]
    eligible = [i for i, (near, far) in enumerate(scored)
                if near >= NEAR_STRENGTH or (checkable and far >= min_strength)]
    if not eligible:
        return None, max(far for _, far in scored)
    top = max(scored[i][0] for i in eligible)
    return min((list(bases.values())[i] for i in eligible if scored[i][0] >= top - TIE),
               key=lambda b: abs(np.linalg.det(b))), 0.0


def _refined(current: np.ndarray, bases: dict[tuple, np.ndarray], smooth: np.ndarray,
             center: np.ndarray, reliable: np.ndarray, peaks: np.ndarray) -> np.ndarray:
    """``current`` refined, one step at a time, to the best-evidenced lattice that holds
    it (index 2-4, or a denser candidate) whose added lags repeat the print
    (``REFINE_AT``): a refinement of high index mixes true added lags with spurious ones
    and averages them."""
    seen = {_key(current)}
    for _ in range(6):
        area = abs(np.linalg.det(current))
        finer = [_canonical(current @ np.linalg.inv(m.T)) for k in NEST_INDEX
                 for m in _index_matrices(k)]
        finer += [b for b in bases.values() if abs(np.linalg.det(b)) < area - 0.5
                  and nested(b, current)]
        finer = [b for b in finer if _key(b) not in seen and _on_peaks(b, peaks)
                 and _verifiable(reliable, center, b)]
        ev = [_coset_evidence(smooth, center, b, current) for b in finer]
        ok = [(e, -abs(np.linalg.det(b)), i) for i, (b, e) in enumerate(zip(finer, ev,
                                                                           strict=True))
              if e >= REFINE_AT]
        if not ok:
            break
        current = finer[max(ok)[2]]
        seen.add(_key(current))
    return current


def _coarsened(current: np.ndarray, smooth: np.ndarray, center: np.ndarray,
               reliable: np.ndarray) -> np.ndarray:
    """Half of the lattice's lags clearly weaker than the other half at the same lag
    (``COARSEN_BELOW``): a partial symmetry (a glide's half shift) taken for a repeat;
    the half that holds. Else ``current``."""
    coarser = [_canonical(current @ m) for m in _index_matrices(2)]
    coarser = [b for b in coarser if _verifiable(reliable, center, b)]
    ev = [_coset_evidence(smooth, center, current, b) for b in coarser]
    if ev and np.nanmin(ev, initial=np.inf) < COARSEN_BELOW:
        return coarser[int(np.nanargmin(ev))]
    return current


def _on_peaks(basis: np.ndarray, peaks: np.ndarray) -> bool:
    """Whether both basis vectors are autocorrelation peaks (up to sign): a repeat of
    the print is one, a lag inside the blurred central peak or between peaks is not."""
    tol = np.maximum(1.5, 0.05 * np.linalg.norm(basis, axis=0))
    dist = np.minimum(np.linalg.norm(peaks[:, None, :] - basis.T[None], axis=2),
                      np.linalg.norm(peaks[:, None, :] + basis.T[None], axis=2))
    return bool((dist.min(axis=0) <= tol).all())


def nested(fine: np.ndarray, coarse: np.ndarray) -> bool:
    """Whether every point of lattice ``coarse`` is a point of ``fine``."""
    m = np.linalg.solve(fine, coarse)
    return bool(np.abs(m - np.round(m)).max() < 0.1)


def refine_basis(acf: np.ndarray, valid: np.ndarray, basis: np.ndarray, rounds: int = 3
                 ) -> tuple[np.ndarray, np.ndarray, int]:
    """Weighted least squares on many sub-pixel peaks p = i w1 + j w2: the basis (columns,
    (row, col) px), the standard errors of its vectors and the number of peaks used.
    A round with too few peaks keeps the previous estimate."""
    h2, w2 = acf.shape
    center = np.array([h2 // 2, w2 // 2], float)
    sig = np.full(2, np.nan)
    n_used = 0
    radius_full = 0.75 * min(h2, w2)
    for it in range(rounds):
        radius = radius_full if it else min(radius_full, 4.5 * np.abs(basis).sum(0).max())
        n, ir = _lattice_lags(basis, radius, center, valid)
        if len(n) < 2:
            break
        pv, pos = _peaks_at(acf, ir, basis, center)
        good = pv > 0.3 * max(float(pv.max()), 1e-6)
        wgt = np.clip(pv, 0, None) * good
        if wgt.sum() <= 0 or good.sum() < 2:
            break
        sol, res, wgt, good2 = _robust_fit(n, pos, pv, good, wgt)
        if (good2.sum() < 3 or np.linalg.matrix_rank(n[good2]) < 2
                or np.abs(sol.T - basis).max() > 0.25 * np.linalg.norm(basis, axis=0).min()):
            break  # too few peaks to refine on: keep the peak-pair estimate
        basis = sol.T
        n_used = int(good2.sum())
        sig = _standard_errors(n, res, wgt, n_used)
    return basis, sig, n_used


def _lattice_lags(basis: np.ndarray, radius: float, center: np.ndarray, valid: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (i, j) of the lattice points within ``radius`` that lie inside the
    autocorrelation (3 px from its border) at a ``valid`` lag, and their pixels."""
    h2, w2 = valid.shape
    n, pts = lattice_points(basis, radius)
    rc = pts + center
    inside = (rc[:, 0] > 3) & (rc[:, 0] < h2 - 4) & (rc[:, 1] > 3) & (rc[:, 1] < w2 - 4)
    n, rc = n[inside], rc[inside]
    ir = np.round(rc).astype(int)
    ok = valid[ir[:, 0], ir[:, 1]]
    return n[ok], ir[ok]


def _peaks_at(acf: np.ndarray, ir: np.ndarray, basis: np.ndarray, center: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """Each lattice point ``ir`` snapped to the local maximum within a small window,
    then refined to sub-pixel: the peaks' heights and their lags from ``center``."""
    h2, w2 = acf.shape
    win = max(2, int(0.15 * min(np.hypot(*basis[:, 0]), np.hypot(*basis[:, 1]))))
    win = min(win, 6)
    offs = np.arange(-win, win + 1)
    dy, dx = np.meshgrid(offs, offs, indexing="ij")
    rr = np.clip(ir[:, 0, None] + dy.ravel()[None], 1, h2 - 2)
    cc = np.clip(ir[:, 1, None] + dx.ravel()[None], 1, w2 - 2)
    vals = acf[rr, cc]
    k = np.argmax(vals, axis=1)
    peak = np.stack([rr[np.arange(len(k)), k], cc[np.arange(len(k)), k]], axis=1)
    pv = vals[np.arange(len(k)), k]
    return pv, subpixel(acf, peak) - center


def _robust_fit(n: np.ndarray, pos: np.ndarray, pv: np.ndarray, good: np.ndarray,
                wgt: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Weighted least squares of ``pos = n @ sol``, refitted without the peaks off by
    more than three robust deviations: (sol, residuals, weights, peaks kept)."""
    sw = np.sqrt(wgt)[:, None]
    sol, *_ = np.linalg.lstsq(n * sw, pos * sw, rcond=None)
    res = pos - n @ sol
    r = np.hypot(res[:, 0], res[:, 1])
    thr = max(3 * np.median(r[good]) * 1.4826, 0.5)
    good2 = good & (r < thr)
    if good2.sum() >= 2:
        wgt = np.clip(pv, 0, None) * good2
        sw = np.sqrt(wgt)[:, None]
        sol, *_ = np.linalg.lstsq(n * sw, pos * sw, rcond=None)
        res = pos - n @ sol
    return sol, res, wgt, good2


def _standard_errors(n: np.ndarray, res: np.ndarray, wgt: np.ndarray, m: int) -> np.ndarray:
    """Standard errors of the two fitted vectors from the weighted residuals of ``m``
    peaks; NaN where the normal matrix is singular."""
    dof = max(m - 2, 1)
    s2 = float((wgt[:, None] * res**2).sum() / max(wgt.sum(), 1e-12)) * m / dof
    ntn = (n * wgt[:, None]).T @ n / max(wgt.mean(), 1e-12)
    try:
        cov = np.linalg.inv(ntn) * s2
        return np.sqrt(np.clip(np.diag(cov), 0, None))
    except np.linalg.LinAlgError:
        return np.full(2, np.nan)


def right_handed(b1: np.ndarray, b2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The reduced basis (row, col) turned right-handed in (x, y) where the reduction
    leaves the choice to noise: at a right angle ``-b2`` is as reduced as ``b2``."""
    det = b1[1] * b2[0] - b1[0] * b2[1]  # x1 y2 - y1 x2
    if det < 0 and abs(float(b1 @ b2)) <= 0.02 * float(np.hypot(*b1) * np.hypot(*b2)):
        return b1, -b2
    return b1, b2
