"""Each piece's grain direction in pattern space, and where it came from.

A cutter lays every piece with its grain line along the fabric's grain. The direction
comes from the first source available, per piece:

1. ``file``: a grain line in the pattern file (JSON ``grainline``; a DXF-AAMA piece's
   layer 7 line sets its frame in `solver.nest.dxf_aama` directly);
2. ``operator``: ``--grain-line PIECE=DEG`` or a job option;
3. ``drape``: the 3D drape. Per piece the linear map ``J`` (3x2) from pattern to 3D is
   fitted by least squares over the piece's triangles (the area-weighted mean of their
   Jacobians, vectorised over all pieces with ``np.bincount``); the grain is the pattern
   direction ``d = J^+ a`` whose 3D image
   best matches the axis ``a``: the garment's up axis for body pieces, the limb's axis for
   sleeves and legs. A piece is a limb when it wraps around an axis (its area-weighted
   face normals spread around it, as on a tube) that lies far from vertical; that axis is
   the normals' direction of least spread. A specification (GarmentCode, GPG) has no
   drape but places each flat panel around the body, y up: that placement is its drape,
   and a limb's axis is the normal of its end (a cuff), since flat panels do not wrap.
4. ``outline``: flat patterns with none of the above. The piece's longest principal axis
   (second moments of its area) is a guess, and the caller is warned: a pattern's
   vertical axis means nothing (the Berkeley back pieces lie sideways).

The up axis of a drape is either given (``"z"``, ``"-y"``...) or detected: garments are
close to mirror-symmetric left-right and roughly front-back, never top-bottom, so the
coordinate axis across which the 3D garment is least mirror-symmetric is vertical; its
sign follows the modelling conventions (y-up and z-up both positive).
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from solver.garment.drape import (
    LIMB_ANGLE_DEG,
    PANEL_UP,
    detect_up,
    limb_end_axes,
    panel_positions,
)
from solver.geometry import FLIP, signed_areas

SOURCES = ("file", "operator", "drape", "outline")
LIMB_SPREAD = 0.45  # normals' 2nd / 1st spread above which a piece wraps around an axis
AXES = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True)
class PieceGrain:
    """One piece's grain: direction ``deg`` (pattern space, degrees in (-180, 180]),
    its ``source`` (one of ``SOURCES``), and ``bias`` when it is cut at 45 degrees."""

    deg: float
    source: str
    bias: bool = False

    @property
    def guessed(self) -> bool:
        return self.source == "outline"

    def to_dict(self) -> dict:
        return {"grain_deg": self.deg, "grain_source": self.source,
                "bias": self.bias}


def parse_up(text: str) -> np.ndarray:
    """``"z"``, ``"+y"``, ``"-x"`` -> unit (3,) vector."""
    t = text.strip().lower()
    sign = -1.0 if t.startswith("-") else 1.0
    t = t.lstrip("+-")
    if t not in AXES:
        raise ValueError(f"up axis must be x, y or z with an optional sign, got {text!r}")
    v = np.zeros(3)
    v[AXES[t]] = sign
    return v


def _piece_sums(values: np.ndarray, piece: np.ndarray, n: int) -> np.ndarray:
    """(n, ...) per-piece sums of (F, ...) values."""
    flat = values.reshape(len(values), -1)
    out = np.stack([np.bincount(piece, weights=flat[:, k], minlength=n)
                    for k in range(flat.shape[1])], axis=1)
    return out.reshape((n,) + values.shape[1:])


def drape_maps(garment, xyz: np.ndarray | None = None) -> np.ndarray:
    """(P,3,2) linear maps from pattern to 3D (``xyz``, default the drape), one per piece:
    the area-weighted mean of the faces' Jacobians, i.e. the least-squares fit
    ``argmin_J sum_f A_f |J_f - J|^2``."""
    f = garment.faces
    x = garment.xyz if xyz is None else xyz
    e2 = np.stack([garment.uv[f[:, 1]] - garment.uv[f[:, 0]],
                   garment.uv[f[:, 2]] - garment.uv[f[:, 0]]], axis=2)  # (F,2,2) columns
    e3 = np.stack([x[f[:, 1]] - x[f[:, 0]], x[f[:, 2]] - x[f[:, 0]]], axis=2)  # (F,3,2)
    det = e2[:, 0, 0] * e2[:, 1, 1] - e2[:, 0, 1] * e2[:, 1, 0]  # 2 A_f
    adj = np.stack([np.stack([e2[:, 1, 1], -e2[:, 0, 1]], -1),
                    np.stack([-e2[:, 1, 0], e2[:, 0, 0]], -1)], -2)  # det * inverse
    area_jac = 0.5 * (e3 @ adj)  # A_f J_f, with J_f = e3 e2^-1
    piece, n = garment.piece_of_face(), garment.n_pieces
    area = np.maximum(np.bincount(piece, weights=0.5 * np.abs(det), minlength=n), 1e-300)
    return _piece_sums(area_jac * np.sign(det)[:, None, None], piece, n) / area[:, None, None]


def limb_axes(garment, up: np.ndarray) -> np.ndarray:
    """(P,3) unit axis of each limb piece (sleeve, leg) or NaN for a body piece.

    The axis a piece wraps around is the direction its face normals spread least in; it
    is a limb when the normals spread around it (second spread >= ``LIMB_SPREAD`` x the
    first, as on a tube or half a tube) and it lies more than ``LIMB_ANGLE_DEG`` from up.
    It points towards the up side, or, for a horizontal limb, towards the garment's middle
    (where a sleeve's cap is).
    """
    f, x = garment.faces, garment.xyz
    nrm = np.cross(x[f[:, 1]] - x[f[:, 0]], x[f[:, 2]] - x[f[:, 0]])  # area-weighted x2
    area = np.linalg.norm(nrm, axis=1)
    unit = nrm / np.maximum(area, 1e-300)[:, None]
    piece, n = garment.piece_of_face(), garment.n_pieces
    cov = _piece_sums(area[:, None, None] * unit[:, :, None] * unit[:, None, :], piece, n)
    w, vec = np.linalg.eigh(cov)  # ascending
    axis = vec[:, :, 0]
    spread = w[:, 1] / np.maximum(w[:, 2], 1e-300)
    cos_up = axis @ up
    limb = (spread >= LIMB_SPREAD) & (np.abs(cos_up) < np.cos(np.radians(LIMB_ANGLE_DEG)))
    centre = np.stack([np.bincount(piece, weights=area * x[f].mean(1)[:, k], minlength=n)
                       for k in range(3)], axis=1) / np.maximum(
        np.bincount(piece, weights=area, minlength=n), 1e-300)[:, None]
    inward = (x.mean(0) - centre)
    inward -= np.outer(inward @ up, up)
    towards = np.where(np.abs(cos_up) > 0.5, cos_up, np.einsum("pi,pi->p", axis, inward))
    axis = axis * np.where(towards < 0, -1.0, 1.0)[:, None]
    return np.where(limb[:, None], axis, np.nan)


def drape_grain(garment, up: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(P,) grain angles in degrees from the drape, and (P,) bool: the piece is a limb.

    A specification without a drape places its panels around the body: that placement is
    the drape here (body pieces up ``PANEL_UP``). Flat panels do not wrap around a limb,
    so its axis is read off its end instead (`solver.garment.drape.limb_end_axes`).
    """
    placed = panel_positions(garment) if garment.xyz is None else None
    if garment.xyz is None and placed is None:
        raise ValueError("the garment has no 3D drape")
    if placed is not None:
        up = PANEL_UP if up is None else np.asarray(up, float) / np.linalg.norm(up)
        jac = drape_maps(garment, placed)
        limb = limb_end_axes(garment, placed, up)
        return _grain_along(jac, limb, up)
    up = detect_up(garment.xyz) if up is None else np.asarray(up, float) / np.linalg.norm(up)
    return _grain_along(drape_maps(garment), limb_axes(garment, up), up)


def _grain_along(jac: np.ndarray, limb: np.ndarray, up: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Per piece the pattern direction whose 3D image (``jac``, (P,3,2)) best matches up,
    or the limb's axis where ``limb`` (P,3) is not NaN; degrees and the limb mask."""
    is_limb = ~np.isnan(limb[:, 0])
    target = np.where(is_limb[:, None], limb, up[None, :])
    jtj = np.einsum("pki,pkj->pij", jac, jac) + 1e-12 * np.eye(2)
    d = np.linalg.solve(jtj, np.einsum("pki,pk->pi", jac, target)[..., None])[..., 0]
    return np.degrees(np.arctan2(d[:, 1], d[:, 0])), is_limb


def outline_grain(garment) -> np.ndarray:
    """(P,) degrees: each piece's longest principal axis (area second moments), a guess."""
    f, uv = garment.faces, garment.uv
    p = uv[f]  # (F,3,2)
    area = np.abs(signed_areas(uv, f))
    # second moment of a triangle about the origin: A/12 (sum v v^T + (sum v)(sum v)^T)
    s = p.sum(1)
    m2 = area[:, None, None] / 12.0 * (np.einsum("fki,fkj->fij", p, p)
                                         + s[:, :, None] * s[:, None, :])
    piece, n = garment.piece_of_face(), garment.n_pieces
    tot = np.maximum(np.bincount(piece, weights=area, minlength=n), 1e-300)
    c = _piece_sums(area[:, None] * s / 3.0, piece, n) / tot[:, None]
    cov = _piece_sums(m2, piece, n) / tot[:, None, None] - c[:, :, None] * c[:, None, :]
    vec = np.linalg.eigh(cov)[1][:, :, 1]
    vec = vec * np.where(vec[:, 1] < 0, -1.0, 1.0)[:, None]  # point it up the page
    return np.degrees(np.arctan2(vec[:, 1], vec[:, 0]))


_RANK = {"file": 0, "operator": 1, "drape": 2, "outline": 3}


def paired_grains(grains: tuple[PieceGrain, ...], pairs) -> tuple[PieceGrain, ...]:
    """Grains with each mirror pair's two pieces cut mirrored (`solver.garment.symmetry`
    ``MirrorPair``: ``p_second = rotation @ FLIP @ p_first + translation``): the better
    source wins (file, operator, drape, outline), two inferred grains meet halfway; two
    given grains are kept as given. Without it a left and a right sleeve inferred from
    a slightly asymmetric drape could not both be on grain once they are mirrored."""
    out = list(grains)
    for pair in pairs:
        gi, gj = out[pair.first], out[pair.second]
        ri, rj = _RANK[gi.source], _RANK[gj.source]
        if ri == rj and ri < _RANK["drape"]:
            continue
        m = pair.rotation @ FLIP  # first's directions -> second's
        di = np.array([np.cos(np.radians(gi.deg)), np.sin(np.radians(gi.deg))])
        dj = np.array([np.cos(np.radians(gj.deg)), np.sin(np.radians(gj.deg))])
        back = np.linalg.solve(m, dj)
        if ri == rj:
            d = di + (back if di @ back >= 0 else -back)
        else:
            d = di if ri < rj else back
        d_second = m @ d
        out[pair.first] = PieceGrain(float(np.degrees(np.arctan2(d[1], d[0]))),
                                     gi.source if ri <= rj else gj.source, gi.bias)
        out[pair.second] = PieceGrain(
            float(np.degrees(np.arctan2(d_second[1], d_second[0]))),
            gj.source if rj <= ri else gi.source, gj.bias)
    return tuple(out)


def grain_lines(garment, degrees: Iterable[float] | None = None) -> np.ndarray:
    """(P,2,2) per piece a grain line (tail, head) in pattern mm for pictures and markers:
    through the piece's centroid along its grain (``degrees``, else ``garment.grains()``),
    60 % of the piece's extent in that direction."""
    deg = np.radians(list(degrees) if degrees is not None else [g.deg for g in garment.grains()])
    d = np.column_stack([np.cos(deg), np.sin(deg)])
    out = np.empty((garment.n_pieces, 2, 2))
    for i in range(garment.n_pieces):  # one small projection per piece
        pts = garment.uv[garment.piece_of_vertex == i]
        centre = pts.mean(axis=0)
        half = 0.3 * float(np.ptp(pts @ d[i]))
        out[i] = [centre - half * d[i], centre + half * d[i]]
    return out


def resolve_piece(garment, key: int | str, what: str) -> int:
    """A piece named by name or index -> its index (ValueError naming ``what``)."""
    names = {n: i for i, n in enumerate(garment.piece_names)}
    if isinstance(key, str) and key in names:
        return names[key]
    text = str(key)
    if text.lstrip("-").isdigit() and 0 <= int(text) < garment.n_pieces:
        return int(text)
    raise ValueError(f"{what}: no piece {key!r}; pieces are "
                     f"{', '.join(garment.piece_names)} (or 0..{garment.n_pieces - 1})")


def parse_grain_lines(specs: Iterable[str] | None) -> dict[str, float]:
    """``["front=90", "2=0"]`` -> {"front": 90.0, "2": 0.0} (``--grain-line``)."""
    out: dict[str, float] = {}
    for spec in specs or []:
        name, sep, value = spec.rpartition("=")
        try:
            deg = float(value)
        except ValueError:
            deg = np.nan
        if not sep or not name or not np.isfinite(deg):
            raise ValueError(f"--grain-line {spec}: expected PIECE=DEGREES")
        out[name] = deg
    return out


def piece_grains(garment, *, lines: Mapping[int | str, float] | None = None,
                 bias: Iterable[int | str] = (), up: np.ndarray | str | None = None
                 ) -> tuple[PieceGrain, ...]:
    """Every piece's grain from its first available source (see the module docstring).

    ``lines`` are the operator's directions (degrees, by piece name or index), ``bias``
    the pieces to cut on the bias, ``up`` the drape's up axis (detected when None).
    Warns once, naming the pieces, when a grain had to be guessed from an outline.
    """
    n = garment.n_pieces
    deg = np.full(n, np.nan)
    source = np.array(["outline"] * n, dtype=object)
    if garment.xyz is not None or panel_positions(garment) is not None:
        up_vec = parse_up(up) if isinstance(up, str) else up
        deg[:], _ = drape_grain(garment, up_vec)
        source[:] = "drape"
    operator = {resolve_piece(garment, k, "--grain-line"): float(v)
                for k, v in (lines or {}).items()}
    for i, v in operator.items():
        deg[i], source[i] = v, "operator"
    for i, ((x0, y0), (x1, y1)) in garment.grainlines.items():
        if 0 <= int(i) < n and (x1 - x0, y1 - y0) != (0, 0):
            deg[int(i)] = np.degrees(np.arctan2(y1 - y0, x1 - x0))
            source[int(i)] = "file"
    guess = np.isnan(deg)
    if guess.any():
        deg[guess] = outline_grain(garment)[guess]
        names = ", ".join(garment.piece_names[i] for i in np.flatnonzero(guess))
        warnings.warn(f"{garment.source}: no grain line in the file and no drape for "
                      f"{names}: grain guessed along each piece's longest axis (give it "
                      "with --grain-line PIECE=DEG)", stacklevel=2)
    on_bias = {resolve_piece(garment, k, "--bias") for k in bias}
    wrapped = (deg + 180.0) % 360.0 - 180.0
    return tuple(PieceGrain(float(180.0 if w == -180.0 else w), str(s), i in on_bias)
                 for i, (w, s) in enumerate(zip(wrapped, source)))
