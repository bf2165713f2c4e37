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

The steps live in :mod:`vision.motif` (1), :mod:`vision.isometries` (2),
:mod:`vision.groupfit` (3) and :mod:`vision.decision` (4, the operations that must hold on
single repeats); :func:`classify` reads them in order.

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
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np

from solver.wallpaper import Wallpaper
from vision.consistency import (
    EDGE_SLACK_PX,
    WEIGHT_FLOOR,
    RepeatSpectra,
    pixel_rounding,
    repeat_spectra,
)
from vision.decision import (
    ADDED_OPERATION_LAG,
    OWN_ASYMMETRY,
    REPEAT_SUPPORT,
    SHARED_ASYMMETRY,
    supported_winner,
)
from vision.groupfit import GroupFit, fit_groups, isometry_scores, lattice_strain
from vision.isometries import holohedry, isometry_name
from vision.lattice import LatticeResult
from vision.motif import CELL_N, mean_cell, repeat_cells, split_half_reliability
from vision.neighbours import neighbour_correlation, print_band, worse_likeness
from vision.prepare import prepare_image
from vision.whitening import symmetric_metric, whitened, whitening

# isometry_name, mean_cell and symmetric_metric stay part of this module's interface (bench
# reads them here); they live in vision.isometries, vision.motif and vision.whitening.
__all__ = ["ClassifyOptions", "Classification", "classify", "isometry_name",
           "lattice_whitening", "mean_cell", "moved_origin", "repeat_cells", "symmetric_metric"]

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

#: Harmonics per repeat where the consistency test's whitening rolls off: below
#: ``BAND``, as anti-aliased strokes leave pixel-scale residuals (line caps, widths
#: rounded to pixels) of a few per cent even under their true mirrors.
CONSISTENCY_BAND = 6.0


def lattice_whitening(basis: np.ndarray, band: float, n: int = CELL_N) -> np.ndarray:
    """The whitening (n, n) of cells of the lattice ``basis``, rolled off at ``band``
    harmonics per repeat, under the metric of the undistorted print."""
    return whitening(n, symmetric_metric(basis, holohedry(basis, tol=HOLOHEDRY_TOL)),
                     WHITEN, band)


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


@dataclass(frozen=True)
class ClassifyOptions:
    """The settings of :func:`classify`, with their defaults; ``classify(..., tau=0.9)``
    sets one by name."""

    #: Mean-cell grid (a multiple of 12).
    cell_n: int = CELL_N
    #: Most repeats sampled (the central ones: least distorted by the view).
    max_repeats: int = 400
    #: Score (relative to the motif's reliability) at which an operation is as likely
    #: present as absent, and the width of that transition.
    tau: float = TAU
    kappa: float = KAPPA
    #: Exponent of the motif's |frequency| weighting (0: none), and the Gaussian
    #: prefilter of the image, in cell-grid spacings.
    whiten: float = WHITEN
    prefilter: float = 1.0
    #: How far the measured lattice may be from each group's lattice (the print may be
    #: stretched or sheared by the cloth or the camera) and the prior width of that
    #: strain: the answer is the group the print was designed with.
    holohedry_tol: float = HOLOHEDRY_TOL
    strain_sigma: float = STRAIN_SIGMA
    #: Harmonics per repeat where the whitened motif rolls off (thread-scale texture
    #: above it does not share the print's symmetry); lower where single repeats differ
    #: below it (:func:`vision.neighbours.print_band`) unless not ``adaptive_band``.
    band: float = BAND
    adaptive_band: bool = True
    #: Temperature of the posterior over groups.
    temperature: float = TEMPERATURE
    #: Distortion the image is known to carry (relative), e.g. the lattice change a
    #: measured perspective makes across the frame (:mod:`vision.perspective`): the
    #: print's lattice cannot be read to better than that, so the snap tolerance and the
    #: strain prior widen by it.
    allowance: float = 0.0
    #: How far the operations a group adds to a subgroup (or to the translations) may
    #: all score below the subgroup's before the group is not taken, and how much that
    #: widens per unit of the single repeats' disagreement.
    lag: float = ADDED_OPERATION_LAG
    lag_spread: float = ADDED_LAG_SPREAD
    #: Refuse a group one of whose operations leaves the same residual all over the
    #: cloth (:func:`vision.decision.invents`, with its two thresholds); off only to
    #: measure what it changes.
    consistency: bool = True
    own_asymmetry: float = OWN_ASYMMETRY
    shared_asymmetry: float = SHARED_ASYMMETRY
    #: On an image whose repeats lie whole pixels apart (a rendering), allow every edge
    #: to sit up to ``EDGE_SLACK_PX`` off its image under an operation
    #: (:func:`vision.consistency.pixel_rounding`). A group read only with that
    #: allowance goes to the operator (confidence at most ``ROUNDING_CONFIDENCE``): a
    #: faint stroke along an edge hides in it as well.
    pixel_slack: bool = True


