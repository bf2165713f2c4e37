"""Printed fabrics with known symmetry: random prints of all 17 wallpaper groups.

A print is a colour texture on the primitive cell of its lattice, sampled in
*fractional* coordinates, so one texture serves any repeat size, lattice shape and
orientation: a pixel is rendered by mapping it to millimetres, then to fractional
coordinates (vectorised), then looking the texture up with wrap-around.

Why it is exact: the random motif is built in Fourier space on the reciprocal lattice
and symmetrised with the group's own operations from :mod:`solver.wallpaper` (the one
table of the project), so the print has the group's symmetries by construction and,
because the coefficients are random and complex, generically no others. Anti-aliasing
is analytic: the colour texture is low-passed with a Gaussian whose width is given in
millimetres (about half a pixel), applied on the reciprocal lattice, which is isotropic
and therefore keeps every symmetry. The textile classics live in
:mod:`simulators.classics` and use the same machinery.

Image convention used throughout the simulators: pixel ``(col, row)`` is centred on the
point ``offset + (col, row) * mm_per_px`` millimetres (OpenCV's integer pixel centres),
x to the right, y down.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from solver.wallpaper import GROUP_NAMES, GROUPS, Wallpaper

__all__ = [
    "Frieze",
    "Print",
    "lattice_for",
    "random_print",
    "render_print",
    "wave_print",
]

# Grid sizes of cell textures are multiples of this, so that every fractional
# translation of the group table (0, 1/2) and every thread grid of the classics lands
# on texture samples exactly.
_GRID_STEP = 24
_MIN_GRID, _MAX_GRID = 96, 2040
# Motif draws per print, and the accidental-symmetry score that ends the search early.
_MOTIF_TRIES, _MOTIF_ACCEPT = 12, 0.55


@dataclass(frozen=True)
class Frieze:
    """Ground truth of a one-dimensional repeat (stripes): not a wallpaper lattice.

    ``w1`` is the translation (mm, across the stripes); the pattern is constant along
    the perpendicular direction. ``group`` is the frieze group in IUC notation with the
    axis along ``w1`` ("p11m": mirror along the axis only; "p2mm": also mirrors across).
    """

    group: str
    w1: np.ndarray
    origin: np.ndarray

    @property
    def direction(self) -> np.ndarray:
        """Unit vector along the stripes (the continuous-translation direction)."""
        d = np.array([-self.w1[1], self.w1[0]])
        return d / np.hypot(*d) + 0.0  # + 0.0: no negative zeros in JSON

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": "frieze",
            "group": self.group,
            "w1": self.w1.tolist(),
            "direction": self.direction.tolist(),
            "origin": self.origin.tolist(),
            "units": "mm",
        }


class Print:
    """A printed fabric: a periodic colour texture on a cell, plus its ground truth.

    Parameters
    ----------
    name : str
        ``"random-p4m"``, ``"gingham"``, ...
    truth : Wallpaper or Frieze
        The exact symmetry of the print, in the fabric's millimetres.
    texture : callable
        ``texture(m) -> (m, m, 3) float32 BGR in [0, 1]``: the cell sampled at
        fractional coordinates ``(col / m, row / m)`` (col along ``basis[:, 0]``).
        ``m`` is always a multiple of 24.
    basis, origin : (2, 2), (2,) float arrays
        The rendering cell in mm (columns = cell vectors); for a wallpaper the truth's
        own ``w1, w2, origin``.
    """

    def __init__(self, name: str, truth: Wallpaper | Frieze,
                 texture: Callable[[int], np.ndarray],
                 basis: np.ndarray | None = None, origin: np.ndarray | None = None) -> None:
        self.name = name
        self.truth = truth
        if isinstance(truth, Wallpaper):
            basis, origin = truth.basis, truth.origin
        if basis is None or origin is None:
            raise ValueError("a frieze print needs an explicit rendering cell")
        self.basis = np.asarray(basis, float)
        self.origin = np.asarray(origin, float)
        self._basis_inv = np.linalg.inv(self.basis)
        self._texture = texture
        self._cache: dict[tuple[int, float], np.ndarray] = {}

    def __repr__(self) -> str:
        return f"Print({self.name!r}, {self.truth!r})"

    @property
    def wallpaper(self) -> Wallpaper | None:
        return self.truth if isinstance(self.truth, Wallpaper) else None

    def truth_dict(self) -> dict[str, Any]:
        """FABRIC.json fields of the truth (loadable by ``Wallpaper.from_dict``) + name."""
        d = self.truth.to_dict()
        d["print"] = self.name
        return d

    # ------------------------------------------------------------ sampling
    def grid_size(self, pixel_mm: float) -> int:
        """Texture samples per cell edge: finer than the pixels, a multiple of 24."""
        longest = float(np.max(np.hypot(*self.basis)))
        want = 1.5 * longest / max(pixel_mm, 1e-9)
        m = int(math.ceil(want / _GRID_STEP)) * _GRID_STEP
        return int(min(max(m, _MIN_GRID), _MAX_GRID))

    def filtered_texture(self, pixel_mm: float) -> np.ndarray:
        """The cell texture band-limited for pixels of ``pixel_mm`` (cached).

        The Gaussian (sigma = half a pixel, at least 0.6 texel to remove the texture's
        own staircase) is applied on the reciprocal lattice, where the Cartesian
        frequency of the integer harmonic k is ``B^-T k``: isotropic in millimetres,
        so every symmetry of the print survives the filtering.
        """
        m = self.grid_size(pixel_mm)
        texel = float(np.max(np.hypot(*self.basis))) / m
        sigma = max(0.5 * pixel_mm, 0.6 * texel)
        key = (m, round(sigma, 6))
        if key not in self._cache:
            base = np.asarray(self._texture(m), np.float32)
            k = np.fft.fftfreq(m, 1.0 / m)
            ku, kv = np.meshgrid(k, k)  # rows vary along v (w2), columns along u (w1)
            nu = np.stack([ku, kv], -1) @ self._basis_inv  # (m, m, 2) cycles per mm
            gain = np.exp(-2.0 * math.pi**2 * sigma**2 * np.einsum("...i,...i", nu, nu))
            spec = np.fft.fft2(base, axes=(0, 1)) * gain[..., None]
            tex = np.fft.ifft2(spec, axes=(0, 1)).real.astype(np.float32)
            if len(self._cache) >= 2:  # textures can be 50 MB: keep the last two
                self._cache.clear()
            self._cache[key] = np.clip(tex, 0.0, 1.0)
        return self._cache[key]

    def fractional(self, xy: np.ndarray) -> np.ndarray:
        """(..., 2) fabric mm -> (..., 2) fractional coordinates of the rendering cell."""
        return (np.asarray(xy) - self.origin) @ self._basis_inv.T

    def colour_at(self, x: np.ndarray, y: np.ndarray, pixel_mm: float, *,
                  anti_alias: bool = True) -> np.ndarray:
        """Colours (H, W, 3) float32 BGR in [0, 1] at fabric points (mm, (H, W) each).

        ``pixel_mm`` is the footprint of one output pixel on the fabric, which sets the
        anti-aliasing filter; without it (``anti_alias=False``) each point takes the
        colour of the texel it falls in, hard edges rounded to the pixels as a drawing
        program writes them.
        """
        if not anti_alias:
            return self._nearest(x, y, self.grid_size(pixel_mm))
        tex = self.filtered_texture(pixel_mm)
        m = tex.shape[0]
        # float32 is ample (table coordinates of 1 m carry 1e-4 mm) and twice as fast;
        # the cell index is removed before scaling to texels, so no precision is lost.
        inv = self._basis_inv.astype(np.float32)
        dx = np.asarray(x, np.float32) - np.float32(self.origin[0])
        dy = np.asarray(y, np.float32) - np.float32(self.origin[1])
        u = inv[0, 0] * dx + inv[0, 1] * dy
        v = inv[1, 0] * dx + inv[1, 1] * dy
        u -= np.floor(u)
        v -= np.floor(v)
        u *= np.float32(m)
        v *= np.float32(m)
        return cv2.remap(tex, u, v, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)

    def _nearest(self, x: np.ndarray, y: np.ndarray, m: int) -> np.ndarray:
        """The unfiltered texture's texel under each point."""
        tex = np.asarray(self._texture(m), np.float32)
        uv = self.fractional(np.stack([np.asarray(x, float), np.asarray(y, float)], -1))
        ij = np.floor((uv - np.floor(uv)) * m).astype(int) % m
        return tex[ij[..., 1], ij[..., 0]]  # rows vary along v (w2), columns along u


