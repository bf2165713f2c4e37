"""The vision benchmark by group and by source, with the confusion table: every real
photograph in ``../shared`` and renderings of all 17 groups, of which three- and
six-fold prints under the conventions other generators draw them in.

Sources (``bench.vision`` holds the first five; each is reported on its own):

- ``photos-*``: the labelled photographs, read on their labelled region;
- ``frames``: the same photographs whole, as taken;
- ``renderings``: random prints of every group drawn on whole pixels, no camera;
- ``waves``: Farris's smooth wave prints of every group;
- ``npm-wallpaper-groups``, ``npm-as-written``: an outside generator's line drawings;
- ``hexagonal`` (here): prints of the five hexagonal groups and of near-hexagonal
  cmm, cm and p2 (rhombic cells of 58-64 degrees, side ratio up to 1.04, as lace
  grounds are) the ways other generators lay them out: the lattice turned at random,
  ``w1`` upright, or one rectangular tile of whole pixels drawn and repeated, which
  makes the hexagon a little off (its height rounded to a pixel) and rounds every
  tile's edges alike (:func:`tiled_hexagon`); with and without anti-aliasing, no
  camera. Evaluation only: no constant was picked on it.

    python -m bench vision_groups
    python -c "from bench.vision_groups import run; run(per_group=2)"
"""

from __future__ import annotations

import math
import platform
from collections import Counter
from datetime import date

import numpy as np

from bench.vision import Sample, evaluate, npm, npm_as_written, photos, renderings, waves
from simulators.fabric import Print, random_print, render_print, to_uint8
from solver.wallpaper import GROUP_NAMES

HEXAGONAL = ("p3", "p3m1", "p31m", "p6", "p6m")
NEAR_HEXAGONAL = ("cmm", "cm", "p2")
LAYOUTS = ("turned", "upright", "rounded tile")


def hexagon_basis(layout: str, repeat: float, rng: np.random.Generator) -> np.ndarray:
    """A hexagonal basis (columns w1, w2, px) laid out as ``layout`` says."""
    turn = {"turned": rng.uniform(0.0, 60.0), "upright": 90.0, "rounded tile": 0.0}[layout]
    a, b = math.radians(turn), math.radians(turn + 120.0)
    return repeat * np.array([[math.cos(a), math.cos(b)], [math.sin(a), math.sin(b)]])


def near_hexagon_basis(group: str, repeat: float, rng: np.random.Generator) -> np.ndarray:
    """A rhombic (cmm, cm) or oblique (p2) basis a few degrees and per cent off
    hexagonal, turned at random."""
    angle = math.radians(rng.uniform(58.0, 64.0))
    if group == "p2":
        w1 = np.array([1.0, 0.0])
        w2 = rng.uniform(1.01, 1.04) * np.array([math.cos(angle), math.sin(angle)])
    else:  # the rhombus of a centred rectangle, symmetric about the x axis
        w1 = np.array([math.cos(angle / 2), math.sin(angle / 2)])
        w2 = w1 * [1.0, -1.0]
    turn = math.radians(rng.uniform(0.0, 180.0))
    rot = np.array([[math.cos(turn), -math.sin(turn)], [math.sin(turn), math.cos(turn)]])
    return repeat * rot @ np.column_stack([w1, w2])


