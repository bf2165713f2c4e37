"""An outside reference for the group decision: line drawings replicated by the npm
package ``wallpaper-groups`` 1.0.3 (MIT, github eskimoblood/wallpaper-groups).

The package is evaluation only: it is installed by ``make bench`` into ``bench/.npm``
(git-ignored), called through ``bench/npm_wallpaper.js``, and never copied in. Nobody
here wrote its geometry, which is why it is worth having; for the same reason its
labels are not trusted. Every pattern's group and lattice are *measured* on the
package's own line segments, colours included, by ``simulators.lineart.symmetry_of``
(exact isometries: every segment of the pattern's interior must land on a segment of
the same stroke) and the measured group is the truth. What that found, on every
type (see BENCHMARKS.md):

- the 16 types are p1, p2, pm, pg, cm, p2mm, p2mg, p2gg, c2mm, p4, p4mm, p4mg, p3,
  p3m1, p31m, p6 (no p6m, no pgg): ``p2mm``, ``p2mg``, ``c2mm``, ``p4mm``, ``p4mg``
  are our pmm, pmg, cmm, p4m, p4g;
- ``p2gg`` is not pgg: it is a half turn on a centred lattice, i.e. p2 (no glide);
- ``p4``, ``p4mm``, ``p4mg`` turn a quarter about (width, height) on a 2 width x 2
  height lattice: only with width == height are they p4, p4m, p4g (else all three are p2);
- cells are larger than the drawn tile (pm, p2: width x 2 height; pg: 2 width x
  height; p2mm, p2mg, p4*: doubled both ways; cm, p2gg, c2mm, p31m, p6: centred rows;
  p3, p3m1: hexagonal with side sqrt(3) width).

The drawing (ours, OpenCV): random polylines in the package's tile, a colour and a
width per line, the whole pattern scaled and turned, then blur, noise and JPEG; or, as a
generator writes its PNG, a tile of whole pixels, not turned, no camera, half of them
without anti-aliasing (``as_written``).
"""

from __future__ import annotations

import json
import math
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from simulators.lineart import degrade, draw_lines, symmetry_of

HERE = Path(__file__).resolve().parent
NPM_DIR = HERE / ".npm"
SCRIPT = HERE / "npm_wallpaper.js"
TYPES = ("p1", "p2", "pm", "pg", "cm", "p2mm", "p2mg", "p2gg", "c2mm", "p4", "p4mm",
         "p4mg", "p3", "p3m1", "p31m", "p6")
#: Types whose quarter turn needs a square tile (see the module text).
SQUARE = ("p4", "p4mm", "p4mg")
MM_PER_PX = 0.25


def unavailable() -> str | None:
    """Why the source cannot run here (None when it can)."""
    if shutil.which("node") is None:
        return "node is not installed"
    if not (NPM_DIR / "node_modules" / "wallpaper-groups").is_dir():
        return f"the npm package is not installed in {NPM_DIR} (make bench installs it)"
    return None


def call_package(requests: list[dict]) -> list[dict]:
    """The package's patterns for ``requests`` (its own arguments; lines as [x, y])."""
    out = subprocess.run(["node", str(SCRIPT), str(NPM_DIR)], check=True,
                         input=json.dumps({"requests": requests}), capture_output=True,
                         text=True, timeout=120)
    return json.loads(out.stdout)["patterns"]


# ---------------------------------------------------------------- requests, drawings
def _request(kind: str, rng: np.random.Generator) -> dict:
    width = 1.0
    height = width if kind in SQUARE else width * math.exp(rng.uniform(-0.5, 0.5))
    return {"type": kind, "width": width, "height": height}


def _motif(tile: np.ndarray, rng: np.random.Generator) -> list[list[list[float]]]:
    """2-4 random polylines (2-3 points) inside the tile's bounding box."""
    lo, hi = tile.min(0), tile.max(0)
    return [(lo + rng.uniform(0, 1, (int(rng.integers(2, 4)), 2)) * (hi - lo)).tolist()
            for _ in range(int(rng.integers(2, 5)))]


