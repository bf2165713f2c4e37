"""A marker longer than the table, cut in bites: the pieces moved off the bite boundaries.

A cutting table sees one window of the roll at a time; the conveyor advances the roll and
the next bite is cut. No piece may straddle a boundary between two bites (half of it
would be cut before the advance, half after, with the slip of the conveyor in between),
so :func:`plan_bites` walks the nested marker from its start, and at each window's end
chooses the boundary that costs the least length: the pieces before it stay, the rest of
the marker moves on, as one block, just far enough to clear the boundary by the gap on
each side. On a print the move is a whole lattice vector (the pieces stay on the print
they were aligned to; the pairs stay pairs), so it may also move the block across the
roll within the fabric's width. What the boundaries cost is the marker's length with
them against the nest's own length without them.

:func:`nest_in_bites` also lets the nest itself know the boundaries: thin keep-out
strips across the roll at every window's end, so that the search packs around them, and
keeps whichever of the two markers is shorter (neither wins everywhere: moving blocks
costs about half a piece per boundary, fencing costs the search's freedom).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import shapely

from solver.nest.bitepull import pull_back
from solver.nest.budget import Deadline, deadline_of
from solver.nest.instance import NestProblem, affine, compose
from solver.nest.layout import Layout, Placed
from solver.nest.solve import nest

#: mm of window left unused at a bite's end that weigh as one mm of fabric when choosing
#: a boundary: a bite fewer saves an advance and a registration, fabric is dearer
UNUSED_WINDOW_WEIGHT = 0.1
#: half the width of a fence between bites, as a fraction of the window (the gap to the
#: pieces on either side comes on top of it)
FENCE_HALF_WIDTH = 1e-4


@dataclass(frozen=True)
class Bite:
    """The part of the marker cut between two advances of the roll (marker mm, x along
    the roll): the window ``[start_mm, start_mm + window]`` holds ``pieces`` (their ids),
    which end at ``end_mm`` (the next bite's pieces begin beyond it, by the gap).
    ``advance_commanded_mm`` moves the roll from the previous bite's start to this one's;
    the measured advance and skew are filled in on the table (None until then)."""

    index: int
    start_mm: float
    end_mm: float
    pieces: tuple[str, ...]
    advance_commanded_mm: float
    advance_measured_mm: float | None = None
    skew_deg: float | None = None

    def measured(self, advance_mm: float, skew_deg: float) -> Bite:
        """This bite with the advance and skew measured on the print after the advance."""
        return replace(self, advance_measured_mm=float(advance_mm), skew_deg=float(skew_deg))

    def to_dict(self) -> dict[str, Any]:
        """The report's row of this bite (issue 35's ``summary.bites``)."""
        rounded = lambda v, n: None if v is None else round(float(v), n)  # noqa: E731
        return {"index": self.index, "start_mm": round(self.start_mm, 3),
                "end_mm": round(self.end_mm, 3), "pieces": list(self.pieces),
                "advance_commanded_mm": round(self.advance_commanded_mm, 3),
                "advance_measured_mm": rounded(self.advance_measured_mm, 3),
                "skew_deg": rounded(self.skew_deg, 4)}


@dataclass
class BitePlan:
    """The marker with its pieces moved off the boundaries, cut as ``bites`` in order."""

    layout: Layout
    bites: list[Bite]
    window_mm: float
    length_unbounded_mm: float  # the nest's marker, with no boundaries
    # (2,) the block move at each boundary (before its pieces were pulled back)
    shifts: list[np.ndarray] = field(default_factory=list)
    # how the boundaries were paid: "moved" (blocks moved on), "pulled" (and their pieces
    # pulled back) or "fenced" (the nest knew them), and the length the other way (moved
    # or pulled against fenced) gave (None: not tried, or no marker)
    method: str = "moved"
    other_length_mm: float | None = None

    @property
    def boundary_cost_mm(self) -> float:
        """Length the boundaries added to the marker."""
        return float(self.layout.length - self.length_unbounded_mm)

    def bite_of(self) -> dict[str, int]:
        """Each piece's bite index, by piece id."""
        return {pid: b.index for b in self.bites for pid in b.pieces}

    def summary(self) -> dict[str, Any]:
        return {"window_mm": self.window_mm, "bites": len(self.bites), "method": self.method,
                "length_mm": round(self.layout.length, 3),
                "length_unbounded_mm": round(self.length_unbounded_mm, 3),
                "boundary_cost_mm": round(self.boundary_cost_mm, 3),
                "boundary_cost_pct": round(100 * self.boundary_cost_mm
                                           / self.length_unbounded_mm, 3)}