def render_print(p: Print, size_mm: tuple[float, float], mm_per_px: float, *,
                 offset: tuple[float, float] = (0.0, 0.0),
                 anti_alias: bool = True) -> np.ndarray:
    """A flat, top-down image of the print: (H, W, 3) BGR uint8.

    Pixel ``(col, row)`` is centred on ``offset + (col, row) * mm_per_px`` mm;
    ``anti_alias``: see :meth:`Print.colour_at`.
    """
    if mm_per_px <= 0:
        raise ValueError(f"mm per pixel must be positive, got {mm_per_px}")
    w = int(round(size_mm[0] / mm_per_px))
    h = int(round(size_mm[1] / mm_per_px))
    if w < 1 or h < 1 or w > 20000 or h > 20000:
        raise ValueError(f"image of {w}x{h} px out of range (size {size_mm} mm at "
                         f"{mm_per_px} mm/px)")
    xs = offset[0] + np.arange(w) * mm_per_px
    ys = offset[1] + np.arange(h) * mm_per_px
    x, y = np.meshgrid(xs, ys)
    return to_uint8(p.colour_at(x, y, mm_per_px, anti_alias=anti_alias))


def to_uint8(img: np.ndarray) -> np.ndarray:
    return np.clip(np.rint(img * 255.0), 0, 255).astype(np.uint8)


