"""Wallpaper-group classification of a print, with its origin w0, from the mean unit cell.

Method (own code, after the cited work):

1. The *motif* is the mean cell over all repeats, sampled on an ``N x N`` grid of
   fractional coordinates of the reduced lattice basis. Each repeat is first registered
   to the running mean by a circular cross-correlation (one FFT per repeat, all at once),
   so perspective and folds that move repeats by a fraction of a cell do not blur it.
2. Every lattice isometry ``A`` (an integer matrix in that basis: the lattice's
   holohedry) is scored at *every* translation part ``s`` at once: the normalised
   correlation of the motif ``M(f)`` with ``M(A f + s)`` is one circular correlation in
   Fourier space. Because ``A`` is an integer matrix, ``M(A f)`` is an exact permutation
   of the grid, so no interpolation blurs the test.
3. Each of the 17 groups, in each basis of the lattice that fits its convention
   (``solver.wallpaper`` ops conjugated by a unimodular ``U``), predicts the translation
   part of every one of its operations from a single origin ``o``. The origin is found
   by summing the scores of all the group's operations over every grid origin (dense
   search), then refined to sub-grid precision.
4. The group is chosen by likelihood over all 17: required operations should score high,
   every other isometry of the lattice (rotations, mirrors, glides) low. Scores are
   divided by the motif's split-half reliability, so the thresholds do not move with
   noise or the number of repeats. ``confidence`` is the posterior of the winner.
5. Real cloth: the whitening rolls off above ``BAND`` harmonics per repeat (yarn and
   twill lines do not share the print's symmetry), and the isometries tested are those
   of the lattice *up to a stretch or shear of ~16 %* (``HOLOHEDRY_TOL``): the motif is
   sampled in lattice coordinates, so a square check pulled rectangular still maps onto
   itself under the integer quarter turn. Each group's answer must snap to its lattice
   (``Wallpaper.snapped``), and a prior on the strain it needs (``STRAIN_SIGMA``) asks
   more evidence of more distortion. The answer is the group the print was designed
   with; the strain is reported. A group whose operations hold on a lattice further off
   its own than the snap allows cannot be the answer, but it stays in the posterior:
   the answer that forbids those operations then goes to the operator.

References
----------
.. [1] Y. Liu, R. T. Collins, Y. Tsin, "A computational model for periodic pattern
       perception based on frieze and wallpaper groups", IEEE PAMI 26(3):354-371, 2004.
       :DOI:`10.1109/TPAMI.2004.1262332` (symmetry scores on the median/mean tile,
       decision over the 17 groups).
.. [2] J. Hays, M. Leordeanu, A. A. Efros, Y. Liu, "Discovering texture regularity as a
       higher-order correspondence problem", ECCV 2006.
.. [3] M. von Gagern, "Automatic detection of wallpaper groups", diploma thesis, TU
       München, 2008 (rotation centres and mirror axes by correlation).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from functools import lru_cache
from typing import NamedTuple

import cv2
import numpy as np
from scipy import fft as sfft

from solver.wallpaper import GROUP_NAMES, GROUPS, Wallpaper
from vision.consistency import (
    EDGE_SLACK_PX,
    SAMPLE,
    WEIGHT_FLOOR,
    RepeatSpectra,
    asymmetry,
    beyond_rounding,
    pixel_rounding,
    repeat_spectra,
    rounding_slack,
)
from vision.lattice import LatticeResult
from vision.neighbours import neighbour_correlation, print_band, worse_likeness
from vision.prepare import prepare_image
from vision.subgroups import is_subgroup
from vision.whitening import symmetric_metric, whitened, whitening

__all__ = ["Classification", "classify", "isometry_name", "lattice_whitening", "mean_cell",
           "repeat_cells", "symmetric_metric", "symmetry_elements"]

#: Grid of the mean cell: divisible by 2, 3, 4 and 6 so that every operation of every
#: group maps grid points onto grid points.
CELL_N = 96

#: Highest confidence of a group that holds only with rounding to the pixel grid allowed
#: (``classify``'s ``pixel_slack``): under the operator's threshold.
ROUNDING_CONFIDENCE = 0.5

#: Likelihood of an operation being present given its reliability-normalised score.
TAU = 0.86
KAPPA = 0.05

#: Exponent of the |frequency| weighting of the motif before scoring. Blur and coarse
#: shapes make any motif look nearly symmetric; the fine detail is where a missing
#: symmetry shows, so it is weighted up (isotropically, which keeps every symmetry).
WHITEN = 1.0

#: Harmonics per repeat length at which the whitening rolls off (Gaussian). Finer detail
#: is thread-scale texture (twill lines, yarn, knit loops, the camera's resampling) that
#: real cloth does not carry with the print's symmetry; chosen across sources (synthetic
#: renders, textile classics, photographs of four origins), see ``bench/vision.py``.
BAND = 12.0

#: Temperature of the posterior over groups (log-likelihoods divided by it), as fitted
#: across sources by ``bench.vision.fit_temperature`` (BENCHMARKS.md).
TEMPERATURE = 1.0


#: Relative metric tolerance of the lattice isometries tested: wide enough for a square
#: or hexagonal print on fabric stretched or sheared by up to about 16 % (each group's
#: answer must still snap to its lattice, see :meth:`Wallpaper.snapped`).
HOLOHEDRY_TOL = 0.45
HOLOHEDRY_STRAIN = 0.16

#: How far a measured lattice may be off a group's lattice (relative length, angle in
#: radians) for the group to be considered: ``Wallpaper.snapped``'s own default.
SNAP_TOL = 0.2

#: Width of the prior on the strain a group needs to explain the measured lattice: a
#: higher symmetry on a distorted lattice needs correspondingly stronger evidence.
STRAIN_SIGMA = 0.1


def lattice_whitening(basis: np.ndarray, band: float, n: int = CELL_N) -> np.ndarray:
    """The whitening (n, n) of cells of the lattice ``basis``, rolled off at ``band``
    harmonics per repeat, under the metric of the undistorted print."""
    return whitening(n, symmetric_metric(basis, holohedry(basis, tol=HOLOHEDRY_TOL)),
                     WHITEN, band)


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

#: How much the lag behind the translations widens per unit of single-repeat
#: disagreement (1 - the median correlation of neighbouring repeats): on the labelled
#: photographs a true mirror of the mean cell falls 0.10 short of the translations
#: where repeats disagree by 0.08, while clean drawings of near-symmetric prints (a bold
#: bar that is its own half turn, thin strokes that are not) lag by 0.05-0.3 with
#: repeats alike to 0.01 (BENCHMARKS.md).
LAG_SPREAD = 1.0

#: How much the lag allowed behind a subgroup's operations widens per unit of
#: single-repeat disagreement. Local stretch that differs from repeat to repeat
#: (drape, wrinkles) lowers an operation that maps one thread direction onto the other
#: (a check's quarter turn) more than one that keeps them (its mirrors along the
#: threads): on a wrinkled gingham photographed in crops the quarter turn lagged the
#: mirrors by up to 0.051 where repeats disagreed by 0.13-0.18. Measured on every
#: source at 0.1, 0.2, 0.3: only those crops change (BENCHMARKS.md).
ADDED_LAG_SPREAD = 0.1

#: Harmonics per repeat up to which single repeats are compared to tell whether the
#: lattice's step repeats the print at all: at the print's scale. Finer, blur and noise
#: dominate a small print: on 170 small prints under blur up to 2.5 px and noise
#: (`tests/vision/test_classify.py`) neighbouring repeats of the true lattice correlate
#: 0.12 or more at 12 harmonics, 0.24 at 6 and 0.60 at 3.
LIKENESS_BAND = 3.0

#: Confidence ceiling of an answer that single repeats cannot check: one drawn from
#: fewer than three whole repeats, or from repeats that look little alike.
FEW_REPEATS_CONFIDENCE = 0.5

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
#: Harmonics per repeat where the consistency test's whitening rolls off: below
#: ``BAND``, as anti-aliased strokes leave pixel-scale residuals (line caps, widths
#: rounded to pixels) of a few per cent even under their true mirrors.
CONSISTENCY_BAND = 6.0


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


def _likeness(cells: np.ndarray, ij: np.ndarray, metric: np.ndarray, alpha: float
              ) -> tuple[float, float]:
    """How alike single repeats look up to ``LIKENESS_BAND`` harmonics per repeat: along
    the worse lattice vector (:func:`vision.neighbours.worse_likeness`), and, as this
    check has always read it, consecutive repeats in the order sampled (along w2; over
    ``max_repeats``, pairs spread over the frame's centre, which a lattice drifting
    off the print under a steep view fails)."""
    spectra = np.fft.fft2(cells).reshape(len(cells), -1)
    w = whitening(cells.shape[-1], metric, alpha, LIKENESS_BAND).ravel()
    keep = w > WEIGHT_FLOOR * w.max()
    return worse_likeness(spectra, ij, w), neighbour_correlation(spectra[:, keep] * w[keep])


def lattice_strain(measured: np.ndarray, ideal: np.ndarray) -> float:
    """Largest principal strain of the affine map taking ``ideal`` (2,2) onto
    ``measured`` (columns w1, w2): 0.1 is a 10 % stretch."""
    f = measured @ np.linalg.inv(ideal)
    return float(np.abs(np.linalg.svd(f, compute_uv=False) - 1.0).max())


@dataclass
class Classification:
    """Outcome of :func:`classify` (millimetres of the input image frame)."""

    wallpaper: Wallpaper | None
    group: str | None
    confidence: float
    #: Log-likelihood per group, including those that hold only on a lattice further
    #: off theirs than a print is snapped by (never the answer, but weighed against it).
    scores: dict[str, float] = field(default_factory=dict)
    op_scores: dict[str, float] = field(default_factory=dict)  # best score per isometry
    reliability: float = float("nan")
    n_repeats: int = 0
    motif: np.ndarray | None = None
    message: str = ""
    temperature: float = 1.0
    strain: float = 0.0  # stretch/shear of the measured lattice against the group's
    likeness: float = float("nan")  # of neighbouring single repeats (LIKENESS_BAND)

    @property
    def posterior(self) -> dict[str, float]:
        """Calibrated probability of each group whose operations the lattice carries
        (sums to 1); ``confidence`` is the answer's."""
        if not self.scores:
            return {}
        names = list(self.scores)
        ll = np.array([self.scores[k] for k in names]) / self.temperature
        p = np.exp(ll - ll.max())
        return dict(zip(names, (p / p.sum()).tolist(), strict=True))

    def to_dict(self) -> dict:
        out = {"group": self.group, "confidence": round(float(self.confidence), 4),
               "reliability": round(float(self.reliability), 4),
               "n_repeats": self.n_repeats,
               "op_scores": {k: round(v, 3) for k, v in self.op_scores.items()}}
        if self.wallpaper is not None:
            out.update(self.wallpaper.to_dict())
        return out


