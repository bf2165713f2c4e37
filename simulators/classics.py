"""Textile classics with their true symmetry groups, as :class:`~simulators.fabric.Print`.

The groups were not taken on trust: each pattern is built from its construction
(colour order of warp and weft, weave, or drawing) and the group below is the one the
construction has, confirmed on the rendered images by ``tests/simulators/test_fabric.py``
(every operation of the group gives correlation ~1, every other isometry of the lattice
clearly less). Facts that surprise:

- ``houndstooth`` woven the classic way (2/2 twill, four dark and four light threads in
  warp and weft) is **p1**: the twill steps of the "claws" are offset by half a twill
  period between the two sides of a tooth, which breaks the diagonal mirror and the
  half-turn one might expect from the outline (an exhaustive search over all
  isometries of the thread grid finds none; its only colour-swapping symmetry is the
  translation by four threads along both axes).
- ``herringbone`` twill (2/2 twill whose direction reverses every 6 warp threads) is
  **pmg**: mirrors at the reversals, glides along the warp direction (found by the same
  exhaustive search; parquet herringbone of interlocking bricks is another pattern).
- ``tartan`` with a symmetric sett, the same in warp and weft, rendered as its printed
  look (warp and weft colours mixed) is **p4m**; ``plaid`` with different symmetric
  setts in warp and weft is **pmm**.
- ``gingham`` (a two-colour even check) is **p4m**; polka dots on a square grid are p4m,
  on a hexagonal grid p6m; uniform ``diamonds`` (harlequin) on a rhombic lattice are
  **cmm**.
- A *woven* gingham (``woven_check``: yarn-dyed, each crossing shows the warp or the
  weft thread's colour in the weave's order) is not p4m at thread scale. In plain
  weave a quarter turn or a diagonal mirror swaps warp-up and weft-up crossings where
  a coloured thread crosses a white one, so its exact group is pmm (odd threads per
  band) or p4 (even); a 2/2 twill's diagonal breaks every mirror. It was designed
  p4m, and reads so once the yarn is smoothed away.
- ``stripes`` repeat in one direction only: a frieze, reported as
  :class:`~simulators.fabric.Frieze` (p11m for an asymmetric colour order), never as a
  lattice.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from simulators.fabric import Frieze, Print
from solver.wallpaper import Wallpaper

__all__ = ["CLASSICS", "CLASSIC_GROUPS", "classic_print", "woven_check"]

CLASSIC_GROUPS: dict[str, str] = {
    "stripes": "p11m (frieze)",
    "gingham": "p4m",
    "tartan": "p4m",
    "plaid": "pmm",
    "houndstooth": "p1",
    "herringbone": "pmg",
    "polka-square": "p4m",
    "polka-hex": "p6m",
    "diamonds": "cmm",
}
CLASSICS: tuple[str, ...] = tuple(CLASSIC_GROUPS)

# BGR colours in [0, 1].
_NAVY = (0.32, 0.12, 0.06)
_GREEN = (0.18, 0.36, 0.08)
_BLACK = (0.08, 0.08, 0.09)
_RED = (0.14, 0.12, 0.70)
_YELLOW = (0.20, 0.78, 0.88)
_WHITE = (0.93, 0.95, 0.96)
_CREAM = (0.80, 0.90, 0.95)
_BROWN = (0.12, 0.20, 0.34)


def _wrap(u: np.ndarray) -> np.ndarray:
    """Fractional coordinate -> [-0.5, 0.5)."""
    return u - np.floor(u + 0.5)


def _supersampled(fn: Callable[[np.ndarray, np.ndarray], np.ndarray], m: int,
                  ss: int = 4) -> np.ndarray:
    """(m, m, 3) box-filtered samples of ``fn(u, v) -> (..., 3)`` at (col/m, row/m).

    The sub-sample offsets are symmetric about each sample, so a pattern edge that
    falls exactly on a sample is averaged, not decided by floating-point rounding.
    """
    base = np.arange(m) / m
    out = np.zeros((m, m, 3), np.float64)
    offs = ((np.arange(ss) + 0.5) / ss - 0.5) / m
    for dv in offs:
        for du in offs:
            u, v = np.meshgrid(base + du, base + dv)
            out += fn(u, v)
    return (out / (ss * ss)).astype(np.float32)


def _stripe_profile(bands: list[tuple[tuple[float, float, float], float]]):
    """Colour along s in [0, 1) from (colour, width) bands, widths summing to 1."""
    edges = np.cumsum([w for _, w in bands])
    cols = np.array([c for c, _ in bands], np.float64)

    def profile(s: np.ndarray) -> np.ndarray:
        idx = np.searchsorted(edges, np.mod(s, 1.0), side="right")
        return cols[np.minimum(idx, len(cols) - 1)]

    return profile


def _sett(half: list[tuple[tuple[float, float, float], float]]):
    """Colour of a reflective sett at fractional s: ``half`` fills [0, 1/2] (widths sum
    to 1/2) and is mirrored about the pivots at 0 and 1/2."""
    prof = _stripe_profile([(c, 2.0 * w) for c, w in half])
    return lambda s: prof(2.0 * np.abs(_wrap(s)))


def _weave(warp: np.ndarray, weft: np.ndarray, up: np.ndarray) -> np.ndarray:
    """(n, n, 3) colours of a woven cell: warp shows where ``up`` else weft.

    ``warp`` colours are indexed by the thread across (column, u), ``weft`` by row (v).
    """
    return np.where(up[..., None], warp[None, :, :], weft[:, None, :])


def _thread_texture(cell: np.ndarray,
                    shift: tuple[float, float] = (0.0, 0.0)) -> Callable[[int], np.ndarray]:
    """Texture function of a thread grid (rows = v, cols = u), one flat colour per
    crossing, box-supersampled so thread edges are exact. ``shift`` (fractional) is
    where the texture's origin lies in the thread grid."""
    rows, cols = cell.shape[:2]

    def fn(u, v):
        i = np.floor(np.mod(u + shift[0], 1.0) * cols).astype(int) % cols
        j = np.floor(np.mod(v + shift[1], 1.0) * rows).astype(int) % rows
        return cell[j, i]

    return lambda m: _supersampled(fn, m)