def plan_bites(layout: Layout, window_mm: float, *, lattice: np.ndarray | None = None,
               max_advance_mm: float | None = None, pull: bool = False) -> BitePlan:
    """Cut ``layout`` into bites of at most ``window_mm`` along the roll.

    ``lattice``: (2, 2) columns, the print's lattice vectors (fabric mm) that a block of
    pieces may move by; None on plain cloth (any move along the roll).
    ``max_advance_mm``: the longest advance between two bites (default the window; the
    station keeps a strip of cloth in view across each advance to find the print again),
    so a bite may begin before the previous one's pieces end, or hold no piece at all.
    ``pull``: after each block move, slide the block's pieces back into the hole it left
    (`solver.nest.bitepull`; shorter on some markers, longer on others: the boundaries
    after it fall elsewhere).
    Raises ValueError, naming the piece, for one longer than a bite can hold."""
    max_advance = window_mm if max_advance_mm is None else float(max_advance_mm)
    if not 0 < max_advance <= window_mm:
        raise ValueError(f"the longest advance must be within the {window_mm:g} mm window, "
                         f"got {max_advance:g} mm")
    gap = float(layout.gap)
    polygons = [p.polygon() for p in layout.pieces]
    base = shapely.bounds(np.array(polygons, dtype=object))  # (n, 4) x0 y0 x1 y1
    lo, y_lo, hi, y_hi = base.T.copy()
    room = window_mm - 2 * gap
    too_long = np.flatnonzero(hi - lo > room + 1e-9)
    if len(too_long):
        p = layout.pieces[int(too_long[0])]
        raise ValueError(f"piece {p.id!r} is {hi[too_long[0]] - lo[too_long[0]]:.1f} mm along "
                         f"the roll; a bite of the table's {window_mm:g} mm window holds "
                         f"{room:g} mm between its gaps")
    tail = float(layout.length - hi.max())  # the marker's end after its last piece
    offsets = np.zeros((len(polygons), 2))  # each piece's move so far
    bite_of = np.full(len(lo), -1)
    starts, shifts = [], []
    start = float(lo.min()) - gap
    while True:
        starts.append(start)
        left = bite_of < 0
        if hi[left].max() <= start + window_mm - gap + 1e-9:  # the rest fits: last bite
            bite_of[left] = len(starts) - 1
            break
        if hi[left].min() > start + window_mm - gap + 1e-9:  # none ends in view: roll on
            start = min(float(lo[left].min()) - gap, start + max_advance)
            continue
        kept, shift = _cheapest_boundary(lo, hi, y_lo, y_hi, left, start, window_mm, gap,
                                         layout.width, lattice)
        bite_of[kept] = len(starts) - 1
        rest = bite_of < 0
        offsets[rest] += shift
        if pull:
            pull_back(polygons, offsets, rest, float(hi[kept].max()) + gap, gap,
                      layout.width, lattice)
        lo, y_lo, hi, y_hi = (base + np.tile(offsets, 2)).T
        shifts.append(shift)
        start = min(float(lo[rest].min()) - gap, start + max_advance)
    moved = _moved_layout(layout, offsets, float(hi.max()) + tail)
    ends = [float(hi[bite_of == k].max()) + gap if np.any(bite_of == k) else starts[k]
            for k in range(len(starts))]  # after the bite's last piece (its boundary)
    bites = [Bite(k, starts[k], ends[k],
                  tuple(moved.pieces[i].id for i in np.flatnonzero(bite_of == k)),
                  starts[k] - (starts[k - 1] if k else starts[0]))
             for k in range(len(starts))]
    return BitePlan(moved, bites, float(window_mm), float(layout.length), shifts)


def nest_in_bites(problem: NestProblem, window_mm: float, *,
                  time_limit: float | Deadline = 30.0, seed: int | None = 0) -> BitePlan:
    """The shortest marker of ``problem`` (any length) cut in bites of ``window_mm``: the
    free nest with its blocks moved off the boundaries (their pieces pulled back or not),
    or a nest fenced at the boundaries, whichever is shorter; the cost is reported
    against the free nest."""
    if problem.length is not None:
        raise ValueError("a marker cut in bites has no length limit; the window is the bite")
    deadline = deadline_of(time_limit)
    lattice = problem.lattice
    free = nest(problem, time_limit=deadline.share(0.5), seed=seed)
    best = min((replace(plan_bites(free, window_mm, lattice=lattice, pull=pull),
                        method="pulled" if pull else "moved") for pull in (False, True)),
               key=lambda plan: plan.layout.length)
    try:
        fenced = fenced_nest(problem, window_mm, free.length, time_limit=deadline, seed=seed)
    except ValueError:  # the fences left no room the search could find: keep the free one
        return best
    candidate = replace(plan_bites(fenced, window_mm, lattice=lattice), method="fenced",
                        length_unbounded_mm=float(free.length))
    if candidate.layout.length < best.layout.length:
        return replace(candidate, other_length_mm=float(best.layout.length))
    return replace(best, other_length_mm=float(candidate.layout.length))


