"""Snap a free nest to the print jointly: each piece picks a lattice point near its own.

Snapping every piece of a free (sparrow) nest to its *nearest* allowed position moves
each by up to the covering radius, independently, so neighbours collide and a sweep must
push them apart. But a piece has several allowed positions around its free one (the
corners of the lattice cell it sits in, and beyond): choosing among them *together* is a
small constraint problem. Which choices of two neighbours collide is tabulated exactly
(shapely, vectorised over all option pairs); a depth-first search with forward checking
(fewest options first) and branch and bound on the marker length then finds the shortest
collision-free combination, or proves there is none within reach.
"""

from __future__ import annotations

import math
import time

import numpy as np
import shapely

from solver.nest.budget import Deadline, Progress, deadline_of
from solver.nest.fill import first_fill_estimate
from solver.nest.instance import Item, NestProblem, affine
from solver.nest.plain import plain_moves
from solver.nest.regions import repair, snap_to_lattice

AREA_TOL = 1e-7  # overlap accepted at gap 0, fraction of the smaller area (verify: 1e-6)
CLASH_BLOCK = 4096  # option pairs checked exactly between two looks at the clock


def snap_options(problem: NestProblem, item: Item, move: np.ndarray, reach: float,
                 push: float) -> tuple[np.ndarray, np.ndarray]:
    """(m, 2, 3) allowed maps around the free ``move``, and their (m,) outlines.

    Every print operation the item may undergo (not only the one with the free move's
    rotation: a half turn changes the piece's coset, and so which neighbours it fits);
    translations are the lattice points that put the outline's centre within ``reach``
    (mm) of where the free move put it, or up to ``push`` (mm) further along the roll:
    a free nest is tight, and its snapped pieces need room that only a longer marker
    gives. Kept only where the outline stays on the fabric, clear of the keep-outs.
    """
    basis = item.lattice
    centre = np.asarray(shapely.Polygon(item.ref).centroid.coords[0])
    goal = affine(move, centre)[0]
    lo, hi = np.array([-reach, -reach]), np.array([reach + push, reach])
    corners = np.array([[lo[0], lo[1]], [lo[0], hi[1]], [hi[0], lo[1]], [hi[0], hi[1]]])
    fc = np.linalg.solve(basis, corners.T).T
    a = np.arange(math.floor(fc[:, 0].min()) - 1, math.ceil(fc[:, 0].max()) + 2)
    b = np.arange(math.floor(fc[:, 1].min()) - 1, math.ceil(fc[:, 1].max()) + 2)
    cells = np.stack(np.meshgrid(a, b, indexing="ij"), -1).reshape(-1, 2) @ basis.T
    maps = []
    for c in item.candidates:
        base = goal - affine(c, centre)[0]
        f = np.linalg.solve(basis, base)
        d = np.round(f) @ basis.T - base + cells  # offsets from the free centre
        keep = np.all((d >= lo - 1e-9) & (d <= hi + 1e-9), axis=1)
        m = np.repeat(c[None], int(keep.sum()), axis=0)
        m[:, :, 2] += base + d[keep]
        maps.append(m)
    maps = np.concatenate(maps)
    polys = shapely.polygons(np.einsum("mij,nj->mni", maps[:, :, :2], item.ref)
                             + maps[:, None, :, 2])
    g, b = problem.gap, shapely.bounds(polys)
    ok = (b[:, 0] >= g - 1e-9) & (b[:, 1] >= g - 1e-9) & (b[:, 3] <= problem.width - g + 1e-9)
    if problem.length is not None:
        ok &= b[:, 2] <= problem.length - g + 1e-9
    for k in problem.keepouts:
        ok &= ~collide(polys, shapely.Polygon(k), g)
    return maps[ok], polys[ok]


def collide(a, b, gap: float) -> np.ndarray:
    """Elementwise (broadcast): closer than the gap, or overlapping at gap 0."""
    if gap > 0:
        return shapely.dwithin(a, b, gap * (1 - 1e-7))
    inter = shapely.area(shapely.intersection(a, b))
    return inter > AREA_TOL * np.minimum(shapely.area(a), shapely.area(b))


