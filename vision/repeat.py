"""Is every translation of the lattice found a repeat of the print?

The lattice search (:mod:`vision.lattice`) reads the autocorrelation, where a print's
near-translation peaks almost as high as a repeat: a glide's half step under blur, a bold
layer on a finer lattice than the faint one drawn with it. Taken for a repeat, it invents
a translation, so the group comes out a supergroup on a lattice half the right size, and
pieces would be snapped to half a repeat. The cells of the repeats show it: alternate
repeats carry two different cells, and the difference is the same all over the cloth
(:func:`vision.consistency.alternation`). Then the lattice is the index-2 sublattice on
which the alternation is a repeat, and it is asked again.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from vision.classify import lattice_whitening
from vision.consistency import (
    MIN_SPAN,
    Alternation,
    alternation,
    pixel_rounding,
    rounding_map,
)
from vision.decision import OWN_ASYMMETRY, SHARED_ASYMMETRY
from vision.lattice import LatticeResult, sublattice
from vision.motif import repeat_cells

__all__ = ["ALTERNATION_BAND", "FALSE_STEP", "FALSE_STEP_Z", "step_is_repeat", "true_lattice"]

#: Harmonics per repeat where the test's whitening rolls off. A false step differs from
#: a repeat at the print's scale; the fine end carries the weave's beat with the pixels
#: (moire), which can alternate between repeats of a true lattice (a prints-on-cloth
#: bench image: own 0.046 at 6 harmonics, 0.003 at 3).
ALTERNATION_BAND = 3.0

#: The step between alternate repeats is not a repeat when their shared difference is
#: (1) what refuses an operation (:func:`vision.classify.invents`: ``own`` above
#: ``OWN_ASYMMETRY`` and ``share`` above ``SHARED_ASYMMETRY``), or (2) large against the
#: motif (``FALSE_STEP``) and many noise standard errors (``FALSE_STEP_Z``) even where
#: noise dominates single repeats. Measured on the bench (`bench.vision`, every own
#: source and the photographs, two per group): true lattices reach own 0.011 at share
#: 0.14 and share 0.33 at own 0.000; lattices read at half a step own 0.05 at share 0.15
#: (z 148) and 0.10 at 0.51, faint layers on a sublattice (`tests/vision/test_repeat.py`)
#: own 0.002-0.02 at share 0.56-0.97.
FALSE_STEP = 0.02
FALSE_STEP_Z = 8.0


def step_is_repeat(alt: Alternation | None) -> bool:
    """Whether the alternation measured leaves the lattice's step a repeat."""
    return alt is None or not ((alt.own > OWN_ASYMMETRY and alt.share > SHARED_ASYMMETRY)
                               or (alt.own > FALSE_STEP and alt.z > FALSE_STEP_Z))


#: The index-2 sublattice, as columns over the lattice's basis, whose points are the
#: repeats of even parity (p i + q j even).
_SUBLATTICE = {(1, 0): np.array([[2, 0], [0, 1]]),
               (0, 1): np.array([[1, 0], [0, 2]]),
               (1, 1): np.array([[1, 1], [1, -1]])}


def _rounding_of(basis: np.ndarray, scale: float, ij: np.ndarray, n: int
                 ) -> Callable[[tuple[int, int]], np.ndarray | None]:
    """For :func:`alternation`: per parity, whether the repeats of that index-2
    sublattice lie whole pixels apart (a rendering of a half-pixel step), and then the
    lattice cell's rounding map. The lattice's repeats must span ``MIN_SPAN`` each way,
    the sublattice's (half as many along one way) one less."""
    def of(parity: tuple[int, int]) -> np.ndarray | None:
        if len(ij) == 0 or np.ptp(ij, axis=0).min() < MIN_SPAN:
            return None
        even = (ij @ np.array(parity, float)) % 2 == 0
        sub = ij[even] @ np.linalg.inv(_SUBLATTICE[parity]).T  # indices on the sublattice
        if pixel_rounding(basis @ _SUBLATTICE[parity], scale, sub, n,
                          min_span=MIN_SPAN - 1) is None:
            return None
        return rounding_map(basis, n)
    return of


def true_lattice(image: np.ndarray, lat: LatticeResult, *,
                 prepared: tuple[np.ndarray, float], smooth_px: float = 1.0,
                 read: np.ndarray | None = None, max_halvings: int = 2) -> LatticeResult:
    """``lat``, or its sublattice of index 2 (or 4) when alternate repeats differ the same
    way all over the cloth. ``image``, ``prepared`` and ``smooth_px`` are what
    :func:`vision.lattice.detect_lattice` read ``lat`` on; ``read`` the working image the
    print is read on (``prepared``'s by default; the yarn smoothed away, say)."""
    flat, scale = prepared
    read = flat if read is None else read
    for _ in range(max_halvings):
        if not lat.found:
            return lat
        basis = lat.basis / lat.mm_per_px * scale
        try:
            _, (_, _, _, ij, _, cells) = repeat_cells(read, basis)
        except ValueError:
            return lat
        alt = alternation(cells - cells.mean(axis=(1, 2), keepdims=True), ij,
                          lattice_whitening(basis, ALTERNATION_BAND),
                          rounding=_rounding_of(basis, scale, ij, cells.shape[-1]))
        if step_is_repeat(alt):
            return lat
        lat = sublattice(lat, _SUBLATTICE[alt.parity], image, prepared=prepared,
                         smooth_px=smooth_px,
                         message=f"alternate repeats of the lattice first read differ "
                                 f"(shared difference {alt.own:.3f} of the motif): its "
                                 f"step is not a repeat of the print")
    return lat