def classify(image: np.ndarray, lattice: LatticeResult, *, flat: np.ndarray | None = None,
             scale: float | None = None, work_side: int = 1024,
             **options: float | int | bool) -> Classification:
    """Wallpaper group, conventional lattice and origin of the print in ``image``.

    Parameters
    ----------
    image : (H,W) or (H,W,3) array
        The same rectified image :func:`vision.lattice.detect_lattice` was run on.
    lattice : LatticeResult
        Its answer; anything but a 2-D lattice gives ``group=None``.
    flat, scale : optional
        :func:`vision.prepare.prepare_image`'s answer for ``image``, to share it
        between steps; made at ``work_side`` otherwise.
    **options
        The fields of :class:`ClassifyOptions` (a TypeError names any other).

    Returns
    -------
    Classification
        ``wallpaper`` in mm of the input image frame (x right, y down, pixel centres at
        ``(col, row) * mm_per_px``), with the group's conventional basis and an origin
        where the group's operations hold; ``confidence`` in [0, 1]. p1, confidence at
        most ``FEW_REPEATS_CONFIDENCE`` and a ``message`` when single repeats look too
        little alike for any symmetry to be checked on them (``LIKENESS_BAND``).
    """
    opts = ClassifyOptions(**options)
    if not lattice.found:
        return Classification(None, None, 0.0, message=lattice.message or "no lattice")
    if opts.cell_n % 12:
        raise ValueError(f"cell_n must be a multiple of 12, got {opts.cell_n}")
    if flat is None or scale is None:
        flat, scale = prepare_image(image, work_side=work_side)
    return _classify(image.shape[:2], lattice, flat, scale, opts)


class _Cells(NamedTuple):
    """The repeats of one lattice as the decision reads them: the mean cell and the
    single repeats (whitened), their indices, the mean's split-half reliability, the
    lattice's isometries and the metric they keep, what pixel rounding allows (or None),
    the repeats' spectra for the consistency test (or None), how alike single repeats
    look (along the worse vector; consecutive ones) and the whitening's band."""

    motif: np.ndarray
    cells: np.ndarray
    ij: np.ndarray
    reliability: float
    holo: list[np.ndarray]
    rounding: np.ndarray | None
    spectra: RepeatSpectra | None
    likeness: float
    sampled: float
    band: float


