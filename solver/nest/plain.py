"""Plain-fabric nesting with spyrrow (the Python binding of sparrow, Gardeyn & Vanden Berghe).

sparrow is the best published strip packer (ESICUP records, 2025), so we adapt rather
than rewrite: the gap is obtained by buffering every shape by half the gap (mitred, so
it only grows) and nesting on a strip narrowed by the gap, then shifting back; quantities
become demands; a mirrored copy is its own item; the allowed orientations pass through.

.. [1] J. Gardeyn, T. Wauters, G. Vanden Berghe, "An open-source, state-of-the-art
   algorithm for 2D irregular strip packing", 2025 (sparrow). https://github.com/JeroenGar/sparrow
"""

from __future__ import annotations

import atexit
import sys
import threading
import time
from dataclasses import dataclass, field
from datetime import timedelta

import numpy as np
import shapely
import spyrrow

from solver.geometry import rotation_affine
from solver.nest.budget import Deadline, Progress, deadline_of
from solver.nest.instance import MIRROR_X, Item, NestProblem, angle_of, compose
from solver.nest.layout import Layout, build_layout

#: sparrow's constructive start plus how far it runs past its own clock, about this much
#: (s) on the benchmark inputs under load: its search is asked to end this much earlier
SPARROW_RESERVE = 0.1
FEASIBLE = (spyrrow.ReportType.ExplFeas, spyrrow.ReportType.CmprFeas, spyrrow.ReportType.Final)
POLL = 0.02  # s between looks at sparrow's progress queue
#: Points per shape sparrow is given at most. Its collision engine works on every edge: a
#: 62,830-point circle (a digitiser's raw curve) kept it from any marker for minutes under
#: a 1 s budget. Garment pieces and the ESICUP instances have 37-400.
SPARROW_MAX_POINTS = 2000
_RUNNING: set[threading.Thread] = set()  # sparrow runs left behind at their deadline


@atexit.register
def _join_sparrow() -> None:
    """Let sparrow runs left behind finish (within their own time) before the interpreter
    goes: a daemon thread killed inside Rust aborts the process."""
    for thread in list(_RUNNING):
        thread.join()


class Late(ValueError):
    """A search that may be cut short found nothing before its deadline."""