# ---------------------------------------------------------------- motif
def _cell_maps(anchor: np.ndarray, basis: np.ndarray, n: int, shape: tuple[int, int],
               max_repeats: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sampling maps (R, n, n) x and y of the repeats lying wholly inside the image.

    ``basis`` columns are w1, w2 in working (x, y) pixels; the cell grid point (a, b)
    of repeat (i, j) is ``anchor + (a/n + i) w1 + (b/n + j) w2``.
    """
    h, w = shape
    corners = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1]], float) - anchor
    frac = corners @ np.linalg.inv(basis).T
    lo = np.floor(frac.min(0)).astype(int) - 1
    hi = np.ceil(frac.max(0)).astype(int) + 1
    ii, jj = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1),
                         indexing="ij")
    ij = np.stack([ii.ravel(), jj.ravel()], 1).astype(float)
    cell_corners = np.array([[0, 0], [1, 0], [0, 1], [1, 1]], float)
    pts = anchor + (ij[:, None, :] + cell_corners[None]) @ basis.T  # (R,4,2)
    margin = 2.0
    inside = np.all((pts[..., 0] >= margin) & (pts[..., 0] <= w - 1 - margin)
                    & (pts[..., 1] >= margin) & (pts[..., 1] <= h - 1 - margin), axis=1)
    ij = ij[inside]
    if len(ij) > max_repeats:  # keep the central ones: least distorted by the view
        d = np.linalg.norm((ij + 0.5) @ basis.T, axis=1)
        ij = ij[np.argsort(d)[:max_repeats]]
    g = np.arange(n) / n
    ga, gb = np.meshgrid(g, g, indexing="ij")  # [a, b]: a along w1, b along w2
    fa = ij[:, 0, None, None] + ga[None]
    fb = ij[:, 1, None, None] + gb[None]
    x = anchor[0] + fa * basis[0, 0] + fb * basis[0, 1]
    y = anchor[1] + fa * basis[1, 0] + fb * basis[1, 1]
    return x.astype(np.float32), y.astype(np.float32), ij


def repeat_cells(flat: np.ndarray, basis: np.ndarray, *, cell_n: int = CELL_N,
                 max_repeats: int = 400, prefilter: float = 1.0) -> tuple[np.ndarray, tuple]:
    """The anchor (the central repeat's cell is centred on the image, so that at least
    one whole repeat is sampled even when only about three fit across) and
    :func:`mean_cell`'s answer for the lattice ``basis`` (working (x, y) px). The image
    is band-limited to the cell grid first: sampling a sharp print more coarsely than
    its pixels by interpolation leaves errors that differ between a point and its
    symmetric partner, and a whitening would amplify them."""
    h, w = flat.shape
    anchor = np.array([(w - 1) / 2.0, (h - 1) / 2.0]) - basis @ np.array([0.5, 0.5])
    spacing = float(np.linalg.norm(basis, axis=0).max()) / cell_n
    if spacing > 1.0:
        flat = cv2.GaussianBlur(flat, (0, 0), prefilter * spacing)
    return anchor, mean_cell(flat, basis, anchor, n=cell_n, max_repeats=max_repeats)


def mean_cell(flat: np.ndarray, basis: np.ndarray, anchor: np.ndarray, *, n: int = CELL_N,
              max_repeats: int = 400, register: bool = True):
    """Mean unit cell (n, n) over the repeats, the means of its two halves (even and odd
    repeats), the number of repeats, their (i, j) indices, their registration shifts
    (R, 2) in cell units and the registered cells themselves (R, n, n).

    Registration: each repeat's cell is circularly cross-correlated with the mean of
    the others (all FFTs at once), shifted by the peak (Fourier shift theorem, exact for
    a periodic cell) and averaged again; two rounds.
    """
    x, y, ij = _cell_maps(anchor, basis, n, flat.shape, max_repeats)
    r = len(ij)
    if r == 0:
        raise ValueError("no whole repeat of the print lies inside the image")
    # cv2.remap takes maps of fewer than 32767 rows: sample in batches of repeats.
    per = max(1, 32000 // n)
    cells = np.concatenate([
        cv2.remap(flat, x[k:k + per].reshape(-1, n), y[k:k + per].reshape(-1, n),
                  cv2.INTER_LINEAR).reshape(-1, n, n)
        for k in range(0, r, per)]).astype(np.float64)
    cells -= cells.mean(axis=(1, 2), keepdims=True)
    shifts = np.zeros((r, 2))
    spec = sfft.fft2(cells.astype(np.complex64), workers=-1)
    if register and r > 1:
        k = np.fft.fftfreq(n) * n
        ka, kb = np.meshgrid(k, k, indexing="ij")
        for _ in range(2):
            ref = spec.mean(axis=0)
            # Peak of the circular cross-correlation at each repeat's shift.
            xc = sfft.ifft2(spec * np.conj(ref)[None], workers=-1).real
            flatidx = xc.reshape(r, -1).argmax(1)
            pa, pb = np.unravel_index(flatidx, (n, n))
            # Sub-sample: parabola through the neighbours along each axis.
            def _para(c0, cm, cp):
                den = cm - 2 * c0 + cp
                return np.where(np.abs(den) > 1e-12, 0.5 * (cm - cp) / np.where(
                    np.abs(den) > 1e-12, den, 1.0), 0.0)
            rr = np.arange(r)
            c0 = xc[rr, pa, pb]
            da = _para(c0, xc[rr, (pa - 1) % n, pb], xc[rr, (pa + 1) % n, pb])
            db = _para(c0, xc[rr, pa, (pb - 1) % n], xc[rr, pa, (pb + 1) % n])
            sa = ((pa + 0.5) % n - 0.5) + np.clip(da, -0.5, 0.5)
            sb = ((pb + 0.5) % n - 0.5) + np.clip(db, -0.5, 0.5)
            sa = np.where(sa > n / 2, sa - n, sa)
            sb = np.where(sb > n / 2, sb - n, sb)
            # Only small moves are registration; a large one is a bad repeat match.
            ok = np.hypot(sa, sb) < 0.25 * n
            sa, sb = np.where(ok, sa, 0.0), np.where(ok, sb, 0.0)
            shifts += np.stack([sa, sb], 1) / n
            # Separable phase ramp exp(2 pi i (k_a s_a + k_b s_b) / n).
            pa_ = np.exp(2j * np.pi * k[None, :] * sa[:, None] / n).astype(np.complex64)
            pb_ = np.exp(2j * np.pi * k[None, :] * sb[:, None] / n).astype(np.complex64)
            spec = spec * pa_[:, :, None] * pb_[:, None, :]
        # Keep the frame of the central repeats: undo the mean shift.
        mean_shift = np.median(shifts, axis=0)
        phase = np.exp(-2j * np.pi * (ka * mean_shift[0] + kb * mean_shift[1]))
        spec = spec * phase[None].astype(np.complex64)
        shifts -= mean_shift
    cells = sfft.ifft2(spec, workers=-1).real.astype(np.float64)
    motif = cells.mean(axis=0)
    halves = (cells[0::2].mean(0), cells[1::2].mean(0) if r >= 2 else cells[0])
    return motif, halves, r, ij, shifts, cells


def split_half_reliability(a: np.ndarray, b: np.ndarray) -> float:
    """Reliability of the mean of two half-means: their correlation, stepped up by the
    Spearman-Brown formula. A symmetric print's operations cannot score above it."""
    a, b = a.ravel(), b.ravel()
    if np.array_equal(a, b):
        # One repeat only: no second copy to measure the noise by. Taking the cell as
        # exact lets only operations that hold on it closely count (the safe side: a
        # single smooth cell looks nearly symmetric under many operations).
        return 1.0
    if a.std() <= 0 or b.std() <= 0:
        return 0.5
    rho = max(float(np.corrcoef(a, b)[0, 1]), 1e-3)
    return 2 * rho / (1 + rho)


# ---------------------------------------------------------------- the lattice's isometries
def holohedry(basis: np.ndarray, tol: float = 0.2) -> list[np.ndarray]:
    """Integer matrices A (in the basis' fractional coordinates), A != I, that are
    isometries of the lattice up to ``tol`` (relative), i.e. A^T G A = G."""
    g = basis.T @ basis
    out = []
    for e in np.array(np.meshgrid(*[(-1, 0, 1)] * 4, indexing="ij")).reshape(4, -1).T:
        a = e.reshape(2, 2).astype(float)
        if abs(abs(np.linalg.det(a)) - 1) > 1e-9 or np.allclose(a, np.eye(2)):
            continue
        if np.abs(a.T @ g @ a - g).max() <= tol * np.trace(g) / 2:
            out.append(a.astype(int))
    return out


def _key(a: np.ndarray) -> tuple[int, ...]:
    return tuple(np.asarray(a).ravel().tolist())


def _name(a: np.ndarray, basis: np.ndarray) -> str:
    lin = basis @ a @ np.linalg.inv(basis)
    if np.linalg.det(lin) > 0:
        ang = round(math.degrees(math.atan2(lin[1, 0], lin[0, 0])) % 360)
        return f"rot{360 // math.gcd(360, ang)}({ang})"
    ev, vec = np.linalg.eig(lin)
    v = np.real(vec[:, np.argmax(np.real(ev))])
    return f"refl({round(math.degrees(math.atan2(v[1], v[0])) % 180)})"


def _corr_all_shifts(motif: np.ndarray, a: np.ndarray) -> np.ndarray:
    """T[s] = <M(f), M(A f + s)> / <M, M> for every grid shift s (n, n)."""
    n = motif.shape[0]
    g = np.arange(n)
    fa, fb = np.meshgrid(g, g, indexing="ij")
    src_a = (a[0, 0] * fa + a[0, 1] * fb) % n
    src_b = (a[1, 0] * fa + a[1, 1] * fb) % n
    p = motif[src_a, src_b]  # P(f) = M(A f)
    fm = np.fft.fft2(motif)
    r = np.fft.ifft2(np.conj(fm) * np.fft.fft2(p)).real / max(float((motif**2).sum()), 1e-12)
    # T(s) = R(A^-1 s): gather on the grid (A^-1 is an integer matrix too).
    ainv = np.rint(np.linalg.inv(a)).astype(int)
    ta = (ainv[0, 0] * fa + ainv[0, 1] * fb) % n
    tb = (ainv[1, 0] * fa + ainv[1, 1] * fb) % n
    return r[ta, tb]


def _rounded_score(motif: np.ndarray, a: np.ndarray, shift: np.ndarray,
                   rounding: np.ndarray) -> float:
    """:func:`_corr_all_shifts` at one ``shift`` of a cell that repeats by whole pixels,
    less what rounding its edges to the grid explains (:func:`rounding_slack`):
    1 - |M - M(A f + s)|^2 / 2|M|^2, the residual taken beyond that slack."""
    n = motif.shape[0]
    g = np.arange(n)
    fa, fb = np.meshgrid(g, g, indexing="ij")
    image = motif[(a[0, 0] * fa + a[0, 1] * fb + shift[0]) % n,
                  (a[1, 0] * fa + a[1, 1] * fb + shift[1]) % n]
    slack = rounding_slack(np.fft.fft2(motif), np.fft.fft2(image), rounding)
    left = beyond_rounding(motif - image, slack)
    return 1.0 - float((left**2).sum()) / max(2.0 * float((motif**2).sum()), 1e-12)


def _reflection_classes(a: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    return _reflection_classes_cached(_key(a), n)


@lru_cache(maxsize=256)
def _reflection_classes_cached(key: tuple[int, ...], n: int) -> tuple[np.ndarray, np.ndarray]:
    """Boolean (n, n) masks of the shifts s for which (A, s) is a mirror, or a glide.

    (A, s) is a symmetry only if its square (A + I) s is a lattice vector; it is a
    mirror (up to a lattice translation) when s lies in the image of (I - A) on the
    torus, and a glide otherwise.
    """
    a = np.array(key, int).reshape(2, 2)
    g = np.arange(n)
    ka, kb = np.meshgrid(g, g, indexing="ij")
    ap = a + np.eye(2, dtype=int)
    valid = ((ap[0, 0] * ka + ap[0, 1] * kb) % n == 0) & ((ap[1, 0] * ka + ap[1, 1] * kb)
                                                          % n == 0)
    im = np.eye(2, dtype=int) - a
    g2 = np.arange(2 * n)
    oa, ob = np.meshgrid(g2, g2, indexing="ij")
    sa = im[0, 0] * oa + im[0, 1] * ob
    sb = im[1, 0] * oa + im[1, 1] * ob
    even = (sa % 2 == 0) & (sb % 2 == 0)
    mirror = np.zeros((n, n), bool)
    mirror[(sa[even] // 2) % n, (sb[even] // 2) % n] = True
    return mirror & valid, valid & ~mirror


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


class _GroupFit(NamedTuple):
    """A group's best reading of the motif: its log-likelihood, the unimodular ``u``
    taking the lattice basis to the group's conventional one, its origin (cell
    fractions), its operations with their translation parts on the grid, and the
    isometry classes (``(key, "rot" | "mirror" | "glide")``) those operations are."""

    score: float
    u: np.ndarray
    origin: np.ndarray
    ops: list[tuple[np.ndarray, np.ndarray]]
    present: frozenset


def _isometry_scores(motif: np.ndarray, holo: list[np.ndarray], basis: np.ndarray,
                     ceiling: float, rounding: np.ndarray | None
                     ) -> tuple[dict, dict[tuple, float], dict[str, float]]:
    """Every lattice isometry scored at every translation part: the correlations by
    isometry key (raw; with what pixel ``rounding`` explains given back), the best
    score relative to ``ceiling`` of each isometry and class (rotation, mirror, glide:
    the "forbidden" terms of the groups without it), and the same by readable name."""
    n = motif.shape[0]
    corr = {_key(a): _corr_all_shifts(motif, a) for a in holo}
    forb: dict[tuple, float] = {}
    op_scores: dict[str, float] = {}
    for a in holo:
        t = corr[_key(a)] / ceiling
        classes = ([("rot", "", np.ones((n, n), bool))] if round(np.linalg.det(a)) == 1
                   else [(kind, tag, mask) for kind, tag, mask in
                         zip(("mirror", "glide"), "mg", _reflection_classes(a, n),
                             strict=True) if mask.any()])
        for kind, tag, mask in classes:
            at = np.unravel_index(int(np.argmax(np.where(mask, t, -np.inf))), t.shape)
            if rounding is not None:
                # What rounding explains, measured at the class's best shift, is
                # given back at every shift of the class (the decision reads them all).
                gain = _rounded_score(motif, a, np.array(at), rounding) - float(
                    corr[_key(a)][at])
                corr[_key(a)][mask] += gain
                t = corr[_key(a)] / ceiling
            forb[(_key(a), kind)] = float(t[at])
            op_scores[_name(a, basis) + tag] = float(t[at])
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
            if _key(a) not in holo_keys or np.abs(b - np.rint(b)).max() > 1e-6:
                break
            ops.append((a, np.rint(b).astype(int) % n))
        else:
            sig = frozenset((_key(a), tuple(b)) for a, b in ops)
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
        total += _log_sig((corr[_key(a)][ia, ib] / ceiling - tau) / kappa)
        shifts.append((ia, ib))
        if round(np.linalg.det(a)) == 1:
            present.add((_key(a), "rot"))
        else:
            mir, _ = _reflection_classes(a, n)
            present.add((_key(a), "mirror" if mir[b[0], b[1]] else "glide"))
    return total, shifts, present


def _fit_groups(corr: dict, forb: dict[tuple, float], holo: list[np.ndarray],
                basis: np.ndarray, ceiling: float, *, tau: float, kappa: float,
                snap_tol: float, strain_sigma: float
                ) -> tuple[dict[str, _GroupFit], dict[str, tuple[float, float]]]:
    """Each of the 17 groups' best reading (over its conventions and origins): its
    operations should hold, every other isometry class of the lattice should not, and
    the strain its lattice needs costs a prior. Groups whose lattice is beyond
    ``snap_tol`` come apart, as ``(score, strain)``: never the answer, but their
    operations holding is evidence against every answer that forbids them."""
    n = next(iter(corr.values())).shape[0]
    holo_keys = {_key(a) for a in holo}
    best: dict[str, _GroupFit] = {}
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
                best[name] = _GroupFit(score, u, _refine_origin(total, ka, kb) / n, at,
                                       frozenset(present))
    return best, {k: v for k, v in beyond.items() if k not in best}


def _beyond_message(beyond: dict[str, tuple[float, float]], score: float, win: str
                    ) -> str:
    """Why the answer goes to the operator when a group holding beyond the snap is
    likelier than it; empty when none is."""
    likelier = [k for k, (s, _) in beyond.items() if s > score]
    if not likelier:
        return ""
    off = max(likelier, key=lambda k: beyond[k][0])
    return (f"{off} holds on this lattice stretched {100 * beyond[off][1]:.0f} % off its "
            f"own, more than a print is snapped by: the cloth or the view distorts it "
            f"(straighten the cloth, or confirm {win})")


def _joined(*parts: str) -> str:
    return "; ".join(p for p in parts if p)


# ---------------------------------------------------------------- main entry
def classify(image: np.ndarray, lattice: LatticeResult, *, cell_n: int = CELL_N,
             max_repeats: int = 400, tau: float = TAU, kappa: float = KAPPA,
             work_side: int = 1024, flat: np.ndarray | None = None,
             scale: float | None = None, whiten: float = WHITEN,
             prefilter: float = 1.0, holohedry_tol: float = HOLOHEDRY_TOL,
             strain_sigma: float = STRAIN_SIGMA, band: float = BAND,
             temperature: float = TEMPERATURE, allowance: float = 0.0,
             lag: float = ADDED_OPERATION_LAG, lag_spread: float = ADDED_LAG_SPREAD,
             consistency: bool = True,
             own_asymmetry: float = OWN_ASYMMETRY,
             shared_asymmetry: float = SHARED_ASYMMETRY,
             pixel_slack: bool = True, adaptive_band: bool = True) -> Classification:
    """Wallpaper group, conventional lattice and origin of the print in ``image``.

    Parameters
    ----------
    image : (H,W) or (H,W,3) array
        The same rectified image :func:`vision.lattice.detect_lattice` was run on.
    lattice : LatticeResult
        Its answer; anything but a 2-D lattice gives ``group=None``.
    cell_n : int
        Mean-cell grid (multiple of 12).
    tau, kappa : float
        Score (relative to the motif's reliability) at which an operation is as likely
        present as absent, and the width of that transition.
    holohedry_tol, strain_sigma : float
        How far the measured lattice may be from each group's lattice (the print may
        be stretched or sheared by the cloth or the camera) and the prior width of
        that strain: the answer is the group the print was designed with.
    band, adaptive_band
        Harmonics per repeat where the whitened motif rolls off (thread-scale texture
        above it does not share the print's symmetry); lower where single repeats
        differ below it (:func:`vision.neighbours.print_band`) unless not adaptive.
    lag, lag_spread : float
        How far the operations a group adds to a subgroup (or to the translations) may
        all score below the subgroup's before the group is not taken, and how much
        that widens per unit of the single repeats' disagreement.
    allowance : float
        Distortion the image is known to carry (relative), e.g. the lattice change a
        measured perspective makes across the frame (:mod:`vision.perspective`): the
        print's lattice cannot be read to better than that, so the snap tolerance and
        the strain prior widen by it.
    consistency, own_asymmetry, shared_asymmetry
        Refuse a group one of whose operations leaves the same residual all over the
        cloth (:func:`invents`, with its two thresholds); off only to measure what it
        changes.
    pixel_slack
        On an image whose repeats lie whole pixels apart (a rendering), allow every
        edge to sit up to ``EDGE_SLACK_PX`` off its image under an operation
        (:func:`vision.consistency.pixel_rounding`). A group read only with that
        allowance goes to the operator (confidence at most ``ROUNDING_CONFIDENCE``):
        a faint stroke along an edge hides in it as well.

    Returns
    -------
    Classification
        ``wallpaper`` in mm of the input image frame (x right, y down, pixel centres at
        ``(col, row) * mm_per_px``), with the group's conventional basis and an origin
        where the group's operations hold; ``confidence`` in [0, 1]. p1, confidence at
        most ``FEW_REPEATS_CONFIDENCE`` and a ``message`` when single repeats look too
        little alike for any symmetry to be checked on them (``LIKENESS_BAND``).
    """
    if not lattice.found:
        return Classification(None, None, 0.0, message=lattice.message or "no lattice")
    if cell_n % 12:
        raise ValueError(f"cell_n must be a multiple of 12, got {cell_n}")
    if flat is None or scale is None:
        flat, scale = prepare_image(image, work_side=work_side)
    mm = lattice.mm_per_px
    basis = lattice.basis / mm * scale  # working (x, y) px
    try:
        anchor, (motif, halves, nrep, ij, _, cells) = repeat_cells(
            flat, basis, cell_n=cell_n, max_repeats=max_repeats, prefilter=prefilter)
    except ValueError as exc:
        return Classification(None, None, 0.0, message=str(exc))
    motif = motif - motif.mean()
    # The tolerances widen by the known distortion (HOLOHEDRY_TOL spans a strain of
    # HOLOHEDRY_STRAIN; the snap tolerance is a strain already).
    holo = holohedry(basis, tol=holohedry_tol * (1.0 + allowance / HOLOHEDRY_STRAIN))
    snap_tol = SNAP_TOL + allowance
    metric = symmetric_metric(basis, holo)
    # A rendering repeats by whole pixels: its edges' rounding to the grid is the same
    # in every repeat, and is allowed (vision.consistency.EDGE_SLACK_PX).
    rounding = pixel_rounding(basis, scale, ij, cell_n, half=True) if pixel_slack else None
    centred = cells - cells.mean(axis=(1, 2), keepdims=True)
    if adaptive_band and len(cells) >= 3:
        band = min(band, print_band(centred, ij, metric, whiten, band))
    spectra = None
    if consistency:
        spectra = repeat_spectra(centred, ij, whitening(cell_n, metric, whiten,
                                                        min(band, CONSISTENCY_BAND)),
                                 rounding=rounding)
    # How alike single repeats are at the print's scale (see LIKENESS_BAND).
    likeness, sampled = _likeness(centred, ij, metric, whiten) if len(cells) > 1 else (1, 1)
    if whiten:
        motif = whitened(motif, metric, whiten, band)
        halves = tuple(whitened(hv, metric, whiten, band) for hv in halves)
        cells = whitened(centred, metric, whiten, band)
    rel = split_half_reliability(*halves)
    if motif.std() < 1e-6:
        return Classification(None, None, 0.0, message="the mean cell is flat")
    ceiling = max(rel, 0.3)
    corr, forb, op_scores = _isometry_scores(motif, holo, basis, ceiling, rounding)
    best, beyond = _fit_groups(corr, forb, holo, basis, ceiling, tau=tau, kappa=kappa,
                               snap_tol=snap_tol,
                               strain_sigma=math.hypot(strain_sigma, allowance))
    if not best:
        return Classification(None, None, 0.0, message="no group fits the lattice")
    names = list(best)
    ll = np.array([best[k].score for k in names])
    everything = np.concatenate([ll, [v[0] for v in beyond.values()]])
    post = np.exp((ll - everything.max()) / temperature)
    post /= np.exp((everything - everything.max()) / temperature).sum()
    # Behind the translations the allowed lag widens by how much single repeats differ:
    # each repeat is registered onto the mean (a translation), its other operations are
    # not, so on real cloth they fall short of the translations by about as much.
    spread = max(0.0, 1.0 - neighbour_correlation(cells)) if len(cells) > 1 else 0.0
    unlike = len(cells) >= 3 and min(likeness, sampled) < REPEAT_SUPPORT and "p1" in best
    message = ""
    if unlike:
        # The translations themselves fail, at the print's scale, the bar every
        # operation must pass on single repeats: the step is hardly a repeat of the
        # print (a beat of the weave with the pixels, say, over a print it does not
        # fit) and the mean cell's symmetry is the averaging's. Nothing can be
        # checked, so nothing is claimed.
        win = "p1"
        message = (f"single repeats look little alike (correlation "
                   f"{min(likeness, sampled):.2f}, under "
                   f"{REPEAT_SUPPORT:g}): no symmetry can be checked on them, none is "
                   "claimed")
    else:
        win, refused = _supported_winner(names, ll, best, cells, forb, basis,
                                         translation=rel / ceiling - LAG_SPREAD * spread,
                                         lag=lag + lag_spread * spread, spectra=spectra,
                                         asym=(own_asymmetry, shared_asymmetry))
        if refused is not None:
            message = (f"{refused.group} is likelier ({post[names.index(refused.group)]:.2f}) "
                       f"but not taken: {refused.why}")
    # Back to mm of the input image: working px -> input px -> mm.
    new_basis_px = basis @ best[win].u
    origin_w = anchor + basis @ best[win].origin
    origin_in = (origin_w + 0.5) / scale - 0.5
    w1 = new_basis_px[:, 0] / scale * mm
    w2 = new_basis_px[:, 1] / scale * mm
    wp = Wallpaper.snapped(win, w1, w2, origin_in * mm, motif=motif, snap_tol=snap_tol)
    strain = lattice_strain(np.column_stack([w1, w2]), wp.basis)
    wp = _nearest_origin(wp, np.array([(image.shape[1] - 1) / 2,
                                       (image.shape[0] - 1) / 2]) * mm)
    confidence = float(post[names.index(win)])
    message = _joined(message, _beyond_message(beyond, best[win].score, win))
    if nrep < 3 or unlike:
        # No per-repeat check: never sure enough to skip the operator.
        confidence = min(confidence, FEW_REPEATS_CONFIDENCE)
    if rounding is not None:
        strict = classify(image, lattice, cell_n=cell_n, max_repeats=max_repeats, tau=tau,
                          kappa=kappa, work_side=work_side, flat=flat, scale=scale,
                          whiten=whiten, prefilter=prefilter,
                          holohedry_tol=holohedry_tol, strain_sigma=strain_sigma,
                          band=band, temperature=temperature, allowance=allowance,
                          lag=lag, lag_spread=lag_spread, consistency=consistency,
                          own_asymmetry=own_asymmetry, shared_asymmetry=shared_asymmetry,
                          pixel_slack=False, adaptive_band=adaptive_band)
        if strict.group != win:
            confidence = min(confidence, ROUNDING_CONFIDENCE)
            message = _joined(message, (
                f"a rendering (repeats whole pixels apart): {win} holds with its edges "
                f"allowed {EDGE_SLACK_PX:g} px off, {strict.group} without"))
    return Classification(wp, win, confidence,
                          scores={**{k: float(v) for k, v in zip(names, ll, strict=True)},
                                  **{k: float(v[0]) for k, v in beyond.items()}},
                          op_scores=op_scores, reliability=rel, n_repeats=nrep,
                          motif=motif, message=message, temperature=temperature,
                          strain=strain, likeness=likeness)


class _Refusal(NamedTuple):
    """A group likelier than the answer that was not taken, and why (for the operator)."""

    group: str
    why: str


def _supported_winner(names: list[str], ll: np.ndarray, best: dict, cells: np.ndarray,
                      scores: dict, basis: np.ndarray, *, translation: float = 1.0,
                      lag: float = ADDED_OPERATION_LAG,
                      spectra: RepeatSpectra | None = None,
                      asym: tuple[float, float] | None = None
                      ) -> tuple[str, _Refusal | None]:
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
    first: _Refusal | None = None
    for name in order:
        if not is_subgroup(name, top):
            continue
        why = _refusal(name, best, cells, scores, basis, translation=translation, lag=lag,
                       spectra=spectra, seen=seen, asym=asym)
        if not why:
            return name, first
        first = first or _Refusal(name, why)
    return top, None


def _refusal(name: str, best: dict, cells: np.ndarray, scores: dict, basis: np.ndarray,
             *, translation: float, lag: float, spectra: RepeatSpectra | None, seen: dict,
             asym: tuple[float, float] | None) -> str:
    """Why ``name`` cannot be the answer (see :func:`_supported_winner`); empty when it
    can."""
    lagging = _lags(name, best, scores, translation, lag)
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


def isometry_name(a: np.ndarray, basis: np.ndarray | None = None) -> str:
    """An isometry of a lattice (integer matrix ``a`` in its basis) in words: a turn's
    order follows from the integer trace, a reflection's axis (given ``basis``, working
    px) from the basis."""
    if round(np.linalg.det(a)) == 1:
        return {-2: "half turn", -1: "third turn", 0: "quarter turn",
                1: "sixth turn"}.get(int(round(np.trace(a))), "turn")
    return "reflection" if basis is None else f"reflection at {_name(a, basis)[5:-1]} degrees"


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
        key = (_key(a), int(s[0]), int(s[1]))
        if key not in seen:
            asym = asymmetry(spectra, a, s)
            seen[key] = asym.own > own and asym.share > shared
        if seen[key]:
            return a
    return None


def _lags(name: str, best: dict, scores: dict, translation: float = 1.0,
          lag: float = ADDED_OPERATION_LAG) -> tuple[str, float] | None:
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


def _refine_origin(total: np.ndarray, ka: int, kb: int) -> np.ndarray:
    """Sub-grid maximum of the periodic origin score by a parabola along each axis."""
    n = total.shape[0]

    def para(cm, c0, cp):
        den = cm - 2 * c0 + cp
        return 0.0 if abs(den) < 1e-12 else float(np.clip(0.5 * (cm - cp) / den, -0.5, 0.5))

    da = para(total[(ka - 1) % n, kb], total[ka, kb], total[(ka + 1) % n, kb])
    db = para(total[ka, (kb - 1) % n], total[ka, kb], total[ka, (kb + 1) % n])
    return np.array([ka + da, kb + db])


def _nearest_origin(wp: Wallpaper, target: np.ndarray) -> Wallpaper:
    """The same print with its origin moved by a lattice vector next to ``target``."""
    f = wp.to_fractional(target[None])[0]
    origin = wp.origin + wp.basis @ np.floor(f)
    return Wallpaper(wp.group, wp.w1, wp.w2, origin, motif=wp.motif, tol=1e-6)


def symmetry_elements(wp: Wallpaper, region: tuple[float, float, float, float]
                      ) -> tuple[list[tuple[np.ndarray, int]], list[tuple[np.ndarray,
                                                                          np.ndarray, bool]]]:
    """Rotation centres (point, order) and reflection lines (point, direction, is_glide)
    of ``wp`` inside ``region`` = (x0, y0, x1, y1) mm, for drawing."""
    x0, y0, x1, y1 = region
    corners = np.array([[x0, y0], [x1, y0], [x0, y1], [x1, y1]])
    f = wp.to_fractional(corners)
    lo, hi = np.floor(f.min(0)).astype(int) - 1, np.ceil(f.max(0)).astype(int) + 1
    centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
    reach = 0.5 * math.hypot(x1 - x0, y1 - y0)
    centres, lines = [], []
    for op in wp.cartesian_ops()[1:]:
        lin, t = op[:2, :2], op[:2, 2]
        if np.linalg.det(lin) > 0:
            ang = math.degrees(math.atan2(lin[1, 0], lin[0, 0])) % 360
            order = round(360 / ang)
            for i in range(lo[0], hi[0] + 1):
                for j in range(lo[1], hi[1] + 1):
                    # Rotation composed with the translation by i w1 + j w2.
                    c = np.linalg.solve(np.eye(2) - lin, t + wp.basis @ (i, j))
                    if x0 <= c[0] <= x1 and y0 <= c[1] <= y1:
                        centres.append((c, order))
        else:
            ev, vec = np.linalg.eigh((lin + lin.T) / 2)
            d = vec[:, np.argmax(ev)]
            for i in range(lo[0], hi[0] + 1):
                for j in range(lo[1], hi[1] + 1):
                    tt = t + wp.basis @ (i, j)
                    glide = (tt @ d) * d
                    p = (tt - glide) / 2
                    p = p + ((centre - p) @ d) * d  # the axis point nearest the region
                    if np.hypot(*(p - centre)) > reach:
                        continue
                    gl = wp.lattice_residual(glide[None])[0]
                    lines.append((p, d, bool(np.hypot(*gl) > 1e-6 * np.hypot(*wp.w1))))
    return centres, lines
