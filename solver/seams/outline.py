"""A piece's sew line cut into edges, as a sewer reads it before matching seams.

The sew line is split at its corners, the file's turn points and its notches; each edge
knows its arc-length interval on the loop. Arc lengths run counter-clockwise from the
loop's first point, so an interval is ``(start, end)`` with ``end`` possibly past the loop's
length (it wraps). Notches within a few millimetres of each other are one notch group (a
double notch marks the back, a single one the front).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import shapely

from solver.geometry import polygon_area

__all__ = ["SewPiece", "arc_position", "point_at", "sewn_line", "sub_loop"]

CORNER_DEG = 30.0  # a sew line turning by more than this at one point has a corner there
MERGE_MM = 3.0  # breakpoints closer than this are one
NOTCH_GROUP_MM = 12.0
SAME_NOTCH_MM = 0.5  # notches closer than this are one
TURN_DEG = 8.0
DENSE_TURNS = 3  # turn points per corner (plus two) beyond which a CAD marks every vertex
TURN_SPAN_MM = 8.0  # notches closer than this along the line are one double notch
DART_TIP_DEG = 120.0  # a reflex corner turning more than this is a dart's tip ...
DART_LEGS = 0.15  # ... when its two legs agree in length within this share
MIN_LEG_MM = 20.0  # and each leg is at least this long


@dataclass
class SewPiece:
    """One piece to sew: its name, its sew line (CCW, mm) and the marks on it."""

    name: str
    loop: np.ndarray  # (n,2)
    turns: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    notches: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    grain: np.ndarray | None = None  # (2,2) the grain line, where the file has one
    family: str = ""  # copies of one pattern piece (a left and a right) share it

    def __post_init__(self) -> None:
        loop = np.asarray(self.loop, float).reshape(-1, 2)
        if polygon_area(loop) < 0:  # (shapely's area is unsigned)
            loop = loop[::-1]
        self.loop = loop
        seg = np.linalg.norm(np.roll(loop, -1, axis=0) - loop, axis=1)
        self.cum = np.concatenate([[0.0], np.cumsum(seg)])

    @property
    def length(self) -> float:
        return float(self.cum[-1])

    def corners(self, min_deg: float = CORNER_DEG) -> tuple[np.ndarray, np.ndarray]:
        """Arc positions of the loop's corners turning more than ``min_deg``, and each one's
        turn in degrees (positive left: convex; negative: a reflex corner, a dart's tip)."""
        simple = shapely.simplify(shapely.LinearRing(self.loop), 0.5)
        pts = np.asarray(simple.coords)[:-1]
        d_in = pts - np.roll(pts, 1, axis=0)
        d_out = np.roll(pts, -1, axis=0) - pts
        cross = d_in[:, 0] * d_out[:, 1] - d_in[:, 1] * d_out[:, 0]
        turn = np.degrees(np.arctan2(cross, (d_in * d_out).sum(1)))
        sharp = np.abs(turn) > min_deg
        return arc_position(self, pts[sharp]), turn[sharp]

    def turning_points(self) -> np.ndarray:
        """Arc positions of the file's turn points. A CAD that marks a few (the corners and
        where seams end) is taken at its word; one that marks many more than the line has
        corners (AccuMark marks every vertex of its digitised lines) only where the line
        really turns, by more than :data:`TURN_DEG` over :data:`TURN_SPAN_MM` either side."""
        s = arc_position(self, self.turns)
        distinct = np.unique(np.round(s / MERGE_MM))
        if len(distinct) <= DENSE_TURNS * (len(self.corners()[0]) + 2):
            return s
        before = point_at(self, s) - point_at(self, s - TURN_SPAN_MM)
        after = point_at(self, s + TURN_SPAN_MM) - point_at(self, s)
        cross = before[:, 0] * after[:, 1] - before[:, 1] * after[:, 0]
        turn = np.degrees(np.abs(np.arctan2(cross, (before * after).sum(1))))
        return s[turn > TURN_DEG]

    def notch_groups(self, without: np.ndarray | tuple = ()) -> list[tuple[float, int]]:
        """(arc position, notch count) of each notch group along the line, the notches
        within :data:`MERGE_MM` of the arc positions ``without`` left out (a dart's mouth)."""
        s = np.sort(arc_position(self, self.notches))
        s = s[np.diff(s, prepend=-np.inf) > SAME_NOTCH_MM]  # a notch on a fold, unfolded,
        # is there twice
        for v in np.asarray(without, float).reshape(-1):
            d = np.abs(s - v % self.length)
            d = np.minimum(d, self.length - d)
            if len(s) and d.min() <= MERGE_MM:
                s = np.delete(s, int(np.argmin(d)))
        groups: list[list[float]] = []
        for v in s.tolist():
            if groups and v - groups[-1][-1] <= NOTCH_GROUP_MM:
                groups[-1].append(v)
            else:
                groups.append([v])
        if len(groups) > 1 and groups[0][0] + self.length - groups[-1][-1] <= NOTCH_GROUP_MM:
            groups[0] = groups.pop() + groups[0]
        # each group at its middle: a double notch read from the other side of its seam
        # (backwards) is at the same place (a group across the loop's start wraps)
        return [(float(0.5 * (g[0] + g[-1] + (self.length if g[-1] < g[0] else 0.0))
                       % self.length), len(g)) for g in groups]

    def darts(self) -> list[tuple[float, float]]:
        """Arc spans (mouth, mouth) of the line's darts: a tip (a reflex corner sharper than
        :data:`DART_TIP_DEG`) between two legs of one length, each leg running from the tip
        to the next breakpoint. The span's end may pass the loop's length (it wraps)."""
        pos, turn = self.corners(DART_TIP_DEG)
        cuts = self.breakpoints()
        out = []
        for tip in pos[turn < 0].tolist():
            k = int(np.argmin(np.abs(np.mod(cuts - tip + self.length / 2, self.length)
                                     - self.length / 2)))
            legs = ((cuts[k] - cuts[k - 1]) % self.length,
                    (cuts[(k + 1) % len(cuts)] - cuts[k]) % self.length)
            if len(cuts) >= 3 and min(legs) >= MIN_LEG_MM and \
                    abs(legs[0] - legs[1]) <= DART_LEGS * max(legs):
                start = float(cuts[k - 1])
                out.append((start, start + legs[0] + legs[1]))
        return out

    def breakpoints(self) -> np.ndarray:
        """Sorted arc positions where the line is split: corners, notches, turn points; of
        several within :data:`MERGE_MM`, the first of that order (a seam ends at the corner
        itself, not at a turn point a millimetre or two beside it)."""
        notch = [s for s, _ in self.notch_groups()]
        raw = [self.corners()[0], notch, self.turning_points(),
               [0.0] if not len(self.turns) and not len(notch) else []]
        keep = np.zeros(0)
        for v in np.mod(np.concatenate(raw), self.length).tolist():
            d = np.abs(keep - v)
            if not len(keep) or np.minimum(d, self.length - d).min() > MERGE_MM:
                keep = np.append(keep, v)
        return np.sort(keep)


def arc_position(piece: SewPiece, points: np.ndarray) -> np.ndarray:
    """Arc position (mm from the loop's start, CCW) of the loop point nearest each point."""
    points = np.asarray(points, float).reshape(-1, 2)
    if not len(points):
        return np.zeros(0)
    a = piece.loop
    ab = np.roll(a, -1, axis=0) - a
    t = np.clip(np.einsum("pkj,kj->pk", points[:, None] - a[None], ab)
                / np.maximum((ab * ab).sum(1), 1e-300), 0, 1)
    foot = a[None] + t[..., None] * ab[None]
    seg = np.argmin(((foot - points[:, None]) ** 2).sum(-1), axis=1)
    seg_len = np.diff(piece.cum)
    return piece.cum[seg] + t[np.arange(len(points)), seg] * seg_len[seg]


def point_at(piece: SewPiece, s: np.ndarray) -> np.ndarray:
    """(k,2) loop points at arc positions ``s`` (taken modulo the length)."""
    s = np.mod(np.asarray(s, float), piece.length)
    k = np.clip(np.searchsorted(piece.cum, s, side="right") - 1, 0, len(piece.loop) - 1)
    seg = np.maximum(np.diff(piece.cum)[k], 1e-300)
    a, b = piece.loop[k], np.roll(piece.loop, -1, axis=0)[k]
    return a + ((s - piece.cum[k]) / seg)[:, None] * (b - a)


def sub_loop(piece: SewPiece, start: float, end: float) -> np.ndarray:
    """The loop's polyline from arc position ``start`` to ``end`` (CCW, may wrap)."""
    end = end if end > start else end + piece.length
    inner = []
    for lap in (0.0, piece.length):
        c = piece.cum[:-1] + lap
        inner.append(c[(c > start) & (c < end)])
    s = np.concatenate([[start], *inner, [end]])
    return point_at(piece, s)


def sewn_line(piece: SewPiece, start: float, end: float,
              skips: tuple[tuple[float, float], ...] = ()) -> np.ndarray:
    """The loop's polyline from ``start`` to ``end`` as sewn with the darts ``skips`` (arc
    spans inside the interval, sorted) closed: the line after each dart turned about its tip
    so that the dart's far mouth lands on its near one."""
    bounds = [start, *[v for span in skips for v in span], end]
    parts = [sub_loop(piece, bounds[k], bounds[k + 1]) for k in range(0, len(bounds), 2)]
    rot, shift = np.eye(2), np.zeros(2)  # the motion of what follows the darts closed so far
    out = [parts[0]]
    for (d0, d1), part in zip(skips, parts[1:], strict=True):
        near, tip, far = point_at(piece, np.array([d0, 0.5 * (d0 + d1), d1])) @ rot.T + shift
        u, v = near - tip, far - tip
        ang = np.arctan2(v[0] * u[1] - v[1] * u[0], float(u @ v))
        turn = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
        rot, shift = turn @ rot, turn @ (shift - far) + near
        out.append((part @ rot.T + shift)[1:])
    return np.vstack(out)
