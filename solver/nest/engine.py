"""The search engine below the nesting strategies: raster board and bottom-left filler.

Pieces and fabric are rasterised (each piece's mask eroded by a pixel, so the raster test
is optimistic at contact); for one piece and one operation the overlap with everything
already placed is, for every pixel offset at once, a cross-correlation computed with real
FFTs (the fabric's transform is shared by all candidates of a step). It is read only at
the piece's allowed translations (a lattice coset on a print, every pixel on plain
cloth), bottom-left first, and the best candidates are verified exactly with shapely
(vectorised), so rasterisation never produces an overlap, only a missed opportunity.
A compaction pass re-inserts the right-most pieces while time remains (the restarts over
several orderings are :mod:`solver.nest.fill`). Every placement reads the
deadline between candidate maps and between batches of exact checks; the first fill,
which must give a marker, shelves the pieces it has not placed when only the time to
shelve them is left (columns right of its marker, no raster), so it ends on time.

The strategies (:mod:`solver.nest.lattice`, :mod:`solver.nest.regions`, ...) import this
module; it imports none of them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
import scipy.fft as sfft
import shapely

from solver.nest.budget import Deadline
from solver.nest.instance import Item, affine

# weight of "low y" against "short x" in the bottom-left score, cycled over restarts: no
# single value wins everywhere (1 suits many small pieces, 0 a few large ones)
LEANS = (0.1, 1.0, 0.0, 0.5)
AREA_TOL = 1e-7  # overlap accepted by the exact check, fraction of area (verify allows 1e-6)
EXACT_CHECKS = 2048  # raster-free positions checked exactly per placement, best score first
EXACT_BATCH = 32  # checked at once (vectorised); the deadline is read between batches
# the first batches are smaller: the best raster-free position passes the exact check on 83
# of the 99 placements of a fill of the shirts, and checking 32 then wasted a tenth of it
FIRST_BATCHES = (1, 3, 12)
#: measured cost of shelving one item (:meth:`Filler.shelve`): 0.4-1 ms on the shirts and
#: albano at load 7, 1.5-6 ms at load 10-11 on 2 cores; a fill that must give a result
#: starts shelving this long per item left before its end
SHELF_PER_ITEM = 0.005


def exact_batches(n: int) -> list[slice]:
    """Slices of the first ``n`` candidates in the order they are checked exactly."""
    sizes = [*FIRST_BATCHES, *[EXACT_BATCH] * (n // EXACT_BATCH + 1)]
    bounds = np.minimum(np.cumsum([0, *sizes]), n)
    return [slice(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]


@dataclass
class _Shape:
    """One item key under one candidate map, at translation zero."""

    ring: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    ox: int
    oy: int
    mask: np.ndarray
    spec: dict | None = None


def stamp(target: np.ndarray, x0: int, y0: int, img: np.ndarray, weight: float) -> None:
    """Add ``weight`` times the footprint ``img`` at pixel (x0, y0) to ``target``, clipped."""
    r0, c0 = max(y0, 0), max(x0, 0)
    r1, c1 = min(y0 + img.shape[0], target.shape[0]), min(x0 + img.shape[1], target.shape[1])
    if r1 > r0 and c1 > c0:
        target[r0:r1, c0:c1] += weight * img[r0 - y0:r1 - y0, c0 - x0:c1 - x0].astype(
            target.dtype)


def clear_of(cands: np.ndarray, placed: np.ndarray, gap: float, area: float,
             tree: shapely.STRtree | None = None) -> np.ndarray:
    """(n,) bool: which candidate polygons keep the gap to every ``placed`` polygon.

    At gap 0 touching is fine: an overlap up to ``AREA_TOL`` of ``area`` is accepted.
    Only pairs the tree finds close are measured, so the cost follows the contacts,
    not candidates x placed.
    """
    ok = np.ones(len(cands), bool)
    if not len(placed) or not len(cands):
        return ok
    tree = shapely.STRtree(placed) if tree is None else tree
    if gap > 0:
        pairs = tree.query(cands, predicate="dwithin", distance=gap * (1 - 1e-7))
        ok[pairs[0]] = False
        return ok
    pairs = tree.query(cands, predicate="intersects")
    if pairs.shape[1]:
        inter = shapely.area(shapely.intersection(cands[pairs[0]], placed[pairs[1]]))
        ok[pairs[0][inter > AREA_TOL * area]] = False
    return ok


class Board:
    """Occupancy grid (counts) of placed outlines grown by the gap, plus exact polygons."""

    def __init__(self, width: float, length: float, gap: float, res: float) -> None:
        self.width, self.length, self.gap, self.res = width, length, gap, res
        self.rows = int(math.ceil(width / res)) + 1
        self.cols = int(math.ceil(length / res)) + 1
        self.count = np.zeros((self.rows, self.cols), np.int16)
        self.polys: list[shapely.Polygon] = []
        self.rights: list[float] = []  # right edge of each polygon (-inf once removed)
        self.grown: list[tuple[int, int, np.ndarray]] = []
        self._tree = None

    def footprint(self, poly: shapely.Polygon) -> tuple[int, int, np.ndarray]:
        """(x0, y0, uint8 image): every pixel of this board's grid that ``poly`` covers,
        its image placed with its first pixel at column x0, row y0.

        The image is cut to the board (and a pixel around it): a keep-out may reach far
        beyond the roll, and a 2 km square would otherwise be a 58 TiB image."""
        lo = np.floor(np.asarray(poly.bounds[:2]) / self.res).astype(int) - 1
        hi = np.ceil(np.asarray(poly.bounds[2:]) / self.res).astype(int) + 1
        lo, hi = np.maximum(lo, -1), np.minimum(hi, [self.cols, self.rows])
        if np.any(hi < lo):
            return 0, 0, np.zeros((0, 0), np.uint8)
        img = np.zeros((hi[1] - lo[1] + 1, hi[0] - lo[0] + 1), np.uint8)
        pts = np.asarray(poly.exterior.coords) / self.res - 0.5 - lo
        cv2.fillPoly(img, [np.round(pts * 16).astype(np.int32)], 1, cv2.LINE_8, shift=4)
        return int(lo[0]), int(lo[1]), img

    def add(self, poly: shapely.Polygon) -> int:
        grown = poly.buffer(self.gap, quad_segs=4) if self.gap > 0 else poly
        x0, y0, img = self.footprint(grown)
        stamp(self.count, x0, y0, img, +1)
        self.polys.append(poly)
        self.rights.append(poly.bounds[2])
        self.grown.append((x0, y0, img))
        self._tree = None
        return len(self.polys) - 1

    def remove(self, k: int) -> None:
        x0, y0, img = self.grown[k]
        stamp(self.count, x0, y0, img, -1)
        self.polys[k] = shapely.Polygon()
        self.rights[k] = -math.inf
        self.grown[k] = (0, 0, np.zeros((0, 0), np.uint8))
        self._tree = None

    def frontier(self) -> float:
        """Right-most x of the placed polygons (0 when empty)."""
        return max(0.0, max(self.rights, default=0.0))

    def tree(self) -> shapely.STRtree:
        if self._tree is None:
            self._tree = shapely.STRtree(self.polys)
        return self._tree

    def clear_of(self, cands: np.ndarray, area: float) -> np.ndarray:
        """(n,) bool: which candidate polygons keep the gap to every placed polygon."""
        if not self.polys:
            return np.ones(len(cands), bool)
        return clear_of(cands, np.asarray(self.polys, dtype=object), self.gap, area,
                        self.tree())


class Filler:
    """Bottom-left fill on lattice cosets with FFT collision maps (see module docstring)."""

    def __init__(self, items: list[Item], width: float, length: float, gap: float,
                 res: float, fixed: list[shapely.Polygon], score: str = "right") -> None:
        self.items, self.width, self.length, self.gap, self.res = items, width, length, gap, res
        self.fixed = fixed
        self.score = score
        self.lean = LEANS[0]
        self.shapes: dict[tuple, list[_Shape]] = {}
        for it in items:
            if it.key not in self.shapes:
                self.shapes[it.key] = [self._shape(affine(c, it.ref)) for c in it.candidates]
        rows = int(math.ceil(width / res)) + 1
        cols = int(math.ceil(length / res)) + 1
        hmax = max(s.mask.shape[0] for v in self.shapes.values() for s in v)
        wmax = max(s.mask.shape[1] for v in self.shapes.values() for s in v)
        self.fshape = (sfft.next_fast_len(rows + hmax, real=True),
                       sfft.next_fast_len(cols + wmax, real=True))
        self.wmax = wmax
        self.longest = max(float(s.hi[0] - s.lo[0]) for v in self.shapes.values() for s in v)
        # the lattice step along x: the first free position right of the frontier lies within
        self.step = max((float(np.abs(it.lattice).max()) for it in items
                         if it.lattice is not None), default=0.0)
        self.area = {k: shapely.Polygon(v[0].ring).area for k, v in self.shapes.items()}
        # per shape and chunk of the roll: allowed translations (see translations)
        self._moves: dict[tuple[int, int], np.ndarray] = {}
        self._moves_length = length
        self.chunk = max(64 * res, 8 * self.step)  # mm of roll per chunk

    def _shape(self, ring: np.ndarray) -> _Shape:
        lo, hi = ring.min(0), ring.max(0)
        o = np.floor(lo / self.res).astype(int) - 1
        size = np.ceil(hi / self.res).astype(int) + 2 - o
        img = np.zeros((size[1], size[0]), np.uint8)
        pts = ring / self.res - 0.5 - o
        cv2.fillPoly(img, [np.round(pts * 16).astype(np.int32)], 1, cv2.LINE_8, shift=4)
        # eroded by a pixel: the raster test must stay optimistic at contact (touching
        # pieces share boundary pixels after rounding); the exact check decides there
        core = cv2.erode(img, np.ones((3, 3), np.uint8))
        if core.any():
            img = core
        return _Shape(ring, lo, hi, int(o[0]), int(o[1]), img.astype(np.float32))

    def _spec(self, s: _Shape, fshape: tuple[int, int]) -> np.ndarray:
        if s.spec is None:
            s.spec = {}
        if fshape not in s.spec:
            s.spec[fshape] = np.conj(sfft.rfft2(s.mask, fshape, workers=1))
        return s.spec[fshape]

    def window(self, board: Board, target: tuple | None = None,
               ) -> tuple[int, tuple[int, int], float, float]:
        """Columns to correlate: (first column, FFT shape, x range of left edges).

        Bottom-left: a position right of the frontier is never better than the first one
        there, so left edges up to the frontier (plus a lattice step) suffice. Near a
        target: one piece length either side of it. Column counts grow in coarse steps
        so that mask spectra are reused.
        """
        xlim = board.frontier() + self.gap + 2 * self.res + 2 * self.step
        xlo = -math.inf
        c0 = 0
        if target is not None:
            tx = float(target[1][0])
            xlim = max(xlim, tx + self.longest)
            xlo = tx - 2 * self.longest
            c0 = max(0, int(math.floor(xlo / self.res)) - 2)
        cols = int(math.ceil((xlim + self.longest + self.gap) / self.res)) + 3 - c0 + self.wmax
        step = max(64, int(2 ** math.floor(math.log2(max(cols, 1)) - 2)))
        cols = min(int(math.ceil(cols / step) * step), self.fshape[1])
        return c0, (self.fshape[0], sfft.next_fast_len(cols, real=True)), xlo, xlim

    def board(self) -> Board:
        b = Board(self.width, self.length, self.gap, self.res)
        for p in self.fixed:
            b.add(p)
        return b

    def translations(self, item: Item, s: _Shape, xlo: float = -math.inf,
                     xhi: float = math.inf) -> np.ndarray:
        """(m, 2) allowed translations keeping the shape inside the fabric minus the gap,
        sorted along the roll.

        Only those whose left edge lies in [xlo, xhi] (the search window). Made in chunks
        of the roll, each once per shape and fabric length: rebuilding the window's grid
        for every placement took a fifth of a fill of the shirts, and the whole roll's at
        once 0.15 s a shape on albano.
        """
        if self._moves_length != self.length:
            self._moves, self._moves_length = {}, self.length
        lo = max(xlo, self.gap)
        hi = min(xhi, self.length - self.gap - (s.hi[0] - s.lo[0]))
        if hi < lo - 1e-9:
            return np.zeros((0, 2))
        w = self.chunk
        parts = []
        # hi may lie below lo by the tolerance above, across a chunk's edge: lo's chunk
        for c in range(int(math.floor(lo / w)), int(math.floor(max(hi, lo) / w)) + 1):
            if (id(s), c) not in self._moves:
                t = self._grid(item, s, c * w - 1e-9, (c + 1) * w - 1e-9)
                self._moves[id(s), c] = t[np.argsort(t[:, 0], kind="stable")]
            parts.append(self._moves[id(s), c])
        t = np.concatenate(parts) if len(parts) > 1 else parts[0]
        a = np.searchsorted(t[:, 0], xlo - s.lo[0] - 1e-9, "left")
        b = np.searchsorted(t[:, 0], xhi - s.lo[0] + 1e-9, "right")
        return t[a:b]

    def _grid(self, item: Item, s: _Shape, xlo: float, xhi: float) -> np.ndarray:
        """The allowed translations of ``s`` with their left edge in [xlo, xhi)."""
        g = self.gap
        tlo = np.array([max(g, xlo), g]) - s.lo
        thi = np.array([min(self.length - g - s.hi[0], xhi - s.lo[0]), self.width - g - s.hi[1]])
        if np.any(thi < tlo):
            return np.zeros((0, 2))
        if item.lattice is None:
            xs = (np.arange(math.ceil(tlo[0] / self.res), math.floor(thi[0] / self.res) + 1)
                  * self.res)
            ys = (np.arange(math.ceil(tlo[1] / self.res), math.floor(thi[1] / self.res) + 1)
                  * self.res)
            gx, gy = np.meshgrid(xs, ys, indexing="ij")
            t = np.column_stack([gx.ravel(), gy.ravel()])
        else:
            basis = item.lattice
            corners = np.array([[tlo[0], tlo[1]], [tlo[0], thi[1]], [thi[0], tlo[1]],
                                [thi[0], thi[1]]])
            f = corners @ np.linalg.inv(basis).T
            a = np.arange(math.floor(f[:, 0].min()), math.ceil(f[:, 0].max()) + 1)
            b = np.arange(math.floor(f[:, 1].min()), math.ceil(f[:, 1].max()) + 1)
            ga, gb = np.meshgrid(a, b, indexing="ij")
            t = np.column_stack([ga.ravel(), gb.ravel()]) @ basis.T
            t = t[np.all((t >= tlo - 1e-9) & (t <= thi + 1e-9), axis=1)]
        return t[t[:, 0] < xhi - s.lo[0]]  # half-open: chunks share no translation

    def best_position(self, board: Board, item: Item, target: tuple | None = None,
                      deadline: Deadline | None = None) -> tuple[int, np.ndarray] | None:
        """(candidate index, translation) with the best score that passes the exact check.

        The score is bottom-left, or with ``target`` = (candidate index, translation) the
        distance to that wished-for position (used to repair a snapped layout locally).
        None when no position is free, or when ``deadline`` passes first: it is read
        between candidate maps and between batches of exact checks (one placement on a
        long board under load took up to 0.13 s, too long to overrun by).
        """
        c0, fshape, xlo, xlim = self.window(board, target)
        occ = (board.count[:, c0:c0 + fshape[1]] > 0).astype(np.float32)
        focc = sfft.rfft2(occ, fshape, workers=1)
        options = []
        for ci, s in enumerate(self.shapes[item.key]):
            if deadline is not None and deadline.expired():
                return None
            t = self.translations(item, s, xlo, xlim)
            if not len(t):
                continue
            corr = sfft.irfft2(focc * self._spec(s, fshape), fshape, workers=1)
            col = np.clip(np.rint(s.ox + t[:, 0] / self.res).astype(int) - c0, 0, fshape[1] - 1)
            row = np.clip(np.rint(s.oy + t[:, 1] / self.res).astype(int), 0, fshape[0] - 1)
            free = corr[row, col] < 0.5
            t = t[free]
            if not len(t):
                continue
            if target is not None:
                # push right rather than sideways: the sweep goes left to right
                d = t - target[1]
                sc = np.abs(d[:, 0]) + 2 * np.abs(d[:, 1]) + (0.0 if ci == target[0] else 1e6)
            elif self.score == "left":
                sc = (t[:, 0] + s.lo[0]) * 1e3 + t[:, 1] + s.lo[1]
            else:
                lean = self.lean * (s.hi[0] - s.lo[0]) / self.width
                sc = (t[:, 0] + s.hi[0]) + lean * (t[:, 1] + s.hi[1])
            options.append((sc, np.full(len(t), ci), t))
        if not options:
            return None
        sc = np.concatenate([o[0] for o in options])
        ci = np.concatenate([o[1] for o in options])
        t = np.concatenate([o[2] for o in options])
        order = np.argsort(sc, kind="stable")
        return self._first_clear(item, board, order, ci, t, EXACT_CHECKS, deadline)

    def _first_clear(self, item: Item, board: Board, order: np.ndarray, ci: np.ndarray,
                     t: np.ndarray, limit: int, deadline: Deadline | None = None,
                     ) -> tuple[int, np.ndarray] | None:
        """The first of the first ``limit`` positions (candidate map ``ci``, translation
        ``t``) in ``order`` that is clear of ``board`` by the exact check, in batches
        with the deadline read between them; None if none is."""
        area = self.area[item.key]
        for batch in exact_batches(min(len(order), limit)):
            if deadline is not None and deadline.expired():
                return None
            idx = order[batch]
            # all candidate maps of one item share the ring length
            rings = np.stack([self.shapes[item.key][c].ring for c in ci[idx]])
            ok = board.clear_of(shapely.polygons(rings + t[idx][:, None, :]), area)
            if ok.any():
                k = idx[np.argmax(ok)]
                return int(ci[k]), t[k]
        return None

    def fill(self, order: list[int], board: Board, sol: list, index: list[int],
             targets: list | None = None, deadline: Deadline | None = None,
             complete: bool = False) -> bool:
        """Greedy fill of the items in ``order`` (``sol``/``index`` updated).

        False if stuck, or if ``deadline`` passed before every item was placed. A fill that
        must give a result (``complete``) instead shelves the items left when only the time
        to shelve them remains (:meth:`shelve`); where they do not fit on the fabric, it
        goes on filling past the deadline.
        """
        for i, k in enumerate(order):
            wish = None if targets is None else targets[k]
            shelf = SHELF_PER_ITEM * (len(order) - i) if complete else 0.0
            if deadline is not None and not deadline.allows(shelf):
                if not complete:
                    return False
                if self.shelve(order[i:], board, sol, index):
                    return True
                deadline = None  # no room right of the marker: fill on, past the deadline
            pos = self.best_position(board, self.items[k], wish, deadline)
            if pos is None and deadline is not None and deadline.expired():
                if not complete:
                    return False
                if self.shelve(order[i:], board, sol, index):
                    return True
                deadline = None
                pos = self.best_position(board, self.items[k], wish)
            if pos is None:
                return False
            sol[k] = pos
            index[k] = board.add(self.polygon(k, pos))
        return True

    def shelve(self, order: list[int], board: Board, sol: list, index: list[int]) -> bool:
        """Place the items of ``order`` in columns right of every placed item: each at the
        lowest allowed position above the one before that passes the exact check, a new
        column when none is left. No raster and no search (about a millisecond an item):
        what a fill that must give a result does with the items left at its deadline.
        False, with nothing placed, when they do not fit on the fabric."""
        x = max((self.right(k, p) for k, p in enumerate(sol) if p is not None), default=0.0)
        col, bottom, col_right = x + self.gap, -math.inf, x + self.gap
        done = []
        for k in order:
            pos = self._shelf_position(k, board, col, bottom)
            if pos is None:  # the column is full: the next one
                col, bottom = col_right + self.gap, -math.inf
                pos = self._shelf_position(k, board, col, bottom)
            if pos is None:
                for j in done:
                    board.remove(index[j])
                    sol[j] = None
                return False
            sol[k] = pos
            index[k] = board.add(self.polygon(k, pos))
            done.append(k)
            s = self.shapes[self.items[k].key][pos[0]]
            bottom = float(pos[1][1] + s.hi[1]) + self.gap
            col_right = max(col_right, self.right(k, pos))
        return True

    def _shelf_position(self, k: int, board: Board, col: float, bottom: float,
                        ) -> tuple[int, np.ndarray] | None:
        """The lowest allowed position of item ``k`` with its left edge in the first
        lattice step right of ``col`` and its bottom above ``bottom`` that is clear."""
        item = self.items[k]
        options = []
        for ci, s in enumerate(self.shapes[item.key]):
            # a narrow strip: made directly, not as chunks of the roll that only a fill
            # reuses (they made shelving albano's 24 pieces take 3 ms a piece)
            t = self._grid(item, s, col, col + 2 * self.step + 2 * self.res)
            t = t[t[:, 1] + s.lo[1] >= bottom - 1e-9]
            top = t[:, 1] + s.hi[1] + 1e-3 * (t[:, 0] + s.hi[0])
            options.append((top, np.full(len(t), ci), t))
        top, ci, t = (np.concatenate(o) for o in zip(*options))
        order = np.argsort(top, kind="stable")
        return self._first_clear(item, board, order, ci, t, 2 * EXACT_BATCH)

    def pose(self, k: int, move: np.ndarray) -> tuple[int, np.ndarray]:
        """(candidate index, translation) of a given move of item ``k``."""
        cands = self.items[k].candidates
        ci = int(np.argmin([np.abs(c[:, :2] - move[:, :2]).max() for c in cands]))
        return ci, move[:, 2] - cands[ci][:, 2]

    def polygon(self, k: int, pos: tuple[int, np.ndarray]) -> shapely.Polygon:
        return shapely.Polygon(self.shapes[self.items[k].key][pos[0]].ring + pos[1])

    def left(self, k: int, pos: tuple[int, np.ndarray]) -> float:
        return float(self.shapes[self.items[k].key][pos[0]].lo[0] + pos[1][0])

    def right(self, k: int, pos: tuple[int, np.ndarray]) -> float:
        return float(self.shapes[self.items[k].key][pos[0]].hi[0] + pos[1][0])

    def compact(self, sol: list, board: Board, deadline: Deadline,
                board_index: list[int]) -> list:
        """Re-insert pieces right-most first while that shortens the marker or frees room."""
        improved = True
        while improved and not deadline.expired():
            improved = False
            order = np.argsort([-self.right(k, p) for k, p in enumerate(sol)])
            for k in order[: max(4, len(order) // 4)]:
                if deadline.expired():
                    break
                old = sol[k]
                board.remove(board_index[k])
                pos = self.best_position(board, self.items[k], deadline=deadline)
                if pos is not None and self.right(k, pos) < self.right(k, old) - 1e-9:
                    sol[k] = pos
                    improved = True
                else:
                    pos = old
                board_index[k] = board.add(self.polygon(k, pos))
        return sol


def moves_of(filler: Filler, sol: list) -> list[np.ndarray]:
    out = []
    for it, (ci, t) in zip(filler.items, sol):
        g = it.candidates[ci].copy()
        g[:, 2] += t
        out.append(g)
    return out
