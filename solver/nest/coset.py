"""Strip shrinking on the lattice cosets: sparrow's search with the print's allowed moves.

A greedy fill or a snapped free nest leaves the marker where its construction stopped.
sparrow (Gardeyn et al. 2025, see :mod:`solver.nest.plain`) goes further by *shrinking
the strip* and then *separating*: pieces may overlap, and a guided local search moves one
colliding piece at a time to the position of least weighted overlap, raising the weight
of pairs that keep colliding, until no overlap is left. We run the same search where a
piece may only stand on its allowed positions (lattice vectors after one of the print's
grain-keeping operations, :func:`solver.nest.instance.candidate_maps`):

- the weighted overlap of one piece with all others, at every allowed position at once,
  is one FFT cross-correlation per operation (the raster engine of
  :mod:`solver.nest.engine`): the others' outlines grown by the gap are stamped into one
  map with their pair weights;
- collisions and their depth are judged exactly (shapely, vectorised over pairs); a
  raster-free position is taken only after the exact check passes, so every accepted
  marker is valid, never only nearly so;
- after each success the strip is shortened again; after a failure the last valid
  marker is restored and a smaller step tried.

Measured (BENCHMARKS.md): it shortens markers of many small pieces and some of few; on a
lattice coarse against the pieces a move is a whole step, so a small overlap is rarely
resolved by one move and the separation of a much shorter strip mostly stalls.
"""

from __future__ import annotations

import math
import time

import numpy as np
import scipy.fft as sfft
import shapely

from solver.nest.budget import Deadline, Pace, Progress, deadline_of
from solver.nest.engine import (
    AREA_TOL,
    Board,
    Filler,
    clear_of,
    exact_batches,
    moves_of,
    stamp,
)
from solver.nest.fill import default_resolution
from solver.nest.instance import Item, NestProblem, affine
from solver.nest.plain import plain_moves
from solver.nest.regions import near_pairs, repair, snap_to_lattice

SHRINK = (0.03, 0.015, 0.007, 0.003)  # strip steps tried in turn, fraction of the length
GROW = 1.5  # weight factor of a pair still colliding after a round of moves (sparrow: 1.2-2)
DECAY = 0.95  # weight factor of a pair that no longer collides
STALL = 10  # rounds without less overlap make a strike (back to the best state)
STRIKES = 3  # strikes before a separation gives up
CONTACT = 8.0  # raster overlap (weighted pixels) told apart when ordering candidates
EXACT_CHECKS = 256  # raster-free candidates checked exactly before taking an overlapping one
# alone (no marker given): strips tried for the snapped free nest, times the free length
GROW_TARGET = (1.04, 1.07, 1.1, 1.15, 1.2, 1.3)
TRIES = 3  # separations tried per strip: one either succeeds fast or stalls
ATTEMPT = 0.15  # of the time left, for one separation
ATTEMPT_MIN = 0.4  # s, at least (a success takes about 0.1 s)
FREE_SHARE = 0.45  # of the time, for sparrow's free nest
# a search's first move also makes the allowed translations of the whole strip and the
# moving piece's spectra: up to 0.21 s on albano at load 10 on 2 cores. No move starts
# with less time left until one was measured
FIRST_MOVE = 0.25


