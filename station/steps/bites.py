"""A marker longer than the table, bite by bite: plan the bites, then after each advance
find the cloth again and carry the rest of the marker onto it as it really lies.

`plan_job_bites` cuts the verified marker into bites of the table window, each advance
short enough that a strip of cloth stays in view (`vision.advance.MIN_OVERLAP_MM`), so
the print can be found again from the two photographs. `RollTrack` is the station's
knowledge of where the marker lies on the table: at the first bite the marker is where
it was planned; each measured advance (`vision.advance.Advance`) moves it by the rigid
motion the roll really made, and `RollTrack.bite_layout` gives the next bite's pieces
where they now lie. `find_bite` is one turn of the loop: advance (by the conveyor, or
the operator at `OPERATOR_ADVANCE`), photograph, measure, follow. `bites_report` is the
report's per-bite list, each advance with how it was measured (`ADVANCE_SOURCES`).

A print that says nothing along the roll (stripes along it, a plain cloth) cannot give
the advance; the station then measures it from what it put on the cloth itself: the
kerfs of the bite it just cut, photographed after the cut (`BiteStep.cut_photograph`).
Where the bite leaves room, the advance keeps `CUT_IN_VIEW_MM` of that cut in view.
Where no cut lies in the strip, the advance is the commanded one, reported as not
measured.

`save_bites` and `load_bites` keep the plan beside the job's layout.json (a job cut by
another process reads it back); the cut loop itself is `station.steps.cutbites`.
`localise` adds the print's own bow, skew and stretch: a local map of the print under
each piece of a bite (`vision.localmap`), and each piece placed on the print as it lies,
rigidly by default (a piece keeps its shape; what the map would have stretched is named
as the seam error expected), or stretched with it (`[roll] follow_print`).
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from solver.nest.bites import Bite, BitePlan, moved_piece, plan_bites
from solver.nest.instance import IDENTITY, affine, compose, invert
from solver.nest.layout import Layout, Placed
from station.config import FOLLOW_PRINT
from station.steps.table import TableWindow
from vision.advance import MIN_OVERLAP_MM, Advance, measure_advance
from vision.localmap import (
    LocalMap,
    PrintReference,
    fit_local_map,
    local_shifts,
    nearest_rigid,
    tile_centres,
)

#: a piece whose seams are expected off the print by more than this (mm) is named in the
#: report with that figure: the print's departure from one affine map under it, plus,
#: placed rigidly, what the rigid placement leaves of that map at its sew line
LOCAL_MAP_TOLERANCE_MM = 1.0
#: a local map stretching or shearing a piece by more than this (a fraction) is no bow or
#: skew of a print but tiles matched the wrong way: the piece keeps the track alone
MAX_LOCAL_STRAIN = 0.03
#: nor is a print whose tiles disagree with one affine map by a quarter of its repeat
MAX_BEYOND_REPEAT = 0.25

#: room kept at each end of the window (mm) for what one advance may do that was not
#: commanded: a slip of up to 3 mm, and a skew of 0.2 degrees turning the far side
ROLL_MARGIN_MM = 5.0
#: how far into the window the last bite's cut is kept after an advance where the next
#: bite leaves room (mm): its kerfs across the shared strip measure the advance where
#: the print cannot (beyond the slip, and the smoothing of the photographs)
CUT_IN_VIEW_MM = 15.0
#: how an advance was measured: from the print, from the last bite's kerfs, or not at
#: all (the commanded advance, reported as not measured)
ADVANCE_SOURCES = ("print", "cut edges", "commanded")


def plan_job_bites(layout: Layout, window: TableWindow, lattice: np.ndarray | None
                   ) -> BitePlan:
    """The bites of ``layout`` on this table; ``lattice`` (2, 2 columns, mm) of the print
    the pieces were placed on (None: plain cloth). Each bite keeps ``ROLL_MARGIN_MM`` of
    the window free at both ends, so that one advance's error cannot push a piece off.
    The first bite is cut where the marker was planned (`RollTrack`), and a marker on a
    print may begin up to a repeat into the window: every bite is shorter by that lead,
    so that the first still ends ``ROLL_MARGIN_MM`` before the window does and the first
    advance, from there, leaves ``MIN_OVERLAP_MM`` of cloth in view."""
    usable = window.length - 2 * ROLL_MARGIN_MM
    first = min(float(p.outline[:, 0].min()) for p in layout.pieces) - float(layout.gap)
    bite_mm = usable - max(0.0, first - ROLL_MARGIN_MM)
    return plan_bites(layout, bite_mm, lattice=lattice,
                      max_advance_mm=bite_mm - MIN_OVERLAP_MM)


@dataclass
class RollTrack:
    """Where the marker lies on the table window: ``marker_to_window`` maps marker mm to
    window mm (x along the roll from the window's start), composed of every advance. At
    the first bite the marker lies where it was planned (the identity): it was aligned on
    the print photographed there, and a shift would move every piece off its print."""

    marker_to_window: np.ndarray = field(default_factory=lambda: np.array(
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]))
    advances: list[Advance] = field(default_factory=list)
    #: per piece of the bite on the table, window mm -> window mm: the local map of the
    #: print under it (`localise`); a piece without one is cut where the track says
    piece_maps: dict[str, np.ndarray] = field(default_factory=dict)
    #: per piece mapped, what its local map did (the report's ``local_maps``)
    local: list[dict[str, Any]] = field(default_factory=list)

    def advance_for(self, bite: Bite, plan: BitePlan | None = None) -> float:
        """The advance to command so that ``bite`` begins ``ROLL_MARGIN_MM`` into the
        window: the planned one corrected by every slip measured so far. Given its
        ``plan``, as much shorter as keeps `CUT_IN_VIEW_MM` of the previous bite's cut in
        view, while the bite still ends ``ROLL_MARGIN_MM`` before the window does and the
        next advance still leaves `MIN_OVERLAP_MM` of cloth in view."""
        start, end = self.window_points(np.array([[bite.start_mm, 0.0],
                                                  [bite.end_mm, 0.0]]))[:, 0]
        planned = float(start - ROLL_MARGIN_MM)
        if plan is None or bite.index == 0:
            return planned
        window = plan.window_mm + 2 * ROLL_MARGIN_MM  # the photograph's length, at least
        cut_end = self.window_points(np.array([[plan.bites[bite.index - 1].end_mm, 0.0]]))
        wanted = planned - (float(cut_end[0, 0]) - CUT_IN_VIEW_MM)
        room = window - 2 * ROLL_MARGIN_MM - (end - start)
        if bite.index + 1 < len(plan.bites):
            room = min(room, window - MIN_OVERLAP_MM
                       - (plan.bites[bite.index + 1].start_mm - bite.start_mm))
        return planned - float(np.clip(wanted, 0.0, max(room, 0.0)))

    def follow(self, advance: Advance, photo_origin_mm: tuple[float, float] = (0.0, 0.0)
               ) -> RollTrack:
        """The track after ``advance``, measured on photographs whose first pixel centre
        lies at ``photo_origin_mm`` in window mm. The advance maps a point of the new
        photograph onto the old one; the cloth (and the marker on it) moves the other way."""
        theta = np.radians(advance.skew_deg)
        c, s = np.cos(theta), np.sin(theta)
        rot = np.array([[c, -s], [s, c]])
        pivot = np.asarray(advance.pivot_mm, float) + np.asarray(photo_origin_mm, float)
        shift = np.array([advance.advance_mm, advance.across_mm])
        back = np.column_stack([rot.T, pivot - rot.T @ (pivot + shift)])  # new <- old
        return RollTrack(compose(back, self.marker_to_window), [*self.advances, advance])

    def window_points(self, marker_points: np.ndarray) -> np.ndarray:
        """(n, 2) window mm of (n, 2) marker points."""
        pts = np.asarray(marker_points, float).reshape(-1, 2)
        return pts @ self.marker_to_window[:, :2].T + self.marker_to_window[:, 2]

    def bite_layout(self, plan: BitePlan, bite: Bite) -> Layout:
        """The pieces of ``bite`` where they now lie in the window (the marker's other
        pieces left out), ready for `station.steps.program.machine_layout`."""
        wanted = set(bite.pieces)
        pieces = [moved_piece(p, compose(self.piece_maps.get(p.id, IDENTITY),
                                         self.marker_to_window))
                  for p in plan.layout.pieces if p.id in wanted]
        return replace(plan.layout, pieces=pieces, pairs=[],
                       length=plan.window_mm + 2 * ROLL_MARGIN_MM,
                       phase_mm=0.0)  # the window's own layout starts at the window


def localise(track: RollTrack, bite: Bite, photograph: np.ndarray, *, plan: BitePlan,
             reference: PrintReference, mm_per_px: float = 1.0,
             follow: str = "affine") -> RollTrack:
    """``track`` with a local map of the print under each piece of ``bite``, measured on
    ``photograph`` (the window with the bite on it) against ``reference`` (the print as
    planned). ``follow`` (`[roll] follow_print`): "affine" cuts the piece stretched and
    sheared with the print (up to `MAX_LOCAL_STRAIN`): a roll's bow, skew and stretch are
    the cloth's own (weft bow, tension on the table), so the piece follows the yarns and
    is true, its seams as long as their twins, once the cloth lies relaxed. "rigid" only
    turns and moves each piece onto the print, for a print misregistered on straight
    cloth, and names what that leaves of the print's stretch and shear. All tiles of all
    pieces are measured at once."""
    if follow not in FOLLOW_PRINT:
        raise ValueError(f"follow must be one of {', '.join(FOLLOW_PRINT)}, not {follow!r}")
    wanted = set(bite.pieces)
    pieces = [p for p in plan.layout.pieces if p.id in wanted]
    if not pieces:
        return track
    centres, owner = [], []
    for k, p in enumerate(pieces):
        outline = affine(track.marker_to_window, p.outline)
        c = tile_centres(np.array([outline.min(axis=0), outline.max(axis=0)]),
                         photograph.shape[:2], mm_per_px=mm_per_px)
        centres.append(c)
        owner.append(np.full(len(c), k))
    centres_px, owner = np.concatenate(centres), np.concatenate(owner)
    shifts = local_shifts(photograph, reference, invert(track.marker_to_window), centres_px,
                          mm_per_px=mm_per_px)
    maps, notes = {}, []
    repeat = float(np.hypot(*reference.basis).min())
    for k, p in enumerate(pieces):
        local = fit_local_map(centres_px[owner == k] * mm_per_px, shifts[owner == k])
        kept = (local.tiles >= 3 and local.strain <= MAX_LOCAL_STRAIN
                and local.beyond_mm <= MAX_BEYOND_REPEAT * repeat)
        points, weights = sew_points(p, track.marker_to_window)
        rigid, residual = nearest_rigid(local.correction, points, weights)
        left_mm = float(residual.max())  # what the rigid map leaves of the affine one
        chosen = rigid if follow == "rigid" else local.correction
        if kept:  # else the print was not found under the piece: cut where the track says
            maps[p.id] = chosen
        notes.append({"piece": p.id, "bite": bite.index, "follow": follow,
                      **_map_note(local, chosen if kept else None, points, weights,
                                  left_mm if follow == "rigid" else 0.0),
                      "rigid_residual_mm": round(left_mm, 3)})
    return replace(track, piece_maps=maps, local=notes)


def sew_points(piece: Placed, marker_to_window: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """((n, 2) window mm, (n,) weights): the vertices of ``piece``'s sew line (where its
    seams meet; its cut line when it has none), each weighted by the length of sew line
    it stands for (half of each edge beside it), so that a densely drawn curve does not
    outweigh a long straight seam."""
    ring = affine(marker_to_window, piece.outline if piece.sew_line is None
                  else piece.sew_line)
    edge = np.hypot(*(np.roll(ring, -1, axis=0) - ring).T)
    return ring, 0.5 * (edge + np.roll(edge, 1))


def _map_note(local: LocalMap, chosen: np.ndarray | None, points: np.ndarray,
              weights: np.ndarray, rigid_residual_mm: float) -> dict[str, Any]:
    """The report's figures of one piece's map: how far the map ``chosen`` (None: refused)
    moves the piece's sew-line centre, the print's strain and departure from one affine
    map under it, and the seam error expected (at most the departure plus what a rigid
    placement leaves of the map, ``rigid_residual_mm``, 0 when the piece follows it)."""
    centre = weights @ points / weights.sum()
    moved = 0.0 if chosen is None else float(np.hypot(*(affine(chosen, centre)[0] - centre)))
    expected = None if chosen is None else local.beyond_mm + rigid_residual_mm
    return {"tiles": local.tiles, "moved_mm": round(moved, 3),
            "strain": round(local.strain, 5), "beyond_affine_mm": round(local.beyond_mm, 3),
            "mapped": chosen is not None,
            "seam_error_expected_mm": None if expected is None else round(expected, 3),
            "distorted": expected is None or expected > LOCAL_MAP_TOLERANCE_MM}


#: what the job waits at when the operator advances the roll by hand (`station resume`
#: goes on); the conveyor of a machine profile is commanded instead where there is one
OPERATOR_ADVANCE = "advance the fabric {mm:.1f} mm"
_ASKED = re.compile(r"^advance the fabric (-?[0-9]+(?:\.[0-9]+)?) mm")


def operator_advance_mm(reason: str) -> float | None:
    """The mm a job paused at `OPERATOR_ADVANCE` asks for (None: it waits for something
    else)."""
    asked = _ASKED.match(reason or "")
    return float(asked.group(1)) if asked else None


@dataclass
class BiteStep:
    """One bite found on the table: the track after it, the bite with its measured
    advance and skew (None for the first, or where not measured), the photograph the
    next advance compares to, the window photographed again once the bite was cut (its
    kerfs; None until then), and how the advance was measured (`ADVANCE_SOURCES`, None
    for the first bite) with the components the photographs could not measure."""

    track: RollTrack
    bite: Bite
    photograph: np.ndarray
    cut_photograph: np.ndarray | None = None
    source: str | None = None
    unmeasured: tuple[str, ...] = ()

    def how(self) -> dict[str, Any]:
        """The report's words on how this bite's advance was measured."""
        return {"advance_source": self.source, "advance_unmeasured": list(self.unmeasured)}


def find_bite(previous: BiteStep | None, bite: Bite, *, advance: Callable[[float], None],
              photograph: Callable[[], np.ndarray], lattice: np.ndarray | None,
              mm_per_px: float = 1.0, plan: BitePlan | None = None) -> BiteStep:
    """Bring ``bite`` onto the table: command the advance the track asks for (the planned
    one corrected by the slips so far; given the ``plan``, keeping the last cut in view
    where it can) through ``advance``, photograph the window, and measure what the roll
    really did (`measure_bite_advance`). The first bite (``previous`` None) is only
    photographed: the marker lies where it was planned."""
    if previous is None:
        return BiteStep(RollTrack(), bite, photograph())
    commanded = previous.track.advance_for(bite, plan)
    advance(commanded)
    after = photograph()
    measured, source = measure_bite_advance(previous, after, commanded_mm=commanded,
                                            lattice=lattice, mm_per_px=mm_per_px)
    bite = replace(bite, advance_commanded_mm=commanded,
                   advance_measured_mm=measured.advance_mm if measured.along_measured
                   else None,
                   skew_deg=None if "skew" in measured.unmeasured else measured.skew_deg)
    return BiteStep(previous.track.follow(measured), bite, after, source=source,
                    unmeasured=measured.unmeasured)


def measure_bite_advance(previous: BiteStep, after: np.ndarray, *, commanded_mm: float,
                         lattice: np.ndarray | None, mm_per_px: float = 1.0
                         ) -> tuple[Advance, str]:
    """The roll's motion from the previous bite's photograph to ``after``, and how it was
    measured (`ADVANCE_SOURCES`): from the print; where the print says nothing along the
    roll, from the kerfs of the previous bite (its photograph after the cut) across the
    shared strip; where neither does, the commanded advance, the print's drift and skew
    kept where it measured them."""
    by_print = measure_advance(previous.photograph, after, commanded_mm=commanded_mm,
                               mm_per_px=mm_per_px, lattice=lattice)
    if by_print.along_measured:
        return by_print, "print"
    if previous.cut_photograph is not None:
        by_cut = measure_advance(previous.cut_photograph, after, commanded_mm=commanded_mm,
                                 mm_per_px=mm_per_px, lattice=lattice)
        if by_cut.along_measured:
            return by_cut, "cut edges"
    return by_print, "commanded"


def bites_report(bites: list[Bite], how: dict[int, dict[str, Any]] | None = None
                 ) -> list[dict[str, Any]]:
    """The report's ``summary.bites``: per bite the commanded and measured advance, the
    skew and the pieces it cut; with ``how`` (`BiteStep.how` by bite index), how each
    advance was measured (None: no advance, the first bite)."""
    rows = [b.to_dict() for b in bites]
    if how is not None:
        for row in rows:
            row.update(how.get(row["index"], {"advance_source": None,
                                              "advance_unmeasured": []}))
    return rows


def save_bites(plan: BitePlan, path: Path) -> None:
    """bites.json: the window and each bite as planned (its layout is layout.json)."""
    path.write_text(json.dumps({"window_mm": plan.window_mm,
                                "length_unbounded_mm": plan.length_unbounded_mm,
                                "method": plan.method,
                                "bites": bites_report(plan.bites)}, indent=1))


def load_bites(layout: Layout, path: Path) -> BitePlan:
    """The plan `save_bites` wrote, on ``layout`` (its layout.json, read by the caller)."""
    data = json.loads(Path(path).read_text())
    bites = [Bite(int(b["index"]), float(b["start_mm"]), float(b["end_mm"]),
                  tuple(str(p) for p in b["pieces"]), float(b["advance_commanded_mm"]))
             for b in data["bites"]]
    known = {p.id for p in layout.pieces}
    strays = sorted({p for b in bites for p in b.pieces} - known)
    if strays:
        raise ValueError(f"{path}: bites name pieces not in the layout: {strays[:3]}")
    return BitePlan(layout, bites, float(data["window_mm"]),
                    float(data["length_unbounded_mm"]), method=str(data["method"]))
