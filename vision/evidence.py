"""No lattice without evidence: is the lattice read a repeat of the cloth at all?

The autocorrelation of plain cloth (its shading streaks, its yarn) or of a tossed print
(leopard spots, no repeat in view) still has bumps, and the lattice search may fit one
to them. A print's lattice is a repeat all over the frame: its single repeats, each
registered onto the mean, look alike at the print's scale along both lattice vectors
(:func:`vision.neighbours.directional_likeness`). Where they do not, there is nothing to
cut to, and the station must not constrain the nest to a print that is not there: the
cloth is reported ``plain``, with the reason, and the rejected reading is kept as a
candidate that the operator may confirm (:func:`vision.fabric.confirm_fabric`).
"""

from __future__ import annotations

import numpy as np

from vision.classify import Classification
from vision.decision import REPEAT_SUPPORT
from vision.lattice import LatticeResult

__all__ = ["MIN_REPEATS", "missing_evidence", "without_lattice"]

#: Repeats in view below which likeness is not measured: a print of one or two
#: repeats goes to the operator on its own rule (``FEW_REPEATS_CONFIDENCE``).
MIN_REPEATS = 3


def missing_evidence(lat: LatticeResult, cls: Classification) -> str:
    """Why ``lat`` is no repeat of the cloth (empty when it is one, or cannot be told):
    its single repeats look less alike than ``REPEAT_SUPPORT``, the bar every operation
    must pass on single repeats, along one of its vectors."""
    if not lat.found or cls.n_repeats < MIN_REPEATS or not np.isfinite(cls.likeness):
        return ""
    if cls.likeness >= REPEAT_SUPPORT:
        return ""
    return (f"no repeat across the frame: on the best lattice the autocorrelation offers "
            f"({np.hypot(*lat.w1):.1f} x {np.hypot(*lat.w2):.1f} mm) single repeats look "
            f"little alike (correlation {cls.likeness:.2f} along its worse vector, under "
            f"{REPEAT_SUPPORT:g}): plain cloth or a tossed print; confirm the candidate "
            "only if the print repeats")


def without_lattice(lat: LatticeResult, why: str) -> tuple[LatticeResult, Classification]:
    """The answer ``plain``, saying ``why``, in place of the lattice ``lat``."""
    plain = LatticeResult("plain", mm_per_px=lat.mm_per_px, strength=lat.strength,
                          message=why)
    return plain, Classification(None, None, 0.0, message=why)