def stderr_progress(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def inflate(ring: np.ndarray, d: float) -> np.ndarray:
    """Outline grown by ``d`` with mitred corners, never inside the true (round) offset.

    A mitre limited by GEOS is cut square beyond the round offset, so it still contains
    it. No simplification afterwards: dropping the tiny square cut of a sharp corner
    (what a Douglas-Peucker pass with a tolerance does) put it inside the offset, and two
    such pieces ended closer than the gap (``nest fu.json --gap 1`` failed verification).
    """
    if d <= 0:
        return ring
    poly = shapely.Polygon(ring).buffer(d, join_style="mitre", mitre_limit=2.0)
    poly = shapely.simplify(poly, 0.0)  # exactly collinear points only
    return np.asarray(poly.exterior.coords)[:-1]


def coarsened(ring: np.ndarray, max_points: int = SPARROW_MAX_POINTS) -> np.ndarray:
    """``ring`` itself, or when it has more than ``max_points`` points, a ring of at most
    that many that contains it: simplified within a tolerance, then grown by it (every
    point of the outline lies within the tolerance of the simplified one), so the nest
    keeps the piece whole. The tolerance starts at 1e-4 of the piece's size and doubles."""
    if len(ring) <= max_points:
        return ring
    poly = shapely.Polygon(ring)
    tol = 1e-4 * float(np.ptp(ring, axis=0).max())
    while True:
        grown = shapely.simplify(shapely.simplify(poly, tol).buffer(
            tol, join_style="mitre", mitre_limit=2.0), 0.0)
        coords = np.asarray(grown.exterior.coords)[:-1]
        if len(coords) <= max_points:
            return coords
        tol *= 2.0


def narrowest(ring: np.ndarray, orientations) -> float:
    """The smallest extent across the strip (y) of ``ring`` over the allowed rotations
    (every whole degree when rotation is free)."""
    angles = np.radians(np.arange(360.0) if orientations is None else np.asarray(orientations))
    y = np.sin(angles)[:, None] * ring[None, :, 0] + np.cos(angles)[:, None] * ring[None, :, 1]
    return float((y.max(axis=1) - y.min(axis=1)).min())


def spyrrow_pack(shapes: dict, height: float, *, time_limit: float | Deadline,
                 seed: int | None, workers: int = 1, progress: Progress | None = None,
                 label: str = "spyrrow", interruptible: bool = False,
                 others: list | None = None) -> tuple[dict, float]:
    """Run sparrow on ``{key: (ring, demand, orientations|None)}`` until the deadline.

    Returns ``{key: [(angle_deg, (tx, ty)), ...]}`` (one entry per copy) and the strip
    length found. Rotations are about the shape's own origin, then the translation.
    sparrow's clock is not ours (it overruns by up to a second on hard instances), so its
    progress reports are watched and, at the deadline, the best feasible one is the
    answer; sparrow then ends on its own in the background, shortly after.
    Without a feasible one by then it is waited for, unless ``interruptible`` (the caller
    has another marker): then :class:`Late` is raised. ``others``, if given, receives the
    placements and lengths of the other feasible markers sparrow reported on the way
    (different nests, for searches that start from several).
    """
    deadline = deadline_of(time_limit)
    items = [spyrrow.Item(str(k), [tuple(map(float, p)) for p in coarsened(ring)], int(n),
                          None if orient is None else [float(a) for a in orient])
             for k, (ring, n, orient) in shapes.items()]
    inst = spyrrow.StripPackingInstance("nest", float(height), items)
    cfg = spyrrow.StripPackingConfig(early_termination=True, total_computation_time=1,
                                     num_workers=workers, seed=seed)
    # whole seconds only in the constructor; the attributes take any duration
    search = max(0.0, deadline.left() - SPARROW_RESERVE)
    cfg.exploration_time = timedelta(seconds=0.8 * search)
    cfg.compression_time = timedelta(seconds=0.2 * search)
    queue = spyrrow.ProgressQueue()
    result: dict = {}

    def work() -> None:
        try:
            result["sol"] = inst.solve(cfg, progress=queue)
        except BaseException as exc:  # a panic in sparrow surfaces here, not as a lost thread
            result["error"] = exc
        finally:
            _RUNNING.discard(threading.current_thread())

    thread = threading.Thread(target=work, daemon=True)
    watch = _Watch(queue, deadline, progress, label, time.monotonic())
    thread.start()
    if watch.until_done(thread, interruptible):
        if "sol" not in result:
            raise ValueError(f"the strip packer failed: {result.get('error')!r}")
        watch.best = result["sol"]
    if others is not None:
        others.extend((_placements(shapes, s), float(s.width)) for s in watch.feasible
                      if s is not watch.best)
    return _placements(shapes, watch.best), float(watch.best.width)


@dataclass
class _Watch:
    """sparrow's progress reports read while it runs: the feasible markers and the best."""

    queue: object  # spyrrow.ProgressQueue
    deadline: Deadline
    progress: Progress | None
    label: str
    t0: float
    best: object = None
    feasible: list = field(default_factory=list)
    last: float = 0.0  # when progress was last told

    def until_done(self, thread: threading.Thread, interruptible: bool) -> bool:
        """Read the reports until sparrow ends (True) or, with a feasible marker, the
        deadline passes (False; sparrow ends in the background). Without one at the
        deadline: wait on, or raise :class:`Late` if ``interruptible``."""
        while thread.is_alive():
            thread.join(POLL)
            self._read(self.queue.drain())
            if interruptible and self.best is None and self.deadline.expired() \
                    and thread.is_alive():
                _RUNNING.add(thread)
                raise Late(f"{self.label}: no marker before the deadline")
            if self.best is not None and self.deadline.expired() and thread.is_alive():
                if self.progress:
                    self.progress(f"{self.label}: deadline; sparrow's best feasible marker "
                                  "is the answer")
                _RUNNING.add(thread)
                return False
        return True

    def _read(self, reports: list) -> None:
        for kind, sol in reports:
            if kind in FEASIBLE:
                self.feasible.append(sol)
                if self.best is None or sol.width < self.best.width:
                    self.best = sol
        if self.progress and reports and time.monotonic() - self.last > 2.0:
            _, sol = reports[-1]
            self.progress(f"{self.label}: {time.monotonic() - self.t0:5.1f} s  length "
                          f"{sol.width:.4g}  density {sol.density:.1%}")
            self.last = time.monotonic()


def _placements(shapes: dict, sol) -> dict:
    """``{key: [(angle_deg, (tx, ty)), ...]}`` of a sparrow solution."""
    keys = {str(k): k for k in shapes}
    out: dict = {k: [] for k in shapes}
    for pi in sol.placed_items:
        out[keys[pi.id]].append((float(pi.rotation) % 360.0, tuple(map(float, pi.translation))))
    return out


def plain_moves(problem: NestProblem, items: list[Item], extra: float = 0.0, *,
                time_limit: float | Deadline = 30.0, seed: int | None = 0,
                progress: Progress | None = None, interruptible: bool = False,
                others: list | None = None) -> tuple[list[np.ndarray], float]:
    """Per item the map ``G`` (reference frame -> fabric) of a free nest by sparrow.

    ``extra`` is added to every side of every shape (the naive print baseline uses it).
    ``others``, if given, receives (moves, length) of the other feasible nests sparrow
    reported on the way.
    """
    g = problem.gap
    grow = g / 2 + extra
    shapes: dict = {}
    for it in items:
        if it.key not in shapes:
            ring = it.ref @ MIRROR_X[:, :2].T if it.mirrored else it.ref
            orient = problem.pieces[it.piece].orientations
            if problem.fabric is not None:
                # the print allows only its own operations: give sparrow exactly those
                orient = sorted({round(angle_of(c, it.mirrored), 9) for c in it.candidates})
            shapes[it.key] = [inflate(ring, grow), 0, orient]
        shapes[it.key][1] += 1
    shapes = {k: tuple(v) for k, v in shapes.items()}
    for (index, _), (ring, _, orient) in shapes.items():
        if narrowest(ring, orient) > (problem.width - g) * (1 + 1e-9):
            raise ValueError(f"piece {problem.pieces[index].name!r} is wider than the "
                             f"{problem.width:g} mm fabric (less the gaps) in every allowed "
                             "orientation: it cannot be nested")
    # buffered shapes lie in [0, L] x [0, W - g]; true outlines keep ``grow`` inside that,
    # so shifting by g/2 leaves g + extra to every fabric edge and g + 2 extra between pieces
    found: list | None = None if others is None else []
    placed, length = spyrrow_pack(shapes, problem.width - g, time_limit=time_limit, seed=seed,
                                  progress=progress, interruptible=interruptible,
                                  others=found)
    if others is not None:
        others.extend((_moves(items, p, g), w + g) for p, w in found)
    return _moves(items, placed, g), length + g


def _moves(items: list[Item], placed: dict, g: float) -> list[np.ndarray]:
    """Per item its map from sparrow's placements of the shapes grown by ``g / 2``."""
    shift = np.array([g / 2, g / 2])
    moves = []
    used: dict = {k: 0 for k in placed}
    for it in items:
        ang, t = placed[it.key][used[it.key]]
        used[it.key] += 1
        m = rotation_affine(ang)
        m[:, 2] = np.asarray(t) + shift
        moves.append(compose(m, MIRROR_X) if it.mirrored else m)
    return moves


def nest_plain(problem: NestProblem, *, time_limit: float | Deadline = 30.0, seed: int | None = 0,
               progress: Progress | None = None) -> Layout:
    """Free strip packing of the problem's pieces (no print) with sparrow."""
    items = problem.items()
    moves, _ = plain_moves(problem, items, time_limit=time_limit, seed=seed, progress=progress)
    return build_layout(problem, items, moves)
