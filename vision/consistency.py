"""Is a print's leftover asymmetry under an operation part of the motif, or of the cloth?

An operation g of the lattice (an integer matrix ``A`` with a translation ``t`` in cell
grid units) leaves a residual ``c - g c`` on every repeat's cell ``c``. Noise, wrinkles
and local stretch make that residual differ from repeat to repeat and from one part of
the cloth to another; a faint stroke of the print that g does not map onto itself leaves
the *same* residual in every repeat. So the residual's means over the two outer thirds of
the repeats (far apart on the cloth) are compared: their inner product estimates the
energy of the residual both share (noise and local distortion average to zero in it), and
divided by the energy of the motif both share it is the print's own asymmetry under g, 0
for a symmetry of the print however noisy the image.

Three things that are the same in every repeat without being the print's are divided out
first: the translation part is refined below the grid (Newton steps on the mean cell's
correlation; a rotation centre or mirror axis half a step off a 96-point grid leaves a
residual of a few per cent), a weighting of the harmonics that the operation does not
keep (a whitening by a metric that is not its isometry), and the different damping of a
harmonic and its image by a blur that is isotropic in the image but an ellipse in
lattice coordinates.

All in Fourier space on the cells' spectra: an integer matrix ``A`` permutes the
frequencies (``c(A f)`` has spectrum ``C(A^-T k)``), and a translation is a phase ramp, so
no interpolation enters the test.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ["WEIGHT_FLOOR", "Alternation", "Asymmetry", "RepeatSpectra", "alternation",
           "asymmetry", "beyond_rounding", "pixel_rounding", "refine_translation",
           "repeat_spectra", "rounding_map", "rounding_slack"]

#: Single repeats a per-repeat measure is taken over (residual energy here, the
#: operations' support in :func:`vision.decision.repeat_support`): a sample, spread over
#: all, keeps the cost fixed.
SAMPLE = 64

#: How far (working px) an edge of the print and its image under an operation may lie
#: apart without the operation counting as broken, on an image that repeats by whole
#: pixels (:func:`pixel_rounding`): a rendering, whose edges are each rounded to the
#: grid by up to half a pixel (so a pair by up to one), at the same place in every
#: repeat. Such rounding is a residual every repeat shares, as a faint stroke's is, but
#: it lies only along edges the print has on both sides of the operation, at most this
#: far times their slope.
EDGE_SLACK_PX = 1.0

#: Largest drift (input px) of the pixel grid along an image axis over the sampled
#: repeats for them to be rounded alike along it: whole pixels apart, as only a
#: rendering's repeats are (a hexagonal one's along one axis at most). A rendering's
#: lattice is measured to a few thousandths of a pixel; a photograph's lies this close
#: to whole pixels over ``MIN_SPAN`` repeats each way about once in a thousand.
PIXEL_GRID_DRIFT = 0.05
MIN_SPAN = 3


@dataclass
class RepeatSpectra:
    """Spectra (n, n) of the mean cell, of the mean cells of the two outer thirds of
    the repeats (split across the longest extent of their (i, j) indices), and of a
    sample of single repeats (S, n, n)."""

    mean: np.ndarray
    half_a: np.ndarray
    half_b: np.ndarray
    single: np.ndarray
    weight: np.ndarray | None = None  # real filter (n, n) the spectra are weighted by
    rounding: np.ndarray | None = None  # see pixel_rounding: renderings only

    @property
    def shared(self) -> float:
        """Energy of the motif both halves carry (noise in one half is not in the
        other's): the scale the asymmetry is measured against."""
        return float(np.real(np.vdot(self.half_a, self.half_b)))


@dataclass
class Asymmetry:
    """``own``: the residual energy every part of the cloth shares over twice the motif
    energy they share (the print's own asymmetry; 0 for a symmetry of the print).
    ``share``: the part of a single repeat's residual energy that is shared (1: all of
    it is the print's; near 0: noise, wrinkles and local stretch)."""

    own: float
    share: float


def repeat_spectra(cells: np.ndarray, ij: np.ndarray, weight: np.ndarray | None = None,
                   sample: int = SAMPLE, rounding: np.ndarray | None = None
                   ) -> RepeatSpectra | None:
    """The spectra of ``cells`` (R, n, n) with repeat indices ``ij`` (R, 2) that
    :func:`asymmetry` reads, weighted by ``weight`` (n, n), a real, non-negative filter
    (a whitening) if any; None with fewer than three repeats. :func:`asymmetry` undoes
    what of the weighting an operation does not keep. ``rounding``
    (:func:`pixel_rounding`), for repeats rounded alike to the pixel grid: the residual
    that rounding explains is allowed."""
    r = len(cells)
    if r < 3:
        return None
    a, b = _outer_thirds(ij)
    pick = np.linspace(0, r - 1, min(r, sample)).round().astype(int)
    w = 1.0 if weight is None else weight
    return RepeatSpectra(*(np.fft.fft2(cells[k].mean(0)) * w for k in (slice(None), a, b)),
                         np.fft.fft2(cells[pick]) * w, weight, rounding)


def pixel_rounding(basis: np.ndarray, scale: float, ij: np.ndarray, n: int,
                   min_span: int = MIN_SPAN, *, half: bool = False) -> np.ndarray | None:
    """What rounding to the pixel grid explains in the repeats ``ij`` (R, 2) of the
    lattice ``basis`` (columns w1, w2, working px; ``scale`` working px per input px)
    sampled on an ``n``-point cell: the (2, 2) map from a cell's gradient (per cell step
    along w1, w2) to the residual its edges' rounding explains; None unless the repeats,
    ``min_span`` or more each way, lie whole (or with ``half``, half) input pixels apart
    along an image axis, as only a rendering's do (half: a hexagon drawn on a tile of
    whole pixels, whose centre repeat sits half a pixel off where a side is odd).

    Along such an axis every repeat's edges are rounded alike; along the other (a
    hexagonal rendering's) the rounding differs from repeat to repeat and smears the
    mean cell's edges instead, by up to a pixel too: either way an edge may lie up to
    ``EDGE_SLACK_PX`` off its image's, along both axes."""
    basis, ij = np.asarray(basis, float), np.asarray(ij, float)
    if len(ij) == 0 or np.ptp(ij, axis=0).min() < min_span:
        return None  # too few repeats to tell whole pixels from chance
    steps = (2.0 if half else 1.0) * (ij - ij[0]) @ (basis / scale).T
    if not (np.abs(steps - np.rint(steps)).max(axis=0) < PIXEL_GRID_DRIFT).any():
        return None
    return rounding_map(basis, n)


def rounding_map(basis: np.ndarray, n: int) -> np.ndarray:
    """The (2, 2) map from the gradient of a cell of ``basis`` (columns, working px)
    sampled on ``n`` points (per cell step along w1, w2) to ``EDGE_SLACK_PX`` times the
    gradient per working px (chain rule: the steps are the columns of basis / n)."""
    return EDGE_SLACK_PX * np.linalg.inv(np.asarray(basis, float) / n).T


def rounding_slack(spec: np.ndarray, image_spec: np.ndarray, rounding: np.ndarray
                   ) -> np.ndarray:
    """(n, n): per cell point, the difference between a cell (spectrum ``spec``) and its
    aligned image under an operation (``image_spec``) that rounding their edges to the
    pixel grid explains (``rounding``, from :func:`pixel_rounding`), the smaller of the
    two: a stroke with no partner edge in the other gets none."""
    return np.minimum(_slope(spec, rounding), _slope(image_spec, rounding))


def beyond_rounding(residual: np.ndarray, slack: np.ndarray) -> np.ndarray:
    """The residual (..., n, n) in the cell less the ``slack`` rounding explains."""
    return np.sign(residual) * np.maximum(np.abs(residual) - slack, 0.0)


def _slope(spec: np.ndarray, rounding: np.ndarray) -> np.ndarray:
    """|rounding @ gradient| over the cell whose spectrum is ``spec``."""
    n = spec.shape[0]
    k = 2j * np.pi * np.fft.fftfreq(n)
    d_ab = np.stack([np.fft.ifft2(spec * k[:, None]).real.ravel(),
                     np.fft.ifft2(spec * k[None, :]).real.ravel()])
    return np.hypot(*(rounding @ d_ab)).reshape(n, n)


def _outer_thirds(ij: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the repeats in the two outer thirds across the longest extent of
    their (i, j) indices: the parts of the cloth farthest apart."""
    c = np.asarray(ij, float) - np.mean(ij, axis=0)
    _, _, vt = np.linalg.svd(c, full_matrices=False)
    order = np.argsort(c @ vt[0], kind="stable")
    a, _, b = np.array_split(order, 3)
    return a, b


@dataclass
class Alternation:
    """The strongest alternation between neighbouring repeats: ``parity`` (p, q) splits
    the repeats by (p i + q j) mod 2; ``own`` is the energy of the difference between
    the two classes that both outer thirds of the cloth share, over the motif energy
    they share (as :attr:`Asymmetry.own` for the half step as an operation: 0 when the
    half step is a repeat); ``z`` that shared energy in standard errors of noise;
    ``share`` its part of the difference between single neighbouring repeats (as
    :attr:`Asymmetry.share`)."""

    parity: tuple[int, int]
    own: float
    z: float
    share: float = 0.0


#: The three ways of splitting a lattice into two cosets of an index-2 sublattice.
PARITIES = ((1, 0), (0, 1), (1, 1))

#: Harmonics weighted below this fraction of the largest weight carry no energy that
#: counts (1e-8 of it, squared) and are left out of sums over a whitened spectrum
#: (:func:`alternation`, :func:`vision.classify.classify`'s likeness of the repeats).
WEIGHT_FLOOR = 1e-4


def alternation(cells: np.ndarray, ij: np.ndarray, weight: np.ndarray | None = None,
                min_terms: int = 4,
                rounding: Callable[[tuple[int, int]], np.ndarray | None] | None = None
                ) -> Alternation | None:
    """Do neighbouring repeats differ in a way the whole cloth shares?

    A lattice read too fine (a print's near-translation, such as a glide's half step
    under blur, taken for a repeat) puts two different cells ``m + d`` and ``m - d`` in
    alternate repeats. For each index-2 split, every repeat with both neighbours one
    odd step away gives ``+-(c - (c_prev + c_next) / 2) / 2``: ``d`` plus noise, with any
    drift that is linear along the step (perspective, stretch) gone. The inner product of
    its means over the two outer thirds of the cloth (spectra weighted by ``weight``) is
    the difference both share, which noise, wrinkles and local stretch do not. None when
    a third holds fewer than ``min_terms`` such repeats.

    ``rounding(parity)``: for a rendering whose index-2 sublattice of that parity lies
    whole pixels apart (:func:`pixel_rounding`), its map; the two classes are then each
    rounded to the grid their own way, and the half of that difference ``d`` carries
    (up to half of ``EDGE_SLACK_PX`` times the slope) is allowed."""
    ij = np.asarray(ij, float)
    n = cells.shape[-1]
    spec = np.fft.fft2(cells).reshape(len(cells), -1)
    keep = np.ones(n * n, bool)
    if weight is not None:
        # Only the harmonics the weighting keeps: a whitening rolled off at a few
        # harmonics per repeat leaves a few hundred of the cell's n * n.
        w = weight.ravel()
        keep = w > WEIGHT_FLOOR * w.max()
        spec = spec[:, keep] * w[keep]
    third = np.full(len(cells), -1)
    for k, h in enumerate(_outer_thirds(ij) if len(cells) >= 3 else ()):
        third[h] = k
    best = None
    for p in PARITIES:
        found = _split_alternation(spec, ij, third, p, min_terms,
                                   None if rounding is None else (rounding, keep, n))
        if found is not None and (best is None or found.own > best.own):
            best = found
    return best


def _split_alternation(spec: np.ndarray, ij: np.ndarray, third: np.ndarray,
                       p: tuple[int, int], min_terms: int,
                       rounding: tuple[Callable, np.ndarray, int] | None
                       ) -> Alternation | None:
    """:func:`alternation` for the index-2 split of parity ``p``, on the repeats'
    (weighted, kept) spectra ``spec``; ``third`` numbers the repeats of the two outer
    thirds 0 and 1. ``rounding``: the map maker, the harmonics kept and the cell side."""
    steps = [e for e in ((1, 0), (0, 1)) if (p[0] * e[0] + p[1] * e[1]) % 2]
    t, at = _alternate_differences(spec, ij, p, steps)
    parts = [t[third[at] == k] for k in (0, 1)]
    if min(len(x) for x in parts) < min_terms:
        return None
    d_a, d_b = (x.mean(0) for x in parts)
    # Variance of each mean per harmonic (neighbouring terms share a repeat, so
    # this runs low and ``z`` high: it is a guard against few repeats, no more).
    v_a, v_b = ((np.abs(x - x.mean(0)) ** 2).sum(0) / (len(x) * (len(x) - 1))
                for x in parts)
    m_a, m_b = (spec[third == k].mean(0) for k in (0, 1))
    shared_d = float(np.real(np.vdot(d_a, d_b)))
    grid = None if rounding is None else rounding[0](p)
    if grid is not None:
        _, keep, n = rounding
        mean = _in_cell(spec.mean(0), keep, n)
        slack = 0.5 * rounding_slack(mean, mean, grid)
        beyond_a, beyond_b = (beyond_rounding(np.fft.ifft2(_in_cell(d, keep, n)).real, slack)
                              for d in (d_a, d_b))
        shared_d = n * n * float(np.sum(beyond_a * beyond_b))  # Parseval
    own = 2.0 * shared_d / max(float(np.real(np.vdot(m_a, m_b))), 1e-30)
    z = shared_d / math.sqrt(max(float((v_a * v_b).sum()), 1e-300))
    # Single repeats: the difference of each from its neighbour one step away.
    r, q = _neighbours(ij, steps)
    single = float((np.abs(spec[r] - spec[q]) ** 2).sum(1).mean())
    return Alternation(p, own, z, 4.0 * shared_d / max(single, 1e-30))


def _alternate_differences(spec: np.ndarray, ij: np.ndarray, p: tuple[int, int],
                           steps: list[tuple[int, int]]) -> tuple[np.ndarray, np.ndarray]:
    """Per repeat with both neighbours one (odd) step away, ``+-(c - (c_prev + c_next) /
    2) / 2`` signed by its class of the split ``p``, and the repeats they belong to."""
    sign = 1.0 - 2.0 * ((ij @ np.array(p, float)).astype(int) % 2)
    terms, where = [], []
    for e in steps:
        r, nxt = _neighbours(ij, [e])
        r2, prv = _neighbours(ij, [(-e[0], -e[1])])
        both, at_n, at_p = np.intersect1d(r, r2, return_indices=True)
        terms.append(sign[both, None] * (spec[both] - 0.5 * (spec[nxt[at_n]]
                                                             + spec[prv[at_p]])) / 2)
        where.append(both)
    return np.concatenate(terms), np.concatenate(where)


def _in_cell(kept: np.ndarray, keep: np.ndarray, n: int) -> np.ndarray:
    """A spectrum of the ``keep`` harmonics only back on the whole (n, n) cell grid."""
    full = np.zeros(n * n, complex)
    full[keep] = kept
    return full.reshape(n, n)


def _neighbours(ij: np.ndarray, steps: list[tuple[int, int]]) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (r, q) of repeats with ij[q] = ij[r] + a step."""
    key = ij[:, 0].astype(np.int64) * 100003 + ij[:, 1].astype(np.int64)
    order = np.argsort(key)
    rs, qs = [], []
    for e in steps:
        want = key + e[0] * 100003 + e[1]
        pos = np.clip(np.searchsorted(key[order], want), 0, len(key) - 1)
        hit = key[order][pos] == want
        rs.append(np.flatnonzero(hit))
        qs.append(order[pos[hit]])
    return np.concatenate(rs), np.concatenate(qs)


def _perm(a: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Frequency indices m = A^-T k (mod n) for every k of the grid, and m signed."""
    k = np.arange(n)
    ka, kb = np.meshgrid(k, k, indexing="ij")
    ait = np.rint(np.linalg.inv(a).T).astype(int)
    ma = (ait[0, 0] * ka + ait[0, 1] * kb) % n
    mb = (ait[1, 0] * ka + ait[1, 1] * kb) % n
    return ma, mb, np.where(ma > n // 2, ma - n, ma), np.where(mb > n // 2, mb - n, mb)


def refine_translation(spec: np.ndarray, a: np.ndarray, s: np.ndarray,
                       steps: int = 5) -> np.ndarray:
    """Sub-grid translation t near the grid shift ``s`` maximising the correlation of
    the cell with spectrum ``spec`` and its image ``c(A f + t)``."""
    n = spec.shape[0]
    ma, mb, fa, fb = _perm(a, n)
    x = np.conj(spec) * spec[ma, mb]
    w = 2 * np.pi / n
    near = np.array([(s[0] + i, s[1] + j) for i in (-1, 0, 1) for j in (-1, 0, 1)], float)
    # The group's single grid origin fixes s; the operation's own best may be next to it.
    ramp = np.exp(1j * w * (fa[None] * near[:, 0, None, None]
                            + fb[None] * near[:, 1, None, None]))
    t = near[int(np.argmax((x[None] * ramp).real.sum(axis=(1, 2))))]
    for _ in range(steps):
        e = x * np.exp(1j * w * (fa * t[0] + fb * t[1]))
        grad = -w * np.array([(e * fa).imag.sum(), (e * fb).imag.sum()])
        hess = -w * w * np.array([[(e * fa * fa).real.sum(), (e * fa * fb).real.sum()],
                                  [(e * fa * fb).real.sum(), (e * fb * fb).real.sum()]])
        if np.linalg.det(hess) <= 0 or hess[0, 0] >= 0:
            break  # not at a maximum's basin: keep the grid point
        step = -np.linalg.solve(hess, grad)
        if np.abs(step).max() > 1.0:
            break
        t = t + step
        if np.abs(step).max() < 1e-3:
            break
    return t


def _blur_ratio(spec: np.ndarray, ma: np.ndarray, mb: np.ndarray,
                known: np.ndarray | float = 0.0) -> np.ndarray:
    """log |M(k)| - log |M(A^-T k)| as a quadratic form k^T P k, fitted by weighted
    least squares over the harmonics (weights: the product of both amplitudes): the
    part of the amplitude change under the operation that a Gaussian blur (isotropic
    in the image, an ellipse in lattice coordinates) explains, beyond the ``known``
    log ratio (n, n) of a weighting."""
    n = spec.shape[0]
    k = np.fft.fftfreq(n) * n
    ka, kb = np.meshgrid(k, k, indexing="ij")
    amp = np.abs(spec)
    amp_g = amp[ma, mb]
    w = amp * amp_g
    ok = w > 1e-12 * w.max()
    x = np.stack([ka[ok] ** 2, 2 * ka[ok] * kb[ok], kb[ok] ** 2], 1)
    y = (np.log(amp[ok]) - np.log(amp_g[ok])
         - (known[ok] if isinstance(known, np.ndarray) else known))
    sw = np.sqrt(w[ok])
    coef = np.linalg.lstsq(x * sw[:, None], y * sw, rcond=None)[0]
    return coef[0] * ka**2 + 2 * coef[1] * ka * kb + coef[2] * kb**2


def asymmetry(spectra: RepeatSpectra, a: np.ndarray, s: np.ndarray, *,
              blur: bool = True) -> Asymmetry:
    """The residual of the operation (A, s) (translation refined near the grid shift
    ``s``): its part shared by the two outer thirds of the cloth, against the motif
    and against single repeats' residuals.

    ``blur``: first scale each harmonic and its image to their geometric mean by the
    amplitude ratio a Gaussian blur explains (:func:`_blur_ratio`). A blur isotropic in
    the image is not in lattice coordinates when the lattice is stretched or sheared
    (or tilted), so it damps a harmonic and its image differently; the phases, which
    strokes that break the symmetry move, it keeps."""
    n = spectra.mean.shape[0]
    t = refine_translation(spectra.mean, a, s)
    ma, mb, fa, fb = _perm(a, n)
    ph = np.exp(2j * np.pi / n * (fa * t[0] + fb * t[1]))
    ua, ub = np.ones((n, n)), ph
    known: np.ndarray | float = 0.0
    if spectra.weight is not None:
        # A weighting not invariant under A (a whitening by a metric that is an
        # isometry of only some of the tested operations) changes amplitudes, not
        # phases: compare both harmonics under their geometric-mean weight.
        wk, wm = spectra.weight, spectra.weight[ma, mb]
        ok = np.minimum(wk, wm) > 1e-12 * max(float(wk.max()), 1e-300)
        ua = np.where(ok, np.sqrt(wm / np.where(ok, wk, 1.0)), 0.0)
        ub = ub * np.where(ok, np.sqrt(wk / np.where(ok, wm, 1.0)), 0.0)
        known = np.where(ok, np.log(np.where(ok, wk, 1.0)) - np.log(np.where(ok, wm, 1.0)),
                         0.0)
    if blur:
        rho = np.clip(_blur_ratio(spectra.mean, ma, mb, known), -3.0, 3.0)
        ua, ub = ua * np.exp(-0.5 * rho), ub * np.exp(0.5 * rho)

    def residual(spec: np.ndarray) -> np.ndarray:
        return spec * ua - spec[..., ma, mb] * ub

    if spectra.rounding is None:
        shared = float(np.real(np.vdot(residual(spectra.half_a),
                                       residual(spectra.half_b))))
        single = float((np.abs(residual(spectra.single)) ** 2).sum(axis=(-2, -1)).mean())
    else:
        slack = rounding_slack(spectra.mean * ua, spectra.mean[ma, mb] * ub,
                               spectra.rounding)

        def beyond(spec: np.ndarray) -> np.ndarray:
            return beyond_rounding(np.fft.ifft2(residual(spec)).real, slack)

        # n^2 times the sums over the cell: the spectra's scale (Parseval).
        shared = n * n * float(np.sum(beyond(spectra.half_a) * beyond(spectra.half_b)))
        single = n * n * float((beyond(spectra.single) ** 2).sum(axis=(-2, -1)).mean())
    return Asymmetry(shared / max(2.0 * spectra.shared, 1e-30), shared / max(single, 1e-30))