def draw(lines: list, n_motif: int, basis: np.ndarray, rng: np.random.Generator,
         size: tuple[int, int] = (800, 600)) -> tuple[np.ndarray, np.ndarray]:
    """The pattern drawn by OpenCV (a colour and width per motif line, scale, turn,
    blur, noise, JPEG); returns the BGR image and the lattice basis in its pixels."""
    w, h = size
    pts = [np.asarray(line, float) for line in lines]
    allp = np.concatenate(pts)
    centre = (allp.min(0) + allp.max(0)) / 2
    repeats = math.exp(rng.uniform(math.log(4), math.log(16)))
    scale = w / repeats / math.sqrt(abs(np.linalg.det(basis)))
    turn = rng.uniform(0, 2 * math.pi)
    rot = scale * np.array([[math.cos(turn), -math.sin(turn)],
                            [math.sin(turn), math.cos(turn)]])
    background = rng.uniform(0, 255, 3)
    colours = [rng.uniform(0, 255, 3) for _ in range(n_motif)]
    while min(np.abs(c - background).max() for c in colours) < 60:
        background = rng.uniform(0, 255, 3)
    widths = [rng.uniform(0.01, 0.06) * scale for _ in range(n_motif)]
    layers = [([(p - centre) @ rot.T + (w / 2, h / 2) for p in pts[k::n_motif]],
               tuple(colours[k]), widths[k]) for k in range(n_motif)]
    img = draw_lines(layers, size, 1.0, tuple(background))
    return degrade(img, rng), rot @ basis


def draw_as_written(lines: list, n_motif: int, basis: np.ndarray, tile_px: int,
                    rng: np.random.Generator, anti_alias: bool,
                    size: tuple[int, int] = (800, 600)) -> tuple[np.ndarray, np.ndarray]:
    """The pattern as a generator writes its PNG: the package's tile ``tile_px`` whole
    pixels wide, not turned, no camera; strokes anti-aliased, or with their points
    rounded to whole pixels and drawn without (the hard-edged drawings of many
    programs). Returns the BGR image and the lattice basis in its pixels."""
    w, h = size
    background = rng.uniform(0, 255, 3)
    colours = [rng.uniform(0, 255, 3) for _ in range(n_motif)]
    while min(np.abs(c - background).max() for c in colours) < 60:
        background = rng.uniform(0, 255, 3)
    widths = [rng.uniform(0.02, 0.06) * tile_px for _ in range(n_motif)]
    pts = [np.asarray(line, float) * tile_px for line in lines]
    if anti_alias:
        layers = [(pts[k::n_motif], tuple(colours[k]), widths[k]) for k in range(n_motif)]
        return draw_lines(layers, size, 1.0, tuple(background)), basis * tile_px
    img = np.empty((h, w, 3), np.uint8)
    img[:] = np.clip(np.rint(background), 0, 255).astype(np.uint8)
    for k in range(n_motif):
        cv2.polylines(img, [np.rint(p).astype(np.int32) for p in pts[k::n_motif]], False,
                      tuple(float(v) for v in colours[k]), max(1, round(widths[k])),
                      cv2.LINE_8)
    return img, basis * tile_px


def patterns(per_type: int, seed: int = 0, types: tuple[str, ...] = TYPES, first: int = 0,
             as_written: bool = False) -> Iterator[tuple[str, str, np.ndarray, np.ndarray]]:
    """(package type, measured group, image, lattice basis in mm) per pattern: patterns
    ``first`` to ``first + per_type - 1`` of each type (the same whatever is asked);
    ``as_written``: drawn by :func:`draw_as_written` (every other one anti-aliased)
    instead of :func:`draw`."""
    rngs, requests, motifs, tiles_px = [], [], [], []
    for kind in types:
        for k in range(first, first + per_type):
            rng = np.random.default_rng(seed + 4241 * TYPES.index(kind) + k)
            req = _request(kind, rng)
            if as_written:
                # A tile of whole pixels both ways (the package's height is relative).
                tile_px = int(rng.integers(24, 72))
                req["height"] = max(1, round(req["height"] * tile_px)) / tile_px
                tiles_px.append(tile_px)
            rngs.append(rng)
            requests.append(req)
    tiles = [np.asarray(p["tile"], float) for p in call_package(
        [dict(r, columns=1, rows=1, lines=[[[0, 0], [0.1, 0.1]]]) for r in requests])]
    for req, tile, rng in zip(requests, tiles, rngs, strict=True):
        motifs.append(_motif(tile, rng))
        # Enough copies that the middle of the drawing is covered whatever the turn.
        req.update(columns=26, rows=26, lines=motifs[-1])
    for index, (req, motif, rng, pat) in enumerate(zip(requests, motifs, rngs,
                                                       call_package(requests), strict=True)):
        group, basis = symmetry_of(pat["lines"],
                                   labels=[k % len(motif) for k in range(len(pat["lines"]))])
        if as_written:
            img, px = draw_as_written(pat["lines"], len(motif), basis, tiles_px[index],
                                      rng, anti_alias=index % 2 == 1)
        else:
            img, px = draw(pat["lines"], len(motif), basis, rng)
        yield req["type"], group, img, px * MM_PER_PX