# ---------------------------------------------------------------- lattices
def lattice_for(group: str, repeat: float, *, rotation: float = 0.0,
                rng: np.random.Generator | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A lattice ``(w1, w2)`` in mm that fits ``group``, with ``|w1| = repeat``.

    Free shape parameters (the second length of oblique and rectangular lattices, the
    angle of oblique and rhombic ones) are drawn from ``rng`` away from the special
    values, so a print never sits on a lattice of higher symmetry by accident.
    ``rotation`` (degrees) turns the lattice by +rotation in the mathematical sense of
    (x, y); in an image with y down that looks clockwise.
    """
    if group not in GROUPS:
        raise ValueError(f"unknown wallpaper group {group!r}; expected one of "
                         f"{', '.join(GROUP_NAMES)}")
    if not repeat > 0:
        raise ValueError(f"repeat must be positive, got {repeat}")
    rng = rng if rng is not None else np.random.default_rng(0)
    lattice = GROUPS[group].lattice
    ratio, angle = 1.0, 90.0
    if lattice == "oblique":
        ratio, angle = rng.uniform(0.72, 0.88), rng.uniform(68.0, 80.0)
    elif lattice == "rectangular":
        ratio = rng.uniform(0.62, 0.8)
    elif lattice == "rhombic":
        angle = rng.uniform(68.0, 78.0)
    elif lattice == "hexagonal":
        angle = 120.0
    a = math.radians(angle)
    w1 = np.array([repeat, 0.0])
    w2 = repeat * ratio * np.array([math.cos(a), math.sin(a)])
    r = math.radians(rotation)
    rot = np.array([[math.cos(r), -math.sin(r)], [math.sin(r), math.cos(r)]])
    return rot @ w1, rot @ w2


# ---------------------------------------------------------------- random motifs
def _symmetrised_coefficients(group: str, basis: np.ndarray, rng: np.random.Generator,
                              kmax: int = 9) -> tuple[np.ndarray, np.ndarray]:
    """Fourier coefficients (k (K, 2) int, c (K,) complex) of a group-invariant field.

    f(u) = Re sum_k c_k exp(2 pi i k.u) with random complex c_k; F(u) = sum_g f(A_g u +
    b_g) has the coefficient c_k exp(2 pi i k.b_g) at the harmonic A_g^T k, so the sum
    over the group's operations is done exactly on integer harmonics.
    """
    ks = np.array([(i, j) for i in range(-kmax, kmax + 1) for j in range(-kmax, kmax + 1)
                   if (i, j) != (0, 0)], dtype=np.int64)
    nu = ks @ np.linalg.inv(basis)  # cycles per mm
    cell = math.sqrt(abs(np.linalg.det(basis)))
    radius = np.hypot(nu[:, 0], nu[:, 1]) * cell  # cycles per cell edge
    amp = np.exp(-(((radius - 3.0) / 1.3) ** 2))
    c = amp * (rng.normal(size=len(ks)) + 1j * rng.normal(size=len(ks)))
    out_k, out_c = [], []
    for op in GROUPS[group].ops:
        a, b = op[:, :2], op[:, 2]
        out_k.append(np.rint(ks @ a).astype(np.int64))  # rows: (A^T k)^T = k^T A
        out_c.append(c * np.exp(2j * math.pi * (ks @ b)))
    return np.concatenate(out_k), np.concatenate(out_c)


def _wave_sum(ks: np.ndarray, cs: np.ndarray, m: int) -> np.ndarray:
    """sum_k c_k exp(2 pi i k.u) at u = (col/m, row/m), complex: an exact inverse FFT."""
    spec = np.zeros((m, m), complex)
    np.add.at(spec, (ks[:, 1] % m, ks[:, 0] % m), cs)
    return np.fft.ifft2(spec) * (m * m)


def _field_on_grid(ks: np.ndarray, cs: np.ndarray, m: int) -> np.ndarray:
    """The real part of :func:`_wave_sum`: a real field with the group's symmetry."""
    return _wave_sum(ks, cs, m).real


def _lattice_point_ops(basis: np.ndarray) -> np.ndarray:
    """(n, 2, 2) integer fractional matrices of the lattice's holohedry.

    These are every linear part a symmetry of a print on this lattice can have
    (entries in {-1, 0, 1} suffice for the bases :func:`lattice_for` makes).
    """
    cands = np.array(np.meshgrid(*[(-1, 0, 1)] * 4, indexing="ij")).reshape(4, -1).T
    cands = cands.reshape(-1, 2, 2).astype(float)
    cands = cands[np.isclose(np.abs(np.linalg.det(cands)), 1.0)]
    lin = basis @ cands @ np.linalg.inv(basis)
    ortho = np.einsum("nij,nkj->nik", lin, lin)
    return cands[np.all(np.isclose(ortho, np.eye(2), atol=1e-6), axis=(1, 2))]


def accidental_symmetry(group: str, basis: np.ndarray, field: np.ndarray) -> float:
    """Largest normalised correlation of a cell field with any isometric copy of itself
    that is NOT one of the group's operations (1 = an extra symmetry).

    ``field`` is (m, m) on the fractional grid. For every linear part A of the
    lattice's holohedry, the correlation with F(A u + s) over all shifts s is one
    circular FFT correlation on the torus; the shifts that the group's own operations
    with that linear part predict are masked out, every other shift counts.
    """
    m = field.shape[0]
    f = field - field.mean()
    norm = float(np.sum(f * f)) or 1.0
    uu, vv = np.meshgrid(np.arange(m), np.arange(m))  # column = u index, row = v index
    grid = np.stack([uu, vv], -1) / m
    radius = 0.08 * math.sqrt(abs(np.linalg.det(basis)))
    ops = GROUPS[group].ops
    f_conj = np.conj(np.fft.fft2(f))
    worst = -1.0
    for a in _lattice_point_ops(basis):
        src = np.rint(np.stack([uu, vv], -1) @ a.T).astype(int) % m
        g = f[src[..., 1], src[..., 0]]  # g(u) = f(A u)
        corr = np.fft.ifft2(f_conj * np.fft.fft2(g)).real / norm  # at s: <f(u), f(A(u+s))>
        mask = np.zeros((m, m), bool)
        for op in ops[np.all(np.isclose(ops[:, :, :2], a), axis=(1, 2))]:
            d = grid - np.linalg.solve(a, op[:, 2])  # f(A(u + s0)) = f(Au + b)
            d -= np.rint(d)
            mask |= np.hypot(*np.moveaxis(d @ basis.T, -1, 0)) < radius
        if (~mask).any():
            worst = max(worst, float(corr[~mask].max()))
    return worst


def _random_palette(rng: np.random.Generator, n: int) -> np.ndarray:
    """n BGR colours with clearly different lightness (useful in grey too)."""
    light = np.linspace(0.92, 0.22, n) + rng.uniform(-0.04, 0.04, n)
    hue = rng.uniform(0, 2 * math.pi) + np.arange(n) * rng.uniform(1.7, 2.6)
    sat = rng.uniform(0.25, 0.55, n)
    sat[0] *= 0.4
    r = light + sat * 0.5 * np.cos(hue)
    g = light + sat * 0.5 * np.cos(hue - 2.1)
    b = light + sat * 0.5 * np.cos(hue + 2.1)
    return np.clip(np.stack([b, g, r], 1), 0.03, 0.98).astype(np.float32)


def random_print(group: str, repeat: float = 40.0, *, rotation: float = 0.0,
                 origin: tuple[float, float] | None = None, seed: int = 0,
                 w1: np.ndarray | None = None, w2: np.ndarray | None = None) -> Print:
    """A random colour print of ``group`` with repeat ``|w1| = repeat`` mm.

    The motif is a random band-limited periodic field symmetrised over the group
    (see :func:`_symmetrised_coefficients`), quantised into four colour levels by its
    own quantiles (a monotone map, which adds no symmetry) and shaded within each level
    by a second invariant field. ``rotation`` turns the lattice (degrees), ``origin``
    places the cell (default: random, from ``seed``); give ``w1`` and ``w2`` to choose
    the lattice exactly.
    """
    rng = np.random.default_rng(seed)
    if w1 is None or w2 is None:
        w1, w2 = lattice_for(group, repeat, rotation=rotation, rng=rng)
    if origin is None:
        origin = tuple(rng.uniform(0.0, 1.0, 2) @ np.column_stack([w1, w2]).T)
    wp = Wallpaper(group, w1, w2, origin)
    # Band-limited invariant fields can sit close to a supergroup by chance (a p6 field
    # whose chiral harmonics happen to be weak looks p6m): draw a few motifs and keep
    # the first whose colour levels are clearly unlike any isometric copy of themselves.
    best = None
    for _ in range(_MOTIF_TRIES):
        k1, c1 = _symmetrised_coefficients(group, wp.basis, rng)
        ref = _field_on_grid(k1, c1, 96)
        cuts = np.quantile(ref, [0.42, 0.68, 0.86])
        score = accidental_symmetry(group, wp.basis, np.searchsorted(cuts, ref).astype(float))
        if best is None or score < best[0]:
            best = (score, k1, c1, cuts)
        if score < _MOTIF_ACCEPT:
            break
    _, k1, c1, cuts = best
    k2, c2 = _symmetrised_coefficients(group, wp.basis, rng, kmax=4)
    palette = _random_palette(rng, 4)
    ref2 = _field_on_grid(k2, c2, 96)
    scale2 = float(np.std(ref2)) or 1.0

    def texture(m: int) -> np.ndarray:
        level = np.searchsorted(cuts, _field_on_grid(k1, c1, m))
        shade = 1.0 + 0.12 * np.tanh(_field_on_grid(k2, c2, m) / scale2)
        return np.clip(palette[level] * shade[..., None], 0.0, 1.0).astype(np.float32)

    return Print(f"random-{group}", wp, texture)


def wave_print(group: str, repeat: float = 40.0, *, rotation: float = 0.0,
               seed: int = 0) -> Print:
    """A smooth print of ``group`` as Farris's wallpaper recipes draw one [1]_: a sum of
    plane waves symmetrised over the group, domain-coloured (hue from the complex
    value's argument, lightness from its modulus). Unlike :func:`random_print` it has
    no colour levels and so no edges anywhere: the fine detail where a missing symmetry
    shows most is absent, as in the renderings of such generators.

    The complex field is invariant under every operation of the group, so its colours
    are too; of a few draws the one least like any other isometric copy of itself is
    kept (:func:`accidental_symmetry` of its real and imaginary parts).

    .. [1] F. A. Farris, *Creating Symmetry: The Artful Mathematics of Wallpaper
       Patterns*, Princeton University Press, 2015 (wave functions, domain colouring).
    """
    rng = np.random.default_rng(seed)
    w1, w2 = lattice_for(group, repeat, rotation=rotation, rng=rng)
    origin = tuple(rng.uniform(0.0, 1.0, 2) @ np.column_stack([w1, w2]).T)
    wp = Wallpaper(group, w1, w2, origin)
    best = None
    for _ in range(_MOTIF_TRIES):
        ks, cs = _symmetrised_coefficients(group, wp.basis, rng, kmax=4)
        ref = _wave_sum(ks, cs, 96)
        score = max(accidental_symmetry(group, wp.basis, part) for part in (ref.real,
                                                                             ref.imag))
        if best is None or score < best[0]:
            best = (score, ks, cs, float(np.quantile(np.abs(ref), 0.95)) or 1.0)
        if score < _MOTIF_ACCEPT:
            break
    _, ks, cs, unit = best

    def texture(m: int) -> np.ndarray:
        z = _wave_sum(ks, cs, m)
        hsv = np.empty((m, m, 3), np.float32)
        hsv[..., 0] = np.degrees(np.angle(z)) % 360.0
        hsv[..., 1] = 0.8
        hsv[..., 2] = 0.15 + 0.85 * np.tanh(1.5 * np.abs(z) / unit)
        return cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)

    return Print(f"waves-{group}", wp, texture)