def tiled_hexagon(pr: Print, size: tuple[int, int], anti_alias: bool
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The hexagonal print ``pr`` (``w1`` along x, whole pixels) as a generator writes
    it: one rectangular tile of |w1| x round(|w1| sqrt 3) pixels drawn and repeated, so
    the hexagon is off by its height's rounding and every tile's edges are rounded to
    the pixels alike. Returns the image (BGR, ``size`` = (width, height)) and the
    lattice it repeats on (columns, px)."""
    w1, w2 = pr.wallpaper.w1, pr.wallpaper.w2
    width = round(float(w1[0]))
    height = round(2.0 * float(w2[1]))
    x, y = np.meshgrid(np.arange(width, dtype=float),
                       np.arange(height) * (2.0 * float(w2[1]) / height))
    tile = to_uint8(pr.colour_at(x, y, 1.0, anti_alias=anti_alias))
    reps = (-(-size[1] // height), -(-size[0] // width), 1)
    img = np.tile(tile, reps)[:size[1], :size[0]]
    return np.ascontiguousarray(img), np.diag([1.0, height / (2.0 * float(w2[1]))]) @ (
        pr.wallpaper.basis)


def hexagonal(per_group: int, seed: int = 0):
    """Three- and six-fold prints and near-hexagonal grounds (see the module text)."""
    for gi, group in enumerate(HEXAGONAL + NEAR_HEXAGONAL):
        for k in range(per_group):
            rng = np.random.default_rng(seed + 307 * gi + k + 3)
            repeat = float(rng.integers(24, 80))
            layout = LAYOUTS[k % len(LAYOUTS)] if group in HEXAGONAL else "turned"
            basis = (hexagon_basis(layout, repeat, rng) if group in HEXAGONAL
                     else near_hexagon_basis(group, repeat, rng))
            pr = random_print(group, w1=basis[:, 0], w2=basis[:, 1],
                              seed=int(rng.integers(1 << 30)))
            side = int(rng.integers(500, 1200))
            anti_alias = bool(rng.integers(2))
            if layout == "rounded tile":
                img, truth = tiled_hexagon(pr, (side, side * 3 // 4), anti_alias)
            else:
                img = render_print(pr, (side, side * 3 // 4), 1.0, anti_alias=anti_alias)
                truth = pr.wallpaper.basis
            yield Sample("hexagonal", f"{group}/{layout}/{repeat:.0f}px", img, 1.0, group,
                         basis=truth)


def _truth(s: Sample) -> str:
    return s.truth


def _answer(s: Sample) -> str:
    """What was read: a group, or plain/stripes."""
    return s.found["group"] or s.found["kind"]


def _row(name: str, rows: list[dict]) -> str:
    n = Counter(r["outcome"] for r in rows)
    lat = [r["lattice_ok"] for r in rows if r["lattice_ok"] is not None]
    return (f"| {name} | {len(rows)} | {n['right']} ({100 * n['right'] / len(rows):.0f} %) | "
            f"{sum(lat)}/{len(lat)} | {n['subgroup']} | {n['supergroup']} | {n['other']} | "
            f"{n['missed']} | {n['false lattice']} | "
            f"{np.median([r['sec'] for r in rows]):.2f} |")


def table(samples: list[Sample], key) -> str:
    """One row per value of ``key(sample)`` (a source, a true group): images, right
    (the group, its labelled alternative, or plain/stripes where there is no lattice),
    labelled lattices found, the errors, median seconds per image."""
    lines = ["| | images | right | lattice ok | subgroup | supergroup | other | missed | "
             "false lattice | s/image |", "|---" * 10 + "|"]
    for name in dict.fromkeys(key(s) for s in samples):
        lines.append(_row(name, [s.found for s in samples if key(s) == name]))
    return "\n".join(lines)


def confusion(samples: list[Sample]) -> str:
    """Rows: the truth; columns: what was read; a cell counts the images."""
    truths = [g for g in (*GROUP_NAMES, "plain", "stripes") if any(s.truth == g
                                                                   for s in samples)]
    answers = [g for g in (*GROUP_NAMES, "plain", "stripes")
               if any(_answer(s) == g for s in samples)]
    count = Counter((s.truth, _answer(s)) for s in samples)
    lines = ["| truth \\ read | " + " | ".join(answers) + " |",
             "|---" * (len(answers) + 1) + "|"]
    for t in truths:
        lines.append(f"| {t} | " + " | ".join(str(count[t, a]) if count[t, a] else "."
                                              for a in answers) + " |")
    return "\n".join(lines)


def run(per_group: int = 3, *, seed: int = 0, verbose: bool = True) -> dict:
    """Every real photograph, and renderings of all 17 groups from every generator."""
    makers = (photos, lambda: photos(whole=True), lambda: renderings(per_group, seed=seed),
              lambda: waves(per_group, seed=seed), lambda: npm(per_group, seed=seed),
              lambda: npm_as_written(per_group, seed=seed),
              lambda: hexagonal(per_group, seed=seed))
    samples = []
    for make in makers:
        for s in make():
            s.found = evaluate(s, with_baseline=False)
            samples.append(s)
            if verbose:
                f = s.found
                print(f"{s.source:11s} {s.name:30s} truth {s.truth:8s} -> {_answer(s):8s} "
                      f"{f['outcome']:13s} conf {f['conf']:.2f} lattice {f['lattice_ok']!s:5s}"
                      f" {f['sec']:.2f} s", flush=True)
    real = [s for s in samples if s.source.startswith("photos") or s.source == "frames"]
    drawn = [s for s in samples if s not in real]
    text = (f"## Vision by group and source (`python -m bench vision_groups`, "
            f"{date.today().isoformat()}, {platform.machine()}, {per_group} per group)\n\n"
            + table(samples, lambda s: s.source)
            + "\n\nReal photographs by group:\n\n" + table(real, _truth)
            + "\n\nReal photographs, confusion:\n\n" + confusion(real)
            + "\n\nRenderings by group:\n\n" + table(drawn, _truth)
            + "\n\nRenderings, confusion:\n\n" + confusion(drawn))
    print(text)
    return {"samples": samples, "markdown": text}


def main() -> None:
    run()
