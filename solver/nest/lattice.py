"""Print-aware nesting: every piece moves only by symmetries of the print.

On a printed fabric a piece aligned to the print may still move by any whole lattice
vector and by any operation of the print's group that keeps the grain (see
:func:`solver.nest.instance.candidate_maps`); the positions of one piece therefore form
a few *cosets* of the lattice. Several searches compete (see :func:`nest_lattice`):

- the bottom-left fill of :mod:`solver.nest.engine` reads its FFT collision maps only at
  each piece's lattice coset, with restarts (:mod:`solver.nest.fill`) and compaction;
- a free sparrow nest is snapped to the lattice and swept left to right onto the
  nearest allowed positions ("resnap", :mod:`solver.nest.regions`), or jointly onto
  allowed positions around the free ones that do not collide ("joint",
  :mod:`solver.nest.snapjoint`);
- the exact dotted-board model on every allowed position (:mod:`solver.nest.dotted`,
  CP-SAT), hinted with the best marker so far, on inputs small enough to build it;
- the best of those is shortened by strip shrinking on the cosets (:mod:`solver.nest.coset`).
The shortest marker wins.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from solver.nest.budget import Deadline, Progress, deadline_of
from solver.nest.coset import coset_search
from solver.nest.dotted import MAX_OPTIONS, dotted_nest, phase_period
from solver.nest.dotted_options import positions
from solver.nest.fill import fill_search, first_fill_estimate, problem_density
from solver.nest.instance import NestProblem, marker_span
from solver.nest.layout import Layout, build_layout
from solver.nest.naive import naive_moves
from solver.nest.regions import repair_snapped
from solver.nest.snapjoint import joint_search
from solver.wallpaper import covering_radius

SHARES = {"naive": 0.2, "resnap": 0.6, "resnap-margin": 0.6, "repair": 0.6, "fill": 0.4,
          "coset": 0.3, "joint": 0.6, "dotted": 0.8}
# free to start at any phase, only the dotted model chooses it, and its depth-first pass
# needs no good hint, only a marker to bound the length: a quick fill gives one, the
# model gets most of the time, and the joint snap (sparrow) what it leaves. The t-shirt's
# p1 under 5 s at load 7: after the joint snap and the fill, 1.2-2.7 s were left to it,
# too little to solve after a 0.6-0.8 s build
PHASE_SHARES = SHARES | {"dotted": 2.0, "fill": 0.2}
# s: importing OR-tools (0.4-0.6 s the first time), the build and the presolve take about
# that before CP-SAT reads the hint; with less the model only costs time
DOTTED_MIN = 1.0
LIKELY = 0.6  # printed density for the dotted model's size estimate (Berkeley: 0.45-0.70)
MANY = 30  # pieces from which a free nest is resnapped without margin


def nest_lattice(problem: NestProblem, *, time_limit: float | Deadline = 30.0, seed: int | None = 0,
                 progress: Progress | None = None,
                 strategies: tuple[str, ...] | None = None, any_phase: bool = False) -> Layout:
    """Nest on a printed fabric; every strategy runs and the shortest marker wins.

    ``any_phase``: the marker may start at any phase of the print along the roll (a roll
    is cut wherever its print lies): markers are compared by their span, the dotted
    model chooses the phase, and the layout's ``phase_mm`` says where the marker starts
    on the print as found (its pieces lie where they are cut). Only with a lattice
    vector along the roll (:func:`solver.nest.dotted.phase_period`); else the found
    phase is kept.

    - ``resnap``: sparrow nests freely, then every piece is swept left to right onto the
      allowed position nearest to its free one (pushed right where it collides), then
      compacted; keeps sparrow's structure, loses little on fine lattices.
    - ``resnap-margin``: the same from a free nest with half the covering radius of
      margin, so fewer and smaller collisions after snapping (better for few big pieces).
    - ``repair``: the same, but only the pieces in conflict after snapping move.
    - ``fill``: lattice-coset bottom-left greedy fill from scratch with restarts; wins on
      coarse lattices relative to the pieces.
    - ``joint``: a free nest with a quarter of the covering radius of margin (none from
      ``MANY`` pieces) snapped both by the sweep and jointly, each piece to one of the
      allowed positions around its free one, none colliding, the shortest such choice
      (:mod:`solver.nest.snapjoint`); sparrow's earlier, looser nests are snapped
      jointly too while time remains (one of them often snaps shorter).
    - ``dotted``: the dotted-board model (:mod:`solver.nest.dotted`) on every allowed
      position up to the best marker so far, which it starts from; CP-SAT finds shorter
      markers and may prove the shortest (then nothing is left to shrink). Steps aside
      without an earlier marker, with less than ``DOTTED_MIN`` s, or beyond
      ``MAX_OPTIONS`` positions.
    - ``coset``: shrinks the best marker so far with sparrow's strip shrinking on the
      lattice cosets (:mod:`solver.nest.coset`); from a snapped free nest if it runs alone.

    By default: joint, fill, dotted (when the pieces have at most ``MAX_OPTIONS`` allowed
    positions on a marker of density ``LIKELY``), then coset on the best of them. When the
    time left is shorter than a whole fill would take, the naive baseline (:mod:`solver.nest.naive`)
    gives the first marker, then the fill (cut at the deadline, it shelves the pieces
    left: on many small pieces that beats the naive marker, 67.5 % against 59 % on the
    shirts under a 0.5 p1 print) and coset on the better one.
    """
    if problem.fabric is None:
        raise ValueError("print-aware nesting needs a fabric (FABRIC.json)")
    items = problem.items()
    deadline = deadline_of(time_limit)
    run = _Run(problem, items, seed, progress,
               any_phase=any_phase and phase_period(problem.lattice) is not None)
    if strategies is None:
        strategies = _default_strategies(problem, items, deadline, run.any_phase)
    for i, strategy in enumerate(strategies):
        if strategy not in _STRATEGIES:
            raise ValueError(f"unknown nesting strategy {strategy!r}")
        # a share of what is left, so an overrun shrinks the later strategies; once one
        # marker exists the others may be cut short by the deadline
        shares = PHASE_SHARES if run.any_phase else SHARES
        rest = sum(shares.get(s, 0.0) for s in strategies[i:]) or 1.0
        share = deadline.share(shares.get(strategy, 0.0) / rest)
        r = _STRATEGIES[strategy](run, strategy, share, bool(run.results))
        if r is not None:
            r = run.measured(r)
            if progress:
                progress(f"{strategy}: length {r[1]:.4g}  "
                         f"density {problem_density(items, problem, r[1]):.1%}")
            run.results.append(r)
    if not run.results:
        raise ValueError(f"the pieces do not fit on the fabric ({problem.width:g} x "
                         f"{problem.length:g} mm)" if problem.length else "nesting failed")
    layout = build_layout(problem, items, run.best()[0])
    if run.any_phase:
        start = min(float(p.outline[:, 0].min()) for p in layout.pieces) - problem.gap
        layout.phase_mm = max(0.0, start)
    return layout


def _default_strategies(problem: NestProblem, items: list, deadline: Deadline,
                        any_phase: bool = False) -> tuple[str, ...]:
    """Joint, fill, dotted (if the model is small enough), coset; naive first when not
    even a whole fill fits the time. Free of phase: fill, dotted, joint, coset, when the
    quick fill's small share still holds a whole fill (else, under a short budget or a
    loaded machine, no strategy would finish a marker: the found-phase order)."""
    small = positions(problem, items, problem.piece_area / (problem.width * LIKELY))
    strategies = ("joint", "fill", "dotted", "coset") if small <= MAX_OPTIONS else (
        "joint", "fill", "coset")
    if any_phase and small <= MAX_OPTIONS:  # see PHASE_SHARES
        phase_order = ("fill", "dotted", "joint", "coset")
        fill_time = deadline.left() * PHASE_SHARES["fill"] / sum(
            PHASE_SHARES[s] for s in phase_order)
        if 2 * first_fill_estimate(items) <= fill_time:  # 2: the estimate's spread
            return phase_order
    first = deadline.left() * SHARES[strategies[0]] / (SHARES[strategies[0]] + SHARES["fill"])
    if 2 * first_fill_estimate(items) > first:  # 2: the estimate's spread under load
        # too short for a whole fill: the naive marker is certain and quick, a fill
        # cut short and shelved may beat it, strip shrinking improves the better one
        return ("naive", "fill", "coset")
    return strategies


Moves = tuple[list[np.ndarray], float]  # a marker: every item's move, and its length (mm)


@dataclass
class _Run:
    """One :func:`nest_lattice` call: its inputs and the markers its strategies gave."""

    problem: NestProblem
    items: list
    seed: int | None
    progress: Progress | None
    results: list[Moves] = field(default_factory=list)
    proven: bool = False  # the dotted model proved the best marker shortest
    any_phase: bool = False  # markers compared by their span (free to start at any phase)

    def best(self) -> Moves:
        return min(self.results, key=lambda r: r[1])

    def measured(self, marker: Moves) -> Moves:
        """``marker`` with the length this run compares: any phase, its span."""
        if not self.any_phase:
            return marker
        return marker[0], marker_span(self.items, marker[0], self.problem.gap)

    def say(self, line: str) -> None:
        if self.progress:
            self.progress(line)


def _naive(run: _Run, name: str, share: Deadline, late: bool) -> Moves | None:
    try:
        return naive_moves(run.problem, run.items, time_limit=share, seed=run.seed,
                           progress=run.progress, interruptible=late)
    except ValueError as exc:  # a piece too wide with the margin: the others may do
        run.say(f"naive: {exc}")
        return None


def _fill(run: _Run, name: str, share: Deadline, late: bool) -> Moves | None:
    return fill_search(run.problem, run.items, time_limit=share, seed=run.seed,
                       progress=run.progress, interruptible=late)


def _resnap(run: _Run, name: str, share: Deadline, late: bool) -> Moves | None:
    extra = 0.5 * covering_radius(run.problem.lattice) if name == "resnap-margin" else 0.0
    try:
        return repair_snapped(run.problem, run.items, time_limit=share, seed=run.seed,
                              progress=run.progress, everything=name != "repair",
                              extra=extra, interruptible=late)
    except ValueError as exc:  # sparrow gave up; the other strategies may not
        run.say(f"{name}: {exc}")
        return None


def _joint(run: _Run, name: str, share: Deadline, late: bool) -> Moves | None:
    if run.proven:  # free of phase the dotted model ran first and proved its marker
        return None
    # many small pieces lose more to a margin than to collisions after snapping;
    # for few, a quarter of the covering radius leaves the joint snap room (half
    # wastes more than it saves: Berkeley dress, t-shirt, skirt 1-5 points denser)
    extra = 0.0 if len(run.items) >= MANY else 0.25 * covering_radius(run.problem.lattice)
    return joint_search(run.problem, run.items, time_limit=share, seed=run.seed,
                        progress=run.progress, extra=extra, interruptible=late)


def _dotted(run: _Run, name: str, share: Deadline, late: bool) -> Moves | None:
    if not run.results or share.left() < DOTTED_MIN:
        return None
    d = dotted_nest(run.problem, run.items, time_limit=share, progress=run.progress,
                    hint=run.best()[0], max_options=MAX_OPTIONS, any_phase=run.any_phase)
    if d is None or d.moves is None:
        return None
    run.proven = d.optimal
    run.say(f"dotted: bound {d.bound:.4g}{' (optimal)' if run.proven else ''}")
    return d.moves, d.length


def _coset(run: _Run, name: str, share: Deadline, late: bool) -> Moves | None:
    if run.proven:
        return None
    start = run.best()[0] if run.results else None
    return coset_search(run.problem, run.items, time_limit=share, seed=run.seed,
                        progress=run.progress, start=start)


_STRATEGIES = {"naive": _naive, "fill": _fill, "resnap": _resnap, "resnap-margin": _resnap,
               "repair": _resnap, "joint": _joint, "dotted": _dotted, "coset": _coset}