def _rot(deg: float) -> np.ndarray:
    r = math.radians(deg)
    return np.array([[math.cos(r), -math.sin(r)], [math.sin(r), math.cos(r)]])


@dataclass(frozen=True)
class _Placement:
    """Where a classic lies: its turn, its symmetry origin (mm) and its repeat (mm)."""

    rot: np.ndarray
    origin: np.ndarray
    repeat: float

    def wallpaper(self, group: str, w1, w2) -> Wallpaper:
        return Wallpaper(group, self.rot @ np.asarray(w1, float), self.rot @ np.asarray(w2, float),
                         self.origin)


def classic_print(name: str, repeat: float = 40.0, *, rotation: float = 0.0,
                  origin: tuple[float, float] = (0.0, 0.0)) -> Print:
    """A textile classic (see :data:`CLASSICS`) with repeat ``|w1| = repeat`` mm.

    ``rotation`` turns the print (degrees, mathematical sense in x/y); ``origin`` is
    where the cell's symmetry origin (the group table's origin) lies, in mm.
    """
    if name not in CLASSIC_GROUPS:
        raise ValueError(f"unknown classic {name!r}; expected one of {', '.join(CLASSICS)}")
    if not repeat > 0:
        raise ValueError(f"repeat must be positive, got {repeat}")
    place = _Placement(_rot(rotation), np.asarray(origin, float), float(repeat))
    return _BUILDERS[name](name, place)