def fenced_nest(problem: NestProblem, window_mm: float, expected_mm: float, *,
                time_limit: float | Deadline = 30.0, seed: int | None = 0) -> Layout:
    """``problem`` nested around thin keep-out fences at every ``window_mm`` along the roll
    (far enough for a marker twice ``expected_mm``), the fences then dropped from it."""
    count = int(np.ceil(2.0 * expected_mm / window_mm)) + 2
    eps = FENCE_HALF_WIDTH * window_mm
    fences = [np.array([[x - eps, 0.0], [x + eps, 0.0], [x + eps, problem.width],
                        [x - eps, problem.width]])
              for x in window_mm * np.arange(1, count + 1)]
    fenced = nest(replace(problem, keepouts=[*problem.keepouts, *fences]),
                  time_limit=time_limit, seed=seed)
    return replace(fenced, keepouts=list(problem.keepouts))


def _cheapest_boundary(lo, hi, y_lo, y_hi, left, start, window_mm, gap, width, lattice):
    """(the pieces kept in this bite (bool mask), the (2,) move of the rest): among the
    boundaries after each piece that fits the window, the one that adds the least length
    (and, at equal length, leaves the least window unused)."""
    order = np.flatnonzero(left)[np.argsort(hi[left], kind="stable")]
    ends = hi[order]
    fits = ends <= start + window_mm - gap + 1e-9
    best: tuple[float, np.ndarray, np.ndarray] | None = None
    for n in np.flatnonzero(fits) + 1:  # keep the first n pieces by their end
        if n < len(ends) and ends[n - 1] == ends[n]:
            continue  # a boundary is after all pieces ending there, never between them
        kept = np.zeros(len(lo), bool)
        kept[order[:n]] = True
        rest = left & ~kept
        boundary = float(ends[n - 1]) + gap
        need = boundary + gap - float(lo[rest].min())
        shift = _block_move(need, gap - float(y_lo[rest].min()),
                            width - gap - float(y_hi[rest].max()), lattice)
        if shift is None:
            continue
        score = shift[0] + UNUSED_WINDOW_WEIGHT * (start + window_mm - boundary)
        if best is None or score < best[0] - 1e-9:
            best = (score, kept, shift)
    if best is None:
        raise ValueError("no bite boundary keeps the pieces on the print and inside the "
                         f"fabric's {width:g} mm width")
    return best[1], best[2]


def _block_move(need: float, dy_min: float, dy_max: float, lattice: np.ndarray | None
                ) -> np.ndarray | None:
    """The shortest move along the roll of at least ``need`` mm (0 if ``need`` <= 0) that
    keeps the block across the roll within ``[dy_min, dy_max]``: on a print, a whole lattice
    vector; None where no lattice vector does."""
    need = max(need, 0.0)
    if lattice is None:
        return np.array([need, 0.0])
    reach = need + 2.0 * float(np.hypot(*lattice).sum())
    corners = np.array([[need, reach, need, reach], [dy_min, dy_min, dy_max, dy_max]])
    frac = np.linalg.solve(lattice, corners)  # the box of moves, in lattice coordinates
    a, b = (g.ravel() for g in np.meshgrid(
        *(np.arange(np.floor(f.min()), np.ceil(f.max()) + 1) for f in frac)))
    v = lattice @ np.vstack([a, b])  # (2, m) candidate moves
    ok = (v[0] >= need - 1e-9) & (v[1] >= dy_min - 1e-9) & (v[1] <= dy_max + 1e-9)
    if not ok.any():
        return None
    cand = v[:, ok]
    i = np.lexsort((np.abs(cand[1]), cand[0]))[0]  # shortest along, then least across
    return cand[:, i].astype(float)


def _moved_layout(layout: Layout, offsets: np.ndarray, length: float) -> Layout:
    """A copy of ``layout`` with each piece moved by its row of ``offsets``, ``length``
    long."""
    pieces = [_translated(p, d) if np.any(d) else p for p, d in zip(layout.pieces, offsets)]
    return replace(layout, pieces=pieces, length=float(length))


def moved_piece(p: Placed, m: np.ndarray) -> Placed:
    """``p`` carried by the rigid map ``m`` ((2, 3), fabric mm): outline, holes, notches,
    marks, grain line and sew line, and its transform composed with ``m``."""
    m = np.asarray(m, float)
    lin = m[:, :2]
    move = lambda a: affine(m, a)  # noqa: E731
    return replace(
        p, transform=compose(m, p.transform), outline=move(p.outline),
        holes=[move(h) for h in p.holes],
        notches=[(move(a)[0], lin @ np.asarray(d, float), depth) for a, d, depth in p.notches],
        marks=move(p.marks), grainline=None if p.grainline is None else move(p.grainline),
        sew_line=None if p.sew_line is None else move(p.sew_line))


def _translated(p: Placed, d: np.ndarray) -> Placed:
    return moved_piece(p, np.column_stack([np.eye(2), d]))
