"""An outside reference for the group decision: line drawings replicated by the npm
package ``wallpaper-groups`` 1.0.3 (MIT, github eskimoblood/wallpaper-groups).

The package is evaluation only: it is installed by ``make bench`` into ``bench/.npm``
(git-ignored), called through ``bench/npm_wallpaper.js``, and never copied in. Nobody
here wrote its geometry, which is why it is worth having; for the same reason its
labels are not trusted. Every pattern's group and lattice are *measured* on the
package's own line segments by :func:`measured_group` (exact isometries: every
segment of the pattern's interior must land on a segment) and the measured group is
the truth. What that found, on every type (see BENCHMARKS.md):

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
width per line, the whole pattern scaled and turned, then blur, noise and JPEG.
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
from scipy.spatial import cKDTree

from solver.wallpaper import gauss_reduce

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


# ---------------------------------------------------------------- the measured truth
def _keys(segs: np.ndarray) -> np.ndarray:
    """Segment (m, 2, 2) -> a key independent of the endpoints' order: the midpoint
    and the doubled-angle direction times the length."""
    mid = segs.mean(axis=1)
    d = segs[:, 1] - segs[:, 0]
    return np.column_stack([mid, d[:, 0] ** 2 - d[:, 1] ** 2, 2 * d[:, 0] * d[:, 1]])


def _isometries(a, b, a2, b2) -> list[tuple[np.ndarray, np.ndarray]]:
    """The proper and the improper isometry taking points a, b to a2, b2."""
    u, v = b - a, b2 - a2
    t0, t1 = math.atan2(u[1], u[0]), math.atan2(v[1], v[0])
    rot = lambda t: np.array([[math.cos(t), -math.sin(t)], [math.sin(t), math.cos(t)]])  # noqa: E731
    out = []
    for lin in (rot(t1 - t0), rot(t1) @ np.diag([1.0, -1.0]) @ rot(-t0)):
        out.append((lin, a2 - lin @ a))
    return out


def measured_group(lines: list, tol: float = 1e-6) -> tuple[str, np.ndarray]:
    """The wallpaper group (our names) and reduced lattice basis (2, 2) of a pattern of
    polylines, from the isometries that take every segment near its centre onto a
    segment of the pattern (exact up to ``tol`` of the pattern's size)."""
    segs = np.array([[p, q] for line in lines for p, q in zip(line[:-1], line[1:],
                                                                strict=False)], float)
    lo, hi = segs.reshape(-1, 2).min(0), segs.reshape(-1, 2).max(0)
    c, span = (lo + hi) / 2, float((hi - lo).min())
    tol = tol * span
    tree = cKDTree(_keys(segs))
    dist = np.linalg.norm(segs.mean(axis=1) - c, axis=1)
    inner = segs[dist < 0.1 * span]
    length = np.linalg.norm(segs[:, 1] - segs[:, 0], axis=1)
    ref = int(np.argmin(np.where(length > 0.02 * length.max(), dist, np.inf)))
    same = np.flatnonzero((np.abs(length - length[ref]) < tol) & (dist < 0.15 * span))
    a, b = segs[ref]
    found = []
    for k in same:
        for a2, b2 in (segs[k], segs[k][::-1]):
            for lin, t in _isometries(a, b, a2, b2):
                moved = inner @ lin.T + t
                if tree.query(_keys(moved))[0].max() < tol * 10:
                    found.append((lin, t))
    trans = sorted((t for lin, t in found if np.allclose(lin, np.eye(2), atol=1e-6)
                    and np.hypot(*t) > tol), key=lambda t: np.hypot(*t))
    w1 = trans[0]
    w2 = next(t for t in trans if abs(w1[0] * t[1] - w1[1] * t[0]) > tol * span)
    u1, u2, _ = gauss_reduce(w1, w2)
    basis = np.column_stack([u1, u2])
    inv = np.linalg.inv(basis)
    on_lattice = lambda v: np.abs(inv @ v - np.rint(inv @ v)).max() < 1e-4  # noqa: E731
    classes: dict[tuple, tuple[bool, bool, np.ndarray]] = {}
    rotations = set()
    ij = [np.array([i, j]) for i in range(-2, 3) for j in range(-2, 3)]
    for lin, t in found:
        key = tuple(np.round(lin, 4).ravel())
        if np.linalg.det(lin) > 0:
            rotations.add(key)
            continue
        ev, vec = np.linalg.eigh((lin + lin.T) / 2)
        d = vec[:, np.argmax(ev)]
        parts = [((t + basis @ v) @ d) * d for v in ij]
        mirror = any(np.hypot(*g) < 1e-4 * span for g in parts)
        glide = any(not on_lattice(g) for g in parts)
        old = classes.get(key, (False, False, d))
        classes[key] = (old[0] or mirror, old[1] or glide, d)
    n, refl = len(rotations), list(classes.values())
    if n in (1, 2) and not refl:
        return ("p1", "p2")[n - 1], basis
    if n == 1:
        return {(True, False): "pm", (False, True): "pg"}.get(refl[0][:2], "cm"), basis
    if n == 2:
        kinds = sorted(r[:2] for r in refl)
        if kinds == [(True, True), (True, True)]:
            return "cmm", basis
        return {((True, False), (True, False)): "pmm", ((False, True), (False, True)): "pgg",
                ((False, True), (True, False)): "pmg"}[tuple(kinds)], basis
    if n == 4:
        return ("p4" if not refl else "p4m" if all(r[0] for r in refl) else "p4g"), basis
    if n == 6:
        return ("p6m" if refl else "p6"), basis
    if not refl:
        return "p3", basis
    d = refl[0][2]
    along = any(abs(d[0] * v[1] - d[1] * v[0]) < 1e-4 * np.hypot(*v)
                for v in (u1, u2, u1 + u2, u1 - u2))
    return ("p31m" if along else "p3m1"), basis


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
    """The pattern drawn by OpenCV (colours, line widths, scale, turn, blur, noise,
    JPEG); returns the BGR image and the lattice basis in its pixels."""
    w, h = size
    pts = [np.asarray(line, float) for line in lines]
    allp = np.concatenate(pts)
    centre = (allp.min(0) + allp.max(0)) / 2
    repeats = math.exp(rng.uniform(math.log(4), math.log(12)))
    scale = w / repeats / math.sqrt(abs(np.linalg.det(basis)))
    turn = rng.uniform(0, 2 * math.pi)
    rot = scale * np.array([[math.cos(turn), -math.sin(turn)],
                            [math.sin(turn), math.cos(turn)]])
    background = rng.uniform(0, 255, 3)
    colours = [rng.uniform(0, 255, 3) for _ in range(n_motif)]
    while min(np.abs(c - background).max() for c in colours) < 60:
        background = rng.uniform(0, 255, 3)
    img = np.empty((h, w, 3), np.uint8)
    img[:] = background.astype(np.uint8)
    thick = [max(1, int(round(rng.uniform(0.01, 0.05) * scale))) for _ in range(n_motif)]
    for k in range(n_motif):
        mine = [((p - centre) @ rot.T + (w / 2, h / 2)) * 16 for p in pts[k::n_motif]]
        cv2.polylines(img, [np.rint(p).astype(np.int32) for p in mine], False,
                      tuple(float(v) for v in colours[k]), thick[k], cv2.LINE_AA, shift=4)
    sigma = rng.uniform(0.0, 2.0)
    if sigma > 0.3:
        img = cv2.GaussianBlur(img, (0, 0), sigma)
    img = np.clip(img + rng.normal(0, rng.uniform(0, 6), img.shape), 0, 255).astype(np.uint8)
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, int(rng.uniform(60, 95))])
    return cv2.imdecode(buf, cv2.IMREAD_COLOR), rot @ basis


def patterns(per_type: int, seed: int = 0) -> Iterator[tuple[str, str, np.ndarray,
                                                             np.ndarray]]:
    """(package type, measured group, image, lattice basis in mm) per pattern."""
    rngs, requests, motifs = [], [], []
    for ti, kind in enumerate(TYPES):
        for k in range(per_type):
            rng = np.random.default_rng(seed + 4241 * ti + k)
            req = _request(kind, rng)
            rngs.append(rng)
            requests.append(req)
    tiles = [np.asarray(p["tile"], float) for p in call_package(
        [dict(r, columns=1, rows=1, lines=[[[0, 0], [0.1, 0.1]]]) for r in requests])]
    for req, tile, rng in zip(requests, tiles, rngs, strict=True):
        motifs.append(_motif(tile, rng))
        # Enough copies that the middle of the drawing is covered whatever the turn.
        req.update(columns=26, rows=26, lines=motifs[-1])
    for req, motif, rng, pat in zip(requests, motifs, rngs, call_package(requests),
                                    strict=True):
        group, basis = measured_group(pat["lines"])
        img, px = draw(pat["lines"], len(motif), basis, rng)
        yield req["type"], group, img, px * MM_PER_PX
