"""What detection hands on: the fabric's description (:class:`FabricDetection`, written
as FABRIC.json) and the operator's confirmation of it (:func:`confirm_fabric`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from solver.wallpaper import GROUPS, Wallpaper
from vision.classify import Classification, moved_origin
from vision.distortion import Distortion
from vision.groupfit import lattice_strain
from vision.lattice import LatticeResult

__all__ = ["STRETCH_TOL", "FabricDetection", "confirm_fabric"]

#: Stretch of the measured lattice off its group's (relative) beyond which the cloth is
#: reported distorted: pieces cut to the group's lattice come out of the print by it.
STRETCH_TOL = 0.03


@dataclass
class FabricDetection:
    lattice: LatticeResult
    classification: Classification
    distortion: Distortion
    offset: np.ndarray
    mm_per_px: float
    seconds: float
    #: Repeat of the yarn (mm) where the image shows it (:func:`vision.lattice.yarn_repeat`),
    #: smoothed away before the print was read unless nothing was above it; else NaN.
    yarn_mm: float = float("nan")
    #: The reading refused for want of evidence of a repeat (:mod:`vision.evidence`),
    #: which the operator may confirm; None otherwise.
    candidate: Wallpaper | None = None

    @property
    def wallpaper(self) -> Wallpaper | None:
        wp = self.classification.wallpaper
        return None if wp is None else moved_origin(wp, self.offset)

    def fabric_json(self) -> dict:
        """FABRIC.json: the foundation's format plus confidence, distortion and the
        lattice's uncertainty; a stripes/no-print answer has ``group: null``."""
        wp = self.wallpaper
        out: dict = {"group": None, "units": "mm"}
        if wp is not None:
            out.update(wp.to_dict())
            out["kind"] = "lattice"
            if self.classification.message:
                out["message"] = self.classification.message
        else:
            out["kind"] = self.lattice.kind
            out["message"] = self.lattice.message
            if self.lattice.kind == "stripes":
                out["period"] = self.lattice.period
                out["direction_deg"] = self.lattice.direction_deg
            if self.candidate is not None:
                out["candidate"] = moved_origin(self.candidate, self.offset).to_dict()
        out["confidence"] = round(float(self.classification.confidence), 4)
        out["group_confidence"] = {k: round(v, 4) for k, v in
                                   self.classification.posterior.items() if v >= 1e-4}
        out["distortion"] = self.distortion.to_dict()
        # The measured lattice's departure from the group's (snapped) one: a square
        # check stretched 5 % by the cloth or the camera reads 0.05.
        out["distortion"]["lattice_strain"] = round(float(self.classification.strain), 4)
        if self.lattice.found:
            out["lattice_sigma_mm"] = float(self.lattice.sigma_w1[0])
        if np.isfinite(self.yarn_mm):
            out["yarn_mm"] = round(float(self.yarn_mm), 4)
        return out

    def summary(self) -> dict:
        """The ``--json`` line: group (null without a lattice), w1, w2, origin,
        confidence, seconds."""
        wp = self.wallpaper
        return {"group": None if wp is None else wp.group,
                "w1": None if wp is None else [round(v, 4) for v in wp.w1.tolist()],
                "w2": None if wp is None else [round(v, 4) for v in wp.w2.tolist()],
                "origin": None if wp is None else [round(v, 4) for v in wp.origin.tolist()],
                "confidence": round(float(self.classification.confidence), 4),
                "kind": self.lattice.kind,
                "distortion_warning": self.distortion.warning,
                "seconds": round(self.seconds, 3)}


def confirm_fabric(doc: dict, group: str | None = None) -> dict:
    """FABRIC.json ``doc`` as the operator confirmed it: the detected group accepted, or
    replaced by ``group`` on the same measured lattice and origin (snapped to the new
    group's lattice; raises ValueError when that lattice cannot carry it). A snap that
    stretches the measured lattice beyond ``STRETCH_TOL`` is recorded in the
    distortion's strain and warning, as detection records its own. Cloth reported plain
    for want of evidence of a repeat keeps the reading refused (``candidate``): the
    operator accepts plain (no ``group``) or overrides with ``group`` on its lattice."""
    if doc.get("group") is None and doc.get("candidate"):
        if group is None:
            return {**doc, "confirmed": True}
        doc = {**{k: v for k, v in doc.items() if k != "candidate"}, **doc["candidate"],
               "kind": "lattice", "refused": doc.get("message")}
    if doc.get("group") is None:
        raise ValueError(f"no lattice was detected ({doc.get('kind', 'no print')}): "
                         "there is no group to confirm; give the job a FABRIC.json")
    out = dict(doc)
    if group is not None and group != doc["group"]:
        out = _overridden(doc, group)
    out["confirmed"] = True
    out["confidence"] = 1.0
    return out


def _overridden(doc: dict, group: str) -> dict:
    """``doc`` with its group replaced by ``group`` on the measured lattice, snapped to
    the group's; the stretch that takes in its distortion (and warning, beyond
    ``STRETCH_TOL``). A ValueError, with the stretch each group would need, when the
    lattice cannot carry ``group``."""
    if group not in GROUPS:
        raise ValueError(f"unknown wallpaper group {group!r}; expected one of "
                         f"{', '.join(GROUPS)}")
    try:
        wp = Wallpaper.snapped(group, doc["w1"], doc["w2"], doc.get("origin", (0.0, 0.0)))
    except ValueError as exc:
        needs = {g: _strain_for(g, doc["w1"], doc["w2"]) for g in GROUPS}
        carried = sorted((v, g) for g, v in needs.items() if v is not None)
        raise ValueError(
            f"{exc}: the cloth as it lies does not carry {group}, and pieces cut to "
            f"it would drift off the print. Confirm a group this lattice carries "
            f"(with the stretch each needs: "
            f"{', '.join(f'{g} {100 * v:.0f} %' for v, g in carried)}), or straighten "
            "the cloth and photograph it again") from None
    out = {**doc, **wp.to_dict(), "detected_group": doc["group"]}
    strain = _strain_for(group, doc["w1"], doc["w2"])
    distortion = dict(out.get("distortion") or {}, lattice_strain=round(strain, 4))
    if strain > STRETCH_TOL:
        fault = (f"confirmed as {group}, which stretches the measured lattice "
                 f"{100 * strain:.1f} % (tolerance {100 * STRETCH_TOL:g} %): pieces "
                 "cut to it come out of the print by that much")
        distortion["warning"] = "; ".join(w for w in (distortion.get("warning"), fault) if w)
    out["distortion"] = distortion
    return out


def _strain_for(group: str, w1, w2) -> float | None:
    """The stretch (largest principal strain) that snapping the measured lattice
    (w1, w2) to ``group``'s takes; None when it does not snap."""
    try:
        ideal = Wallpaper.snapped(group, w1, w2).basis
    except ValueError:
        return None
    measured = np.column_stack([w1, w2]).astype(float)
    # The snapped basis may be another basis of the same lattice.
    same = measured @ np.rint(np.linalg.solve(measured, ideal))
    return lattice_strain(same, ideal)