def _clash_table(a: np.ndarray, b: np.ndarray, gap: float, deadline: float,
                 ) -> np.ndarray | None:
    """(len(a), len(b)) bool: which options of two pieces collide; None at the deadline.

    In blocks of about ``CLASH_BLOCK`` pairs with the deadline read between them: on a
    stripe print (1 mm steps along the stripes) a piece has hundreds of options, and one
    pair's table took seconds.
    """
    out = np.zeros((len(a), len(b)), bool)
    rows = max(1, CLASH_BLOCK // max(1, len(b)))
    for r in range(0, len(a), rows):
        if time.monotonic() > deadline:
            return None
        out[r:r + rows] = collide(a[r:r + rows, None], b[None, :], gap)
    return out


def joint_snap(problem: NestProblem, items: list[Item], moves: list[np.ndarray], *,
               reach: float, push: float, deadline: float = math.inf,
               ) -> tuple[list[np.ndarray], float] | None:
    """The shortest collision-free choice of allowed positions near the free ``moves``.

    Returns (moves, length) or None when no choice within reach is free (or
    none was found before ``deadline``; the best found so far is returned otherwise).
    """
    n = len(items)
    opts = [snap_options(problem, it, m, reach, push) for it, m in zip(items, moves)]
    if any(len(p) == 0 for _, p in opts):
        return None
    right = [shapely.bounds(p)[:, 2] for _, p in opts]
    # order each piece's options by their right edge: the first free one is its best
    for k in range(n):
        o = np.argsort(right[k], kind="stable")
        opts[k] = (opts[k][0][o], opts[k][1][o])
        right[k] = right[k][o]
    clash = _clash_tables(problem, opts, deadline)
    if clash is None:
        return None
    choice = _Choice(right, clash, deadline)
    try:
        choice.search([np.ones(len(p), bool) for _, p in opts], [-1] * n, 0.0)
    except TimeoutError:
        pass
    if choice.pick is None:
        return None
    out = [opts[k][0][o] for k, o in enumerate(choice.pick)]
    return out, choice.length + problem.gap


def _clash_tables(problem: NestProblem, opts: list, deadline: float
                  ) -> dict[tuple[int, int], np.ndarray] | None:
    """``(i, j) -> (m_i, m_j)`` bool: which options of pieces i and j collide, for the
    pairs whose options' boxes come within the gap; None when the tables alone outgrow
    the budget."""
    n, g = len(opts), problem.gap
    box = np.array([np.concatenate([shapely.bounds(p)[:, :2].min(0), shapely.bounds(p)[:, 2:]
                                    .max(0)]) for _, p in opts])
    clash: dict[tuple[int, int], np.ndarray] = {}
    for i in range(n):
        if time.monotonic() > deadline:
            return None
        near = np.flatnonzero((box[:, 0] <= box[i, 2] + g) & (box[:, 2] >= box[i, 0] - g)
                              & (box[:, 1] <= box[i, 3] + g) & (box[:, 3] >= box[i, 1] - g))
        for j in near[near > i]:
            m = _clash_table(opts[i][1], opts[j][1], problem.gap, deadline)
            if m is None:
                return None
            if m.any():
                clash[i, j] = m
                clash[j, i] = m.T
    return clash


class _Choice:
    """Branch and bound over one option per piece: the shortest choice free of clashes.
    ``right[k]`` (sorted) is the right edge of piece k's options."""

    def __init__(self, right: list[np.ndarray], clash: dict, deadline: float) -> None:
        self.right, self.clash, self.deadline = right, clash, deadline
        n = len(right)
        self.neighbours = [[j for j in range(n) if (i, j) in clash] for i in range(n)]
        self.length, self.pick = math.inf, None  # the best choice so far
        self.nodes = 0

    def search(self, allowed: list[np.ndarray], pick: list[int], length: float) -> None:
        """Extend ``pick`` (-1: not chosen yet) within the ``allowed`` options; raises
        TimeoutError at the deadline."""
        self.nodes += 1
        if self.nodes % 256 == 0 and time.monotonic() > self.deadline:
            raise TimeoutError
        todo = [k for k in range(len(pick)) if pick[k] < 0]
        if not todo:
            self.length, self.pick = length, list(pick)
            return
        # bound: every piece still to place ends at least at its best allowed option
        lows = [self.right[k][allowed[k]].min() for k in todo]
        if max(length, max(lows)) >= self.length - 1e-9:
            return
        k = todo[int(np.argmin([allowed[k].sum() for k in todo]))]  # fewest options first
        for o in np.flatnonzero(allowed[k]):
            new_len = max(length, self.right[k][o])
            if new_len >= self.length - 1e-9:
                break  # options are sorted by their right edge
            sub = self._without_clashes(allowed, pick, k, o)
            if sub is None:
                continue
            pick[k] = o
            self.search(sub, pick, new_len)
            pick[k] = -1

    def _without_clashes(self, allowed: list[np.ndarray], pick: list[int], k: int, o: int
                         ) -> list[np.ndarray] | None:
        """The options still allowed once piece k takes option o; None when a piece not
        chosen yet is left without one."""
        sub = list(allowed)
        for j in self.neighbours[k]:
            if pick[j] < 0:
                sub[j] = allowed[j] & ~self.clash[k, j][o]
                if not sub[j].any():
                    return None
        return sub


# (reach, push) in lattice steps, tried in turn: no one setting wins everywhere (a wider
# reach finds more combinations, and takes longer to exhaust)
REACHES = ((1.5, 4.0), (2.0, 6.0), (1.0, 2.0))
FREE_SHARE = 0.7  # of the time, for sparrow's free nest
SNAP_SHARE = 0.5  # of the time after it, for the final nest's joint snaps; the earlier
# nests' snaps have the rest but the sweep's estimate (the sweep, what they leave)
LOOSER = 1.1  # earlier nests up to this times the final length are snapped
SPACINGS = (1.0, 0.5, 0.25, 0.125)  # lattice steps between the earlier nests, coarse first
SNAP_MAX = 0.3  # s, at most, for one earlier nest's snap


def earlier_nests(others: list, final: float, step: float) -> list:
    """Sparrow's earlier feasible nests worth snapping, coarse to fine: each pass keeps
    those at least a spacing longer than the last one kept (``SPACINGS``, in lattice
    steps), up to ``LOOSER`` times the final length.

    Measured (Berkeley t-shirt, skirt and pants, 50 mm prints): the final nest is not
    the one that snaps best; nests 2-6 % looser snapped to markers 2-5 % shorter (pants
    p1 1481 -> 1440 mm, t-shirt p2 898 -> 855 mm), and the result changes every 5-30 mm
    of free length. One run's nests are alike, though: on the t-shirt-iso p1 all twenty
    snapped to 917-967 mm, where another run's final nest snapped to 867 mm.
    """
    cands = sorted((o for o in others if final < o[1] <= final * LOOSER), key=lambda o: o[1])
    out, taken = [], set()
    for spacing in SPACINGS:
        last = final
        for i, (_, length) in enumerate(cands):
            if length - last >= spacing * step:
                last = length
                if i not in taken:
                    taken.add(i)
                    out.append(cands[i])
    return out


def snap_nests(problem: NestProblem, items: list[Item], free: list[np.ndarray],
               free_len: float, others: list, *, final: float, deadline: float,
               progress: Progress | None = None) -> tuple[list[np.ndarray], float] | None:
    """The shortest joint snap of sparrow's final nest ``free`` (every setting of
    ``REACHES``, until ``final``) and of its earlier nests ``others`` ((moves, length)
    pairs, see :func:`earlier_nests`) until ``deadline`` (both monotonic s)."""
    t0 = time.monotonic()
    step = float(np.abs(problem.lattice).max())
    best = None
    for reach, push in REACHES:
        if time.monotonic() > final:
            break
        r = joint_snap(problem, items, free, reach=reach * step, push=push * step,
                       deadline=final)
        if r is not None and (best is None or r[1] < best[1]):
            best = r
            if progress:
                progress(f"joint snap: {time.monotonic() - t0:5.1f} s  length {r[1]:.4g}")
    reach, push = REACHES[0]
    tried = 0
    for moves, length in earlier_nests(others, free_len, step):
        if time.monotonic() > deadline:
            break
        tried += 1
        r = joint_snap(problem, items, moves, reach=reach * step, push=push * step,
                       deadline=min(deadline, time.monotonic() + SNAP_MAX))
        if r is not None and (best is None or r[1] < best[1]):
            best = r
            if progress:
                progress(f"joint snap: {time.monotonic() - t0:5.1f} s  length {r[1]:.4g} "
                         f"(sparrow's nest of {length:.4g}, final {free_len:.4g})")
    if progress:
        progress(f"joint snap: {tried} of sparrow's {len(others)} earlier nests snapped")
    return best


def joint_search(problem: NestProblem, items: list[Item], *, time_limit: float | Deadline,
                 seed: int | None, progress: Progress | None = None, extra: float = 0.0,
                 interruptible: bool = False) -> tuple[list[np.ndarray], float] | None:
    """One sparrow run (``extra`` mm of margin around every piece): its final free nest
    snapped jointly with each setting of ``REACHES`` and by the nearest-first sweep of
    :func:`solver.nest.regions.repair` (what ``resnap`` does), and its earlier feasible
    nests (:func:`earlier_nests`) snapped jointly while time remains; the shortest wins.

    Unless ``interruptible``, sparrow and the snaps stop early enough to leave the sweep
    its estimated time (cut at the deadline, the sweep shelves the pieces left); it also
    has what they leave, and once a snap exists it is only a fallback (its restarts gave
    way to the earlier nests).
    """
    budget = deadline_of(time_limit)
    sweep = 0.0 if interruptible else first_fill_estimate(items)
    others: list = []
    try:
        free, free_len = plain_moves(problem, items, extra=extra, seed=seed,
                                     time_limit=budget.before(sweep).share(FREE_SHARE),
                                     interruptible=interruptible, others=others)
    except ValueError as exc:  # sparrow gave up (or is late); the other strategies may not
        if progress:
            progress(f"joint snap: {exc}")
        return None
    final = time.monotonic() + budget.before(sweep).share(SNAP_SHARE).left()
    best = snap_nests(problem, items, free, free_len, others, final=final,
                      deadline=time.monotonic() + budget.before(sweep).left(), progress=progress)
    r = repair(problem, items, snap_to_lattice(problem, items, free), time_limit=budget,
               seed=seed, progress=progress, everything=True,
               interruptible=interruptible or best is not None)
    if r is not None and (best is None or r[1] < best[1]):
        best = r
    return best