def _classify(shape: tuple[int, int], lattice: LatticeResult, flat: np.ndarray,
              scale: float, opts: ClassifyOptions) -> Classification:
    """:func:`classify` on the working image ``flat`` of an image of ``shape`` px."""
    mm = lattice.mm_per_px
    basis = lattice.basis / mm * scale  # working (x, y) px
    try:
        anchor, (motif, halves, nrep, ij, _, cells) = repeat_cells(
            flat, basis, cell_n=opts.cell_n, max_repeats=opts.max_repeats,
            prefilter=opts.prefilter)
    except ValueError as exc:
        return Classification(None, None, 0.0, message=str(exc))
    read = _read_cells(motif - motif.mean(), halves, cells, ij, basis, scale, opts)
    if read.motif.std() < 1e-6:
        return Classification(None, None, 0.0, message="the mean cell is flat")
    ceiling = max(read.reliability, 0.3)
    snap_tol = SNAP_TOL + opts.allowance
    corr, forb, op_scores = isometry_scores(read.motif, read.holo, basis, ceiling,
                                            read.rounding)
    best, beyond = fit_groups(corr, forb, read.holo, basis, ceiling, tau=opts.tau,
                              kappa=opts.kappa, snap_tol=snap_tol,
                              strain_sigma=math.hypot(opts.strain_sigma, opts.allowance))
    if not best:
        return Classification(None, None, 0.0, message="no group fits the lattice")
    names = list(best)
    ll = np.array([best[k].score for k in names])
    post = _posterior(ll, beyond, opts.temperature)
    win, message, unlike = _winner(names, ll, post, best, forb, basis, read, opts)
    # Back to mm of the input image: working px -> input px -> mm.
    new_basis_px = basis @ best[win].u
    origin_w = anchor + basis @ best[win].origin
    origin_in = (origin_w + 0.5) / scale - 0.5
    w1 = new_basis_px[:, 0] / scale * mm
    w2 = new_basis_px[:, 1] / scale * mm
    wp = Wallpaper.snapped(win, w1, w2, origin_in * mm, motif=read.motif, snap_tol=snap_tol)
    strain = lattice_strain(np.column_stack([w1, w2]), wp.basis)
    wp = _nearest_origin(wp, np.array([(shape[1] - 1) / 2, (shape[0] - 1) / 2]) * mm)
    confidence = float(post[names.index(win)])
    message = _joined(message, _beyond_message(beyond, best[win].score, win))
    if nrep < 3 or unlike:
        # No per-repeat check: never sure enough to skip the operator.
        confidence = min(confidence, FEW_REPEATS_CONFIDENCE)
    if read.rounding is not None:
        strict = _classify(shape, lattice, flat, scale,
                           replace(opts, band=read.band, pixel_slack=False))
        if strict.group != win:
            confidence = min(confidence, ROUNDING_CONFIDENCE)
            message = _joined(message, (
                f"a rendering (repeats whole pixels apart): {win} holds with its edges "
                f"allowed {EDGE_SLACK_PX:g} px off, {strict.group} without"))
    return Classification(wp, win, confidence,
                          scores={**{k: float(v) for k, v in zip(names, ll, strict=True)},
                                  **{k: float(v[0]) for k, v in beyond.items()}},
                          op_scores=op_scores, reliability=read.reliability, n_repeats=nrep,
                          motif=read.motif, message=message, temperature=opts.temperature,
                          strain=strain, likeness=read.likeness)


def _read_cells(motif: np.ndarray, halves: tuple[np.ndarray, np.ndarray], cells: np.ndarray,
                ij: np.ndarray, basis: np.ndarray, scale: float, opts: ClassifyOptions
                ) -> _Cells:
    """The mean cell (mean removed), its halves and the single repeats of the lattice
    ``basis`` (working px) made ready for the decision (:class:`_Cells`). The tolerances
    widen by the known distortion (``HOLOHEDRY_TOL`` spans a strain of
    ``HOLOHEDRY_STRAIN``)."""
    holo = holohedry(basis, tol=opts.holohedry_tol * (1.0 + opts.allowance / HOLOHEDRY_STRAIN))
    metric = symmetric_metric(basis, holo)
    whiten, band = opts.whiten, opts.band
    # A rendering repeats by whole pixels: its edges' rounding to the grid is the same
    # in every repeat, and is allowed (vision.consistency.EDGE_SLACK_PX).
    rounding = (pixel_rounding(basis, scale, ij, opts.cell_n, half=True) if opts.pixel_slack
                else None)
    centred = cells - cells.mean(axis=(1, 2), keepdims=True)
    if opts.adaptive_band and len(cells) >= 3:
        band = min(band, print_band(centred, ij, metric, whiten, band))
    spectra = None
    if opts.consistency:
        spectra = repeat_spectra(centred, ij, whitening(opts.cell_n, metric, whiten,
                                                        min(band, CONSISTENCY_BAND)),
                                 rounding=rounding)
    # How alike single repeats are at the print's scale (see LIKENESS_BAND).
    likeness, sampled = _likeness(centred, ij, metric, whiten) if len(cells) > 1 else (1, 1)
    if whiten:
        motif = whitened(motif, metric, whiten, band)
        halves = tuple(whitened(hv, metric, whiten, band) for hv in halves)
        cells = whitened(centred, metric, whiten, band)
    return _Cells(motif, cells, ij, split_half_reliability(*halves), holo, rounding, spectra,
                  likeness, sampled, band)