def _stripes(name: str, place: _Placement) -> Print:
    r, rot, o = place.repeat, place.rot, place.origin
    prof = _stripe_profile([(_NAVY, 0.34), (_WHITE, 0.18), (_RED, 0.08), (_WHITE, 0.1),
                            (_YELLOW, 0.05), (_CREAM, 0.25)])
    w1 = rot @ np.array([r, 0.0])
    basis = np.column_stack([w1, rot @ np.array([0.0, r])])
    truth = Frieze("p11m", w1, o.copy())
    return Print(name, truth, lambda m: _supersampled(lambda u, v: prof(u), m),
                 basis=basis, origin=o.copy())


def _gingham(name: str, place: _Placement) -> Print:
    r = place.repeat
    col = np.array(_RED)
    white = np.array(_WHITE)
    mid = 0.5 * (col + white)
    dark = col * 0.75

    def fn(u, v):
        bu = (np.abs(_wrap(u)) < 0.25)[..., None]
        bv = (np.abs(_wrap(v)) < 0.25)[..., None]
        return np.where(bu & bv, dark, np.where(bu | bv, mid, white))

    return Print(name, place.wallpaper("p4m", (r, 0), (0, r)), lambda m: _supersampled(fn, m))


def _tartan(name: str, place: _Placement) -> Print:
    """Tartan (the same sett in warp and weft) or plaid (another sett in the weft)."""
    r = place.repeat
    warp = _sett([(_NAVY, 0.13), (_BLACK, 0.05), (_GREEN, 0.16), (_BLACK, 0.03),
                  (_GREEN, 0.05), (_BLACK, 0.02), (_YELLOW, 0.01), (_BLACK, 0.05)])
    if name == "tartan":
        weft, ratio, group = warp, 1.0, "p4m"
    else:
        weft = _sett([(_RED, 0.17), (_BLACK, 0.04), (_CREAM, 0.02), (_BLACK, 0.04),
                      (_BROWN, 0.15), (_BLACK, 0.08)])
        ratio, group = 0.75, "pmm"
    return Print(name, place.wallpaper(group, (r, 0), (0, r * ratio)),
                 lambda m: _supersampled(lambda u, v: 0.5 * (warp(u) + weft(v)), m))


def _houndstooth(name: str, place: _Placement) -> Print:
    r = place.repeat
    n = 8
    block = (np.arange(n) % 8 < 4)
    dark, light = np.array(_BLACK), np.array(_CREAM)
    threads = np.where(block[:, None], dark, light)
    i, j = np.meshgrid(np.arange(n), np.arange(n))  # i across (u), j down (v)
    up = (i + j) % 4 < 2  # 2/2 twill
    return Print(name, place.wallpaper("p1", (r, 0), (0, r)),
                 _thread_texture(_weave(threads, threads, up)))


def _herringbone(name: str, place: _Placement) -> Print:
    r = place.repeat
    n = 6  # warp threads per twill direction; cell = 2n threads x 4 picks
    p = r / (2 * n)
    i, j = np.meshgrid(np.arange(2 * n), np.arange(4))
    s = np.where(i < n, 1, -1)
    up = (j + s * i) % 4 < 2
    warp = np.tile(np.array(_BROWN), (2 * n, 1))
    weft = np.tile(np.array(_CREAM), (4, 1))
    # The half-turn centre (3.5, 2) threads is the pmg origin; mirrors then lie at
    # the twill reversals (0.5 and 6.5 threads), glide lines along the warp axis.
    return Print(name, place.wallpaper("pmg", (r, 0), (0, 4 * p)),
                 _thread_texture(_weave(warp, weft, up), shift=(3.5 / (2 * n), 2 / 4)))