class CosetSearch:
    """Pieces on allowed positions, possibly overlapping, with pair weights (module doc)."""

    def __init__(self, problem: NestProblem, items: list[Item], length: float,
                 res: float, rng: np.random.Generator) -> None:
        self.problem, self.items, self.rng = problem, items, rng
        self.gap = problem.gap
        cap = length + self.gap + 2 * res
        fixed = [shapely.Polygon(k) for k in problem.keepouts]
        self.filler = Filler(items, problem.width, cap, problem.gap, res, fixed)
        self.board = Board(problem.width, cap, problem.gap, res)
        self.rows, self.cols = self.board.rows, self.board.cols
        self.fixed_map = np.zeros((self.rows, self.cols), np.float32)
        for poly in fixed:
            x0, y0, img = self.board.footprint(self._grow(poly))
            stamp(self.fixed_map, x0, y0, img, 1e6)
        self.fixed = np.asarray(fixed, dtype=object)
        # a piece's outline grown by the gap at translation zero, per key and operation
        self.grown = {k: [self.board.footprint(self._grow(shapely.Polygon(s.ring)))
                          for s in shapes] for k, shapes in self.filler.shapes.items()}
        wmax = max(img.shape[1] for v in self.grown.values() for _, _, img in v)
        self.fshape = (self.filler.fshape[0],
                       sfft.next_fast_len(self.cols + max(wmax, self.filler.wmax) + 2, real=True))
        self._solid: dict[tuple, tuple[int, int, np.ndarray]] = {}
        self.weights = np.ones((len(items), len(items)))
        self.pace = Pace(FIRST_MOVE)  # one move: its FFTs cannot be cut

    def solid(self, key: tuple, ci: int) -> tuple[int, int, np.ndarray]:
        """(x0, y0, spectrum) of the moving piece's own outline, every pixel it touches (not
        eroded as the fill's masks are: an overlap the raster cannot see is one the weights
        cannot push apart). Made on first use, inside the move that needs it, so that the
        search starts at once and a move's measured pace includes it."""
        if (key, ci) not in self._solid:
            x0, y0, img = self.board.footprint(shapely.Polygon(self.filler.shapes[key][ci].ring))
            spec = np.conj(sfft.rfft2(img.astype(np.float32), self.fshape, workers=1))
            self._solid[key, ci] = (x0, y0, spec)
        return self._solid[key, ci]


    def _grow(self, poly: shapely.Polygon) -> shapely.Polygon:
        return poly.buffer(self.gap, quad_segs=4) if self.gap > 0 else poly

    def polygon(self, k: int, pos: tuple[int, np.ndarray]) -> shapely.Polygon:
        return self.filler.polygon(k, pos)

    def right(self, k: int, pos: tuple[int, np.ndarray]) -> float:
        return self.filler.right(k, pos)

    def length_of(self, sol: list) -> float:
        return max(self.right(k, p) for k, p in enumerate(sol)) + self.gap

    # -- overlap -----------------------------------------------------------------------
    def collisions(self, polys: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Colliding pairs (i < j; j from ``len(polys)`` on is a keep-out) and their depth:
        overlap area of the outlines grown by half the gap, plus a floor so that pieces
        merely closer than the gap count."""
        g = self.gap
        n = len(polys)
        polys = np.concatenate([polys, self.fixed])  # keep-outs never move (j >= n)
        i, j = near_pairs(polys, g)
        keep = (i < j) & (i < n)
        i, j = i[keep], j[keep]
        if not len(i):
            return i, j, np.zeros(0)
        half = shapely.buffer(polys, g / 2, quad_segs=4) if g > 0 else polys
        depth = shapely.area(shapely.intersection(half[i], half[j]))
        smaller = np.minimum(shapely.area(polys[i]), shapely.area(polys[j]))
        if g <= 0:  # at gap 0 touching is fine: only a real overlap collides
            real = depth > AREA_TOL * smaller
            i, j, depth, smaller = i[real], j[real], depth[real], smaller[real]
        return i, j, depth + (1e-3 + AREA_TOL) * smaller

    def move(self, k: int, sol: list, polys: np.ndarray, length: float,
             deadline: Deadline | None = None, free_only: bool = False) -> bool:
        """Put piece ``k`` on its allowed position of least weighted overlap in the strip.

        Among raster-free positions the left-most that passes the exact check wins. With
        ``free_only`` the piece stays put unless such a position exists. True if it moved.
        With a ``deadline`` the piece stays put when the move's measured pace does not fit
        in what is left (its FFTs cannot be cut: one took up to 0.5 s on albano under
        load), and when the deadline passes between operations or batches of exact checks.
        """
        if deadline is not None and not self.pace.fits(deadline):
            return False
        self.pace.start()
        try:
            return self._move(k, sol, polys, length, deadline, free_only)
        finally:
            self.pace.stop()

    def _move(self, k: int, sol: list, polys: np.ndarray, length: float,
              deadline: Deadline | None, free_only: bool) -> bool:
        f, res = self.filler, self.filler.res
        item = self.items[k]
        occ = self.fixed_map.copy()
        for j, pos in enumerate(sol):
            if j != k:
                x0, y0, img = self.grown[self.items[j].key][pos[0]]
                shift = np.rint(pos[1] / res).astype(int)
                stamp(occ, x0 + shift[0], y0 + shift[1], img, self.weights[k, j])
        focc = sfft.rfft2(occ, self.fshape, workers=1)
        f.length = length  # the strip: its allowed translations are kept until it changes
        costs, cis, ts, lefts = [], [], [], []
        for ci, s in enumerate(f.shapes[item.key]):
            if deadline is not None and deadline.expired():
                return False
            t = f.translations(item, s)
            if not len(t):
                continue
            x0, y0, spec = self.solid(item.key, ci)
            corr = sfft.irfft2(focc * spec, self.fshape, workers=1)
            col = np.clip(x0 + np.rint(t[:, 0] / res).astype(int), 0, self.fshape[1] - 1)
            row = np.clip(y0 + np.rint(t[:, 1] / res).astype(int), 0, self.fshape[0] - 1)
            costs.append(np.maximum(corr[row, col], 0.0))
            cis.append(np.full(len(t), ci))
            ts.append(t)
            lefts.append(t[:, 0] + s.hi[0] + 0.1 * (t[:, 1] + s.hi[1]))
        if not costs:
            return False
        if deadline is not None and deadline.expired():
            return False
        cost, ci, t, left = map(np.concatenate, (costs, cis, ts, lefts))
        # touching pieces share boundary pixels: the least raster overlap first, left first
        # among equals; the exact check decides. Only the first EXACT_CHECKS are ordered
        # (a partition, not a sort of every allowed position: 10^5 on albano)
        span = float(np.ptp(left)) + 1.0
        key = np.floor(cost / CONTACT) * span + (left - left.min())
        head = min(EXACT_CHECKS, len(key))
        free = np.argpartition(key, head - 1)[:head]
        free = free[np.argsort(key[free], kind="stable")]
        others = np.concatenate([np.delete(polys, k), self.fixed])
        tree = shapely.STRtree(others)
        ring = f.shapes[item.key]
        area = shapely.area(polys[k])
        for batch in exact_batches(len(free)):
            if deadline is not None and deadline.expired():
                return False
            idx = free[batch]
            cands = shapely.polygons(np.stack([ring[c].ring for c in ci[idx]]) + t[idx][:, None])
            ok = clear_of(cands, others, self.gap, area, tree)
            if ok.any():
                pick = idx[np.argmax(ok)]
                return self._place(k, (int(ci[pick]), t[pick]), sol, polys)
        if free_only:
            return False
        # positions the exact check refused collide below the raster's resolution: they
        # cost as much as a contact under the heaviest weight, so the weights move on
        checked = free[:EXACT_CHECKS]
        cost[checked] += CONTACT * self.weights[k].max()
        # least weighted overlap; random among near-ties so that cycles break
        pick = np.argmin(cost * self.rng.uniform(1.0, 1.05, len(cost)))
        return self._place(k, (int(ci[pick]), t[pick]), sol, polys)

    def _place(self, k: int, pos: tuple[int, np.ndarray], sol: list, polys: np.ndarray) -> bool:
        old = sol[k]
        sol[k] = pos
        polys[k] = self.polygon(k, pos)
        return old[0] != pos[0] or not np.allclose(old[1], pos[1])

    # -- separation and strip shrinking ---------------------------------------------------
    def separate(self, sol: list, length: float, deadline: Deadline) -> bool:
        """Guided local search until no pair collides (True), it stalls or the next move
        does not fit before the deadline (False)."""
        polys = np.array([self.polygon(k, p) for k, p in enumerate(sol)], dtype=object)
        self.weights[:] = 1.0
        best, best_sol, stall, strikes = math.inf, list(sol), 0, 0
        while self.pace.fits(deadline):
            i, j, depth = self.collisions(polys)
            if not len(i):
                return True
            total = float(depth.sum())
            if total < best * (1 - 1e-6):
                best, best_sol, stall = total, list(sol), 0
            else:
                stall += 1
                if stall > STALL:  # a strike: back to the least overlap, weights kept
                    strikes += 1
                    if strikes >= STRIKES:
                        return False
                    sol[:] = best_sol
                    polys[:] = [self.polygon(k, p) for k, p in enumerate(sol)]
                    stall = 0
                    continue
            hit = np.zeros_like(self.weights, bool)
            grow = 1.0 + (GROW - 1.0) * depth / depth.max()
            pair = j < len(sol)
            pi, pj, grow = i[pair], j[pair], grow[pair]
            hit[pi, pj] = hit[pj, pi] = True
            self.weights[pi, pj] *= grow
            self.weights[pj, pi] *= grow
            self.weights[~hit] = np.maximum(1.0, self.weights[~hit] * DECAY)
            movers = np.unique(np.concatenate([i, pj]))
            for k in self.rng.permutation(movers):
                if not self.pace.fits(deadline):
                    return False
                self.move(int(k), sol, polys, length, deadline)
        return False

    def squeeze(self, sol: list, length: float, deadline: Deadline) -> bool:
        """Move the pieces beyond ``length`` inside (overlapping), then separate."""
        polys = np.array([self.polygon(k, p) for k, p in enumerate(sol)], dtype=object)
        outside = np.flatnonzero(~self.inside(polys, length))
        for k in outside[np.argsort(-shapely.bounds(polys[outside])[:, 2])]:
            self.move(int(k), sol, polys, length, deadline)
        if not self.inside(polys, length).all():
            return False  # a piece has no allowed position in so short a strip
        return self.separate(sol, length, deadline)

    def inside(self, polys: np.ndarray, length: float) -> np.ndarray:
        """(n,) bool: which outlines keep the gap to the edges of a strip ``length`` long."""
        g, b = self.gap, shapely.bounds(polys)
        return ((b[:, 0] >= g - 1e-9) & (b[:, 1] >= g - 1e-9) & (b[:, 2] <= length - g + 1e-9)
                & (b[:, 3] <= self.problem.width - g + 1e-9))

    def shrink(self, sol: list, deadline: Deadline, progress: Progress | None = None) -> list:
        """Shorten the valid marker ``sol`` while time remains; returns the shortest found."""
        best, best_len = list(sol), self.length_of(sol)
        step, t0 = 0, time.monotonic()
        while self.pace.fits(deadline) and not deadline.expired():
            target = best_len * (1 - SHRINK[step])
            trial = list(best)
            if self.squeeze(trial, target, deadline):
                best, best_len = trial, self.length_of(trial)
                if progress:
                    progress(f"coset search: {time.monotonic() - t0:5.1f} s  length "
                             f"{best_len:.4g}")
                continue
            step = (step + 1) % len(SHRINK)
        return best


def coset_search(problem: NestProblem, items: list[Item], *, time_limit: float | Deadline,
                 seed: int | None, progress: Progress | None = None,
                 start: list[np.ndarray] | None = None, res: float | None = None,
                 ) -> tuple[list[np.ndarray], float] | None:
    """sparrow's free nest snapped to the lattice and separated there, then shrunk.

    The snapped nest overlaps; it is separated on a strip a little longer than the free
    one (longer again after each failure), then the strip shrinks while time remains.
    ``start`` (a valid printed marker from another search) is shrunk instead when it is
    shorter than the first separated one. None when nothing shorter than ``start`` came
    out (or no valid marker at all).
    """
    deadline = deadline_of(time_limit)
    if deadline.expired():
        return None
    rng = np.random.default_rng(seed)
    res = res or default_resolution(problem, items)
    free, free_len = None, math.inf
    if start is None:
        try:
            free, free_len = plain_moves(problem, items, time_limit=deadline.share(FREE_SHARE),
                                         seed=seed)
        except ValueError as exc:  # sparrow gave up
            if progress:
                progress(f"coset search: {exc}")
            return None
    start_len = math.inf if start is None else max(
        float(shapely.Polygon(affine(m, it.ref)).bounds[2])
        for it, m in zip(items, start)) + problem.gap
    search = CosetSearch(problem, items, min(start_len, free_len * GROW_TARGET[-1]), res, rng)
    best = None if start is None else [search.filler.pose(k, m) for k, m in enumerate(start)]
    if free is not None:
        separated = _separated(search, free, free_len, start_len, deadline, progress)
        best = best if separated is None else separated
    if best is None and free is not None:  # each piece to the free position nearest its own
        r = repair(problem, items, snap_to_lattice(problem, items, free),
                   time_limit=deadline, seed=seed, everything=True)
        best = None if r is None else [search.filler.pose(k, m) for k, m in enumerate(r[0])]
    if best is None:
        return None
    best = search.shrink(best, deadline, progress)
    length = search.length_of(best)
    if length >= start_len - 1e-9:
        return None  # nothing shorter than the marker it was given
    return moves_of(search.filler, best), length


def _separated(search: CosetSearch, free: list[np.ndarray], free_len: float,
               start_len: float, deadline: Deadline, progress: Progress | None
               ) -> list | None:
    """The free nest snapped to the lattice and separated on a strip a little longer than
    it (longer after each failure, never as long as ``start_len``); None if it is not."""
    problem, items = search.problem, search.items
    snapped = [search.filler.pose(k, m)
               for k, m in enumerate(snap_to_lattice(problem, items, free))]
    for grow in [grow for grow in GROW_TARGET for _ in range(TRIES)]:
        target = min(free_len * grow, problem.length or math.inf)
        if target >= start_len or deadline.expired():
            return None
        trial = list(snapped)
        attempt = deadline.within(max(ATTEMPT_MIN, ATTEMPT * deadline.left()))
        if search.squeeze(trial, target, attempt):
            if progress:
                progress(f"coset search: snapped free nest separated at "
                         f"{search.length_of(trial):.4g} (free {free_len:.4g})")
            return trial
    return None