def _posterior(ll: np.ndarray, beyond: dict[str, tuple[float, float]], temperature: float
               ) -> np.ndarray:
    """Posterior of the groups scoring ``ll``, normalised over them and the groups
    holding ``beyond`` the snap (weighed, never the answer)."""
    everything = np.concatenate([ll, [v[0] for v in beyond.values()]])
    post = np.exp((ll - everything.max()) / temperature)
    post /= np.exp((everything - everything.max()) / temperature).sum()
    return post


def _winner(names: list[str], ll: np.ndarray, post: np.ndarray, best: dict[str, GroupFit],
            forb: dict[tuple, float], basis: np.ndarray, read: _Cells, opts: ClassifyOptions
            ) -> tuple[str, str, bool]:
    """The group taken (:func:`vision.decision.supported_winner`), why a likelier one was
    not (or ""), and whether single repeats look too little alike to check anything."""
    cells, likeness, sampled = read.cells, read.likeness, read.sampled
    # Behind the translations the allowed lag widens by how much single repeats differ:
    # each repeat is registered onto the mean (a translation), its other operations are
    # not, so on real cloth they fall short of the translations by about as much.
    spread = max(0.0, 1.0 - neighbour_correlation(cells)) if len(cells) > 1 else 0.0
    unlike = len(cells) >= 3 and min(likeness, sampled) < REPEAT_SUPPORT and "p1" in best
    if unlike:
        # The translations themselves fail, at the print's scale, the bar every
        # operation must pass on single repeats: the step is hardly a repeat of the
        # print (a beat of the weave with the pixels, say, over a print it does not
        # fit) and the mean cell's symmetry is the averaging's. Nothing can be
        # checked, so nothing is claimed.
        return "p1", (f"single repeats look little alike (correlation "
                      f"{min(likeness, sampled):.2f}, under "
                      f"{REPEAT_SUPPORT:g}): no symmetry can be checked on them, none is "
                      "claimed"), True
    ceiling = max(read.reliability, 0.3)
    win, refused = supported_winner(names, ll, best, cells, forb, basis,
                                    translation=read.reliability / ceiling - LAG_SPREAD * spread,
                                    lag=opts.lag + opts.lag_spread * spread,
                                    spectra=read.spectra,
                                    asym=(opts.own_asymmetry, opts.shared_asymmetry))
    if refused is None:
        return win, "", False
    return win, (f"{refused.group} is likelier ({post[names.index(refused.group)]:.2f}) "
                 f"but not taken: {refused.why}"), False


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


def _nearest_origin(wp: Wallpaper, target: np.ndarray) -> Wallpaper:
    """The same print with its origin moved by a lattice vector next to ``target``."""
    f = wp.to_fractional(target[None])[0]
    return moved_origin(wp, wp.basis @ np.floor(f))


def moved_origin(wp: Wallpaper, by: np.ndarray) -> Wallpaper:
    """The same print with its origin moved ``by`` (mm), lattice exactly as it is: from a
    part's frame to the image's, or from the image's to the machine's."""
    return Wallpaper(wp.group, wp.w1, wp.w2, wp.origin + by, tol=1e-6, motif=wp.motif)