def _polka(name: str, place: _Placement) -> Print:
    """Polka dots on a square (p4m) or hexagonal (p6m) grid."""
    r = place.repeat
    hexagonal = name == "polka-hex"
    w2 = r * np.array([-0.5, math.sqrt(3) / 2]) if hexagonal else np.array([0.0, r])
    wp = place.wallpaper("p6m" if hexagonal else "p4m", (r, 0), w2)
    basis = np.column_stack([np.array([r, 0.0]), w2])
    dot, ground = np.array(_WHITE), np.array(_NAVY)
    radius = 0.3 * r

    def fn(u, v):
        best = np.full(u.shape, np.inf)
        fu, fv = _wrap(u), _wrap(v)
        for a in (-1, 0, 1):  # nearest lattice point among the neighbours
            for b in (-1, 0, 1):
                x = (fu + a) * basis[0, 0] + (fv + b) * basis[0, 1]
                y = (fu + a) * basis[1, 0] + (fv + b) * basis[1, 1]
                best = np.minimum(best, np.hypot(x, y))
        return np.where((best < radius)[..., None], dot, ground)

    return Print(name, wp, lambda m: _supersampled(fn, m))


def _diamonds(name: str, place: _Placement) -> Print:
    """Uniform outlined diamonds on a rhombic (centred rectangular) lattice."""
    r = place.repeat
    half = math.radians(34.0)  # half-angle of the diamond at its top vertex
    w1 = r * np.array([math.sin(half), math.cos(half)])
    w2 = r * np.array([-math.sin(half), math.cos(half)])
    fill, line, ground = np.array(_GREEN), np.array(_YELLOW), np.array(_CREAM)

    def fn(u, v):
        d = np.maximum(np.abs(_wrap(u)), np.abs(_wrap(v)))
        return np.where((d < 0.33)[..., None], fill,
                        np.where((d < 0.41)[..., None], ground, line))

    return Print(name, place.wallpaper("cmm", w1, w2), lambda m: _supersampled(fn, m))


_BUILDERS: dict[str, Callable[[str, _Placement], Print]] = {
    "stripes": _stripes,
    "gingham": _gingham,
    "tartan": _tartan,
    "plaid": _tartan,
    "houndstooth": _houndstooth,
    "herringbone": _herringbone,
    "polka-square": _polka,
    "polka-hex": _polka,
    "diamonds": _diamonds,
}


def woven_check(repeat: float = 10.0, threads: int = 10, *, weft_threads: int | None = None,
                rotation: float = 0.0, shade: float = 0.0, weave: str = "plain",
                colour: tuple[float, float, float] = _RED) -> Print:
    """A yarn-dyed check: ``threads`` coloured then ``threads`` white threads repeat in
    the warp, and ``weft_threads`` coloured (default: as many) in the weft's repeat of
    the same ``2 * threads`` picks, woven in ``weave`` ("plain", or "twill": 2/2); each
    crossing shows the thread on top. ``shade`` makes the warp that much brighter and
    the weft darker (their sheen differs). The truth is the group it was designed with:
    a gingham (p4m) when warp and weft bands match, else an uneven check (pmm); at
    thread scale it has less (see the module's notes)."""
    n = 2 * threads
    weft_threads = threads if weft_threads is None else int(weft_threads)
    if threads < 1 or not 0 < weft_threads < n:
        raise ValueError(f"need 1 <= threads and 0 < weft_threads < {n}, got "
                         f"{threads}, {weft_threads}")
    if weave not in ("plain", "twill"):
        raise ValueError(f"unknown weave {weave!r}; expected plain or twill")
    col, white = np.array(colour), np.array(_WHITE)
    warp = np.where((np.arange(n) < threads)[:, None], col, white) * (1.0 + shade)
    weft = np.where((np.arange(n) < weft_threads)[:, None], col, white) * (1.0 - shade)
    i, j = np.meshgrid(np.arange(n), np.arange(n))
    up = (i + j) % 2 == 0 if weave == "plain" else (i + j) % 4 < 2
    cell = np.clip(_weave(warp, weft, up), 0.0, 1.0)
    rot = _rot(rotation)
    group = "p4m" if weft_threads == threads else "pmm"
    wp = Wallpaper(group, rot @ np.array([repeat, 0.0]), rot @ np.array([0.0, repeat]),
                   np.zeros(2))
    # The designed mirrors run through the middle of each band.
    return Print(f"woven-{group}", wp,
                 _thread_texture(cell, shift=(threads / (2 * n), weft_threads / (2 * n))))
