"""OBJ garments: ``v`` = draped 3D garment, ``vt`` = sewing pattern (or -m/-w file pairs).

Conventions handled (see ``shared/data/garments/*/SOURCE.md``):

* one ``vt`` per face corner (Berkeley combined files): pattern vertices are recovered by
  welding corners on (v index, identical vt value);
* shared ``vt`` (ARCSim, GarmentCode box meshes): the same welding, which also merges
  duplicated ``vt`` lines (reported as a warning);
* ``name-m.obj`` (pattern in ``v``, z = 0) plus ``name-w.obj`` (world) with identical faces:
  seam partners are vertices with bit-identical world positions.

A seam edge is one 3D edge used by two pattern edges (see :mod:`solver.garment.model`).
The files are parsed with NumPy over whole blocks of lines, not line by line.
"""

from __future__ import annotations

import json
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import untrusted
from solver.garment.errors import GarmentError
from solver.garment.model import Garment, build_garment, unique_rows
from solver.units import mm_per_unit

_UNITS_RE = re.compile(r"units?\s*[:=]\s*(mm|cm|m|in)\b", re.IGNORECASE)
_UNITS_HINT_RE = re.compile(r"\((mm|cm|m)[,)\s]|\bin (mm|cm|m)\b")
_TWO_D_MARK = "station: 2d-only"
_BARE_KEYWORD = re.compile(rb"(?m)^(v|vt|vn|f)[ \t]*\r?$")
_VT_INDEXED_MARK = "station: one vt per pattern vertex"


@dataclass
class ObjData:
    """Raw arrays of an OBJ file (0-based indices)."""

    v: np.ndarray  # (n,3)
    vt: np.ndarray  # (m,2)
    f_v: np.ndarray  # (F,3)
    f_vt: np.ndarray | None  # (F,3) or None when faces carry no vt
    comments: list[str]


def _floats(path: Path, lines: list[str], width: int, what: str) -> np.ndarray:
    """Parse ``width`` leading numbers from each line; a short line means a truncated file."""
    if not lines:
        return np.zeros((0, width))
    tokens = " ".join(lines).split()
    try:
        if len(tokens) == width * len(lines):
            arr = np.array(tokens, dtype=float).reshape(-1, width)
        else:
            rows = [ln.split()[:width] for ln in lines]
            short = [i for i, r in enumerate(rows) if len(r) < width]
            if short:
                raise GarmentError(
                    path, f"{what} line {short[0] + 1} has fewer than {width} numbers (truncated?)"
                )
            arr = np.array(rows, dtype=float)
    except ValueError as exc:
        if isinstance(exc, GarmentError):
            raise
        raise GarmentError(path, f"bad number in {what} line {_first_bad(lines, width)}"
                           ) from None
    if not np.isfinite(arr).all():
        bad = int(np.argmax(~np.isfinite(arr).all(axis=1)))
        raise GarmentError(path, f"{what} {bad + 1} is not finite (NaN or inf)")
    return arr


def _first_bad(lines: list[str], width: int) -> int:
    """The 1-based number of the first line whose leading numbers do not parse (named in
    the error instead of the text, which may be anything the file holds)."""
    for i, line in enumerate(lines):
        try:
            [float(t) for t in line.split()[:width]]
        except ValueError:
            return i + 1
    return 1


def _faces(path: Path, lines: list[str]) -> tuple[np.ndarray, np.ndarray | None]:
    """Face lines -> (F,3) v indices and (F,3) vt indices (or None), 0-based, fan-split."""
    if not lines:
        raise GarmentError(path, "no faces (empty or truncated file)")
    first = lines[0].split()[0] if lines[0].split() else ""
    parts = first.split("/")
    has_vt = len(parts) >= 2 and parts[1] != ""
    per = len(parts)  # numbers per corner once '/' is replaced by ' ' (v//vn -> 2 tokens)
    if len(parts) == 3 and parts[1] == "":
        per = 2
    # the fast path needs every line to be a triangle (a quad plus a truncated line could
    # otherwise add up to the same number count); two single spaces prove three corners
    spaces = np.fromiter(map(str.count, lines, [" "] * len(lines)), np.int64, len(lines))
    triangles = bool((spaces == 2).all()) or bool(
        (np.fromiter(map(len, map(str.split, lines)), np.int64, len(lines)) == 3).all()
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # partial parse: counted below
        try:
            numbers = np.fromstring(" ".join(lines).replace("/", " "), dtype=np.int64, sep=" ")
        except ValueError:  # unparsable: the slow path below names the line
            numbers = np.zeros(0, np.int64)
    try:
        if triangles and len(numbers) == 3 * per * len(lines):
            arr = numbers.reshape(len(lines), 3, per)
            f_v = arr[:, :, 0]
            f_vt = arr[:, :, 1] if has_vt else None
        else:
            f_v, f_vt = _faces_slow(path, lines, per, has_vt)
    except ValueError as exc:
        if isinstance(exc, GarmentError):
            raise
        raise GarmentError(path, "bad face line (a corner is not a vertex number)") from None
    return f_v, f_vt


def _faces_slow(
    path: Path, lines: list[str], per: int, has_vt: bool
) -> tuple[np.ndarray, np.ndarray | None]:
    """Polygons or mixed lines: fan-triangulate; a face with < 3 corners is a truncation."""
    fv: list[list[int]] = []
    ft: list[list[int]] = []
    for i, line in enumerate(lines):
        corners = [c.split("/") for c in line.split()]
        if len(corners) < 3 or any(len(c) != len(corners[0]) or c[0] == "" for c in corners):
            raise GarmentError(path, f"face line {i + 1} is incomplete (truncated?)")
        vi = [int(c[0]) for c in corners]
        ti = [int(c[1]) for c in corners] if has_vt else vi
        for k in range(1, len(corners) - 1):
            fv.append([vi[0], vi[k], vi[k + 1]])
            ft.append([ti[0], ti[k], ti[k + 1]])
    return np.array(fv, dtype=np.int64), (np.array(ft, dtype=np.int64) if has_vt else None)


_WHITESPACE = np.zeros(256, dtype=bool)
_WHITESPACE[[9, 10, 13, 32]] = True


def _fast_blocks(data: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """v, vt and face numbers of a regular OBJ, split and parsed at the byte level.

    Lines are classified by their first bytes and each block's numbers parsed by NumPy in
    one call, so a 30k-face file costs no Python work per line. Returns None for anything
    irregular (polygons, extra components, bad numbers, NaN), which the line-based reader
    then handles with its precise error messages.
    """
    n = len(data)
    buf = np.frombuffer(data + b"\n\n\n", dtype=np.uint8)
    nl = np.flatnonzero(buf[:n] == 10)
    starts = np.concatenate([[0], nl + 1])
    ends = np.concatenate([nl, [n]])
    keep = starts < n
    starts, ends = starts[keep], ends[keep]
    c0, c1, c2 = buf[starts], buf[starts + 1], buf[starts + 2]
    sp1 = (c1 == 32) | (c1 == 9)
    sp2 = (c2 == 32) | (c2 == 9)
    is_v = (c0 == ord("v")) & sp1
    is_vt = (c0 == ord("v")) & (c1 == ord("t")) & sp2
    is_f = (c0 == ord("f")) & sp1
    if not is_v.any() or not is_f.any():
        return None

    def block(sel: np.ndarray, prefix: int) -> tuple[np.ndarray, np.ndarray]:
        """Bytes of the selected lines without their prefix, and tokens per line."""
        s = starts[sel] + prefix
        lengths = ends[sel] + 1 - s  # keep each line's newline (padding gives the last one)
        offsets = np.repeat(s - (np.cumsum(lengths) - lengths), lengths)
        chunk = buf[np.arange(int(lengths.sum())) + offsets]
        ws = _WHITESPACE[chunk]
        first = ~ws & np.concatenate([[True], ws[:-1]])
        line = np.repeat(np.arange(len(lengths)), lengths)
        return chunk, np.bincount(line[first], minlength=len(lengths))

    def numbers(chunk: np.ndarray, dtype: type) -> np.ndarray:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)  # partial parse: counted
            try:
                return np.fromstring(chunk.tobytes().decode("latin-1"), dtype=dtype, sep=" ")
            except ValueError:  # NumPy 2 refuses unparsable text: the line reader says where
                return np.zeros(0, dtype)

    v_chunk, v_tok = block(is_v, 2)
    if not (v_tok == 3).all():
        return None
    v = numbers(v_chunk, float)
    if len(v) != 3 * len(v_tok) or not np.isfinite(v).all():
        return None
    vt = np.zeros((0, 2))
    if is_vt.any():
        vt_chunk, vt_tok = block(is_vt, 3)
        if not (vt_tok == 2).all():
            return None
        vt = numbers(vt_chunk, float)
        if len(vt) != 2 * len(vt_tok) or not np.isfinite(vt).all():
            return None
    f_chunk, f_tok = block(is_f, 2)
    if not (f_tok == 3).all():
        return None
    i0 = int(starts[is_f][0]) + 2
    corner = data[i0 : int(ends[is_f][0])].split()[0].decode("latin-1").split("/")
    if corner[0] == "":
        return None
    per = 2 if (len(corner) == 3 and corner[1] == "") else len(corner)
    f_chunk = np.where(f_chunk == ord("/"), np.uint8(32), f_chunk)
    f = numbers(f_chunk, np.int64)
    if len(f) != 3 * per * len(f_tok):
        return None
    return v.reshape(-1, 3), vt.reshape(-1, 2), f.reshape(-1, 3, per), np.array(corner)


def read_obj(path: str | Path) -> ObjData:
    """Read v, vt and faces of an OBJ file; ARCSim extras (vv, t, ...) are ignored."""
    path = Path(path)
    try:
        data = untrusted.read_bytes(path, what="garment file",
                                    max_bytes=untrusted.limits.MAX_OBJ_BYTES)
    except untrusted.MissingInput:
        raise FileNotFoundError(f"{path}: no such garment file") from None
    except untrusted.InputError as exc:
        raise GarmentError(path, exc.fault) from None
    if not data.strip():
        raise GarmentError(path, "empty file")
    _check_complete(path, data)
    head = data[:16384].decode("utf-8", errors="replace").splitlines()[:50]
    comments = [ln[1:].strip() for ln in head if ln.startswith("#")]
    fast = _fast_blocks(data)
    if fast is not None:
        v, vt, f, corner = fast
        has_vt = len(corner) >= 2 and corner[1] != ""
        f_v, f_vt = f[:, :, 0], (f[:, :, 1] if has_vt else None)
    else:
        lines = data.decode("utf-8", errors="replace").splitlines()
        v_lines = [ln[2:] for ln in lines if ln.startswith("v ")]
        vt_lines = [ln[3:] for ln in lines if ln.startswith("vt ")]
        f_lines = [ln[2:] for ln in lines if ln.startswith("f ")]
        if not v_lines:
            raise GarmentError(path, "no vertices (empty or truncated file)")
        v = _floats(path, v_lines, 3, "vertex")
        vt = _floats(path, vt_lines, 2, "texture vertex")
        f_v, f_vt = _faces(path, f_lines)
    f_v = _resolve(path, f_v, len(v), "vertex")
    if f_vt is not None:
        f_vt = _resolve(path, f_vt, len(vt), "texture vertex")
    return ObjData(v, vt, f_v, f_vt, comments)


def _check_complete(path: Path, data: bytes) -> None:
    """Err on a file cut short, or one with more faces than a garment has.

    A writer ends every line with a newline; a data line without one was cut while being
    written or copied, and its last number may be a valid but wrong index.
    """
    tail = data.rstrip(b" \t\r")
    last = tail[tail.rfind(b"\n") + 1 :]
    if not data.endswith(b"\n") and last.split()[:1] in ([b"v"], [b"vt"], [b"f"], [b"vn"]):
        raise GarmentError(path, "the last line has no line end: the file is truncated")
    bare = _BARE_KEYWORD.search(data)
    if bare is not None:  # a line cut right after its keyword would be silently skipped
        line = data.count(b"\n", 0, bare.start()) + 1
        raise GarmentError(path, f"line {line} is a bare {bare.group(1).decode()!r} with no "
                           "numbers: the file is truncated or damaged")
    faces = data.count(b"\nf ") + data.startswith(b"f ")
    if faces > untrusted.limits.MAX_FACES:
        raise GarmentError(path, f"{faces:,} faces; a garment has at most "
                           f"{untrusted.limits.MAX_FACES:,}")


def _resolve(path: Path, idx: np.ndarray, count: int, what: str) -> np.ndarray:
    """1-based (or negative, relative-to-end) OBJ indices -> 0-based, range-checked."""
    out = np.where(idx < 0, idx + count, idx - 1)
    bad = (out < 0) | (out >= count)
    if bad.any():
        f = int(np.argmax(bad.any(axis=1)))
        index = int(idx[f][bad[f]][0])
        # NumPy saturates numbers beyond int64: say "too large" rather than print 2**63 - 1
        shown = str(index) if abs(index) < 2**62 else "beyond the 64-bit range"
        raise GarmentError(
            path, f"face {f + 1} points at missing {what} {shown} (file has {count})",
        )
    return out


def declared_piece_names(comments: list[str]) -> list[str] | None:
    """Piece names from the ``# pieces: ["a", "b"]`` header that :func:`save_obj` writes."""
    for c in comments:
        if c.startswith("pieces:"):
            try:
                names = json.loads(c[len("pieces:") :])
            except json.JSONDecodeError:
                return None
            if isinstance(names, list) and all(isinstance(n, str) for n in names):
                return names
    return None


def declared_units(comments: list[str]) -> str | None:
    """Units the file states in its header comments (``# units: cm``, ``(cm, ...``)."""
    for c in comments:
        m = _UNITS_RE.search(c)
        if m:
            return m.group(1).lower()
    for c in comments:
        m = _UNITS_HINT_RE.search(c)
        if m:
            return (m.group(1) or m.group(2)).lower()
    return None


def _recover_scale(uv: np.ndarray, xyz: np.ndarray, faces: np.ndarray) -> float | None:
    """Scale of normalised [0,1] texture coordinates, fitted to the 3D edge lengths.

    Returns None unless the pattern spans exactly [0,1] along one axis and stays inside the
    unit square, the usual sign of normalised UVs. The median 3D/2D edge-length ratio is
    robust to the stretched faces that meshes have along seams.
    """
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    tol = 1e-4
    inside = (lo >= -tol).all() and (hi <= 1 + tol).all()
    spans = ((np.abs(lo) <= tol) & (np.abs(hi - 1) <= tol)).any()
    if not (inside and spans):
        return None
    e = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    l2 = np.linalg.norm(uv[e[:, 0]] - uv[e[:, 1]], axis=1)
    l3 = np.linalg.norm(xyz[e[:, 0]] - xyz[e[:, 1]], axis=1)
    ok = l2 > 1e-12
    if not ok.any():
        return None
    return float(np.median(l3[ok] / l2[ok]))


def load_obj(
    path: str | Path, *, units: str | None = None, world: str | Path | None = None
) -> Garment:
    """Load an OBJ garment, or a pattern/world pair when ``world`` is given."""
    path = Path(path)
    if world is not None:
        return load_obj_pair(path, Path(world), units=units)
    obj = read_obj(path)
    unit = units or declared_units(obj.comments) or "mm"
    k = mm_per_unit(unit)
    two_d = any(_TWO_D_MARK in c for c in obj.comments)
    vt_indexed = any(_VT_INDEXED_MARK in c for c in obj.comments)
    if obj.f_vt is None or len(obj.vt) == 0:
        if np.abs(obj.v[:, 2]).max() > 0:
            raise GarmentError(path, "faces carry no texture coordinates: no sewing pattern")
        # a flat mesh on its own (e.g. a -m file without its -w partner): pattern only
        return build_garment(
            obj.v[:, :2] * k,
            obj.f_v,
            np.arange(len(obj.v)),
            xyz=None,
            source=path,
            kind="obj",
            units_in_file=unit,
        )
    uniq_v, v_id = _merged_points(path, obj, two_d)
    point, uv, faces = _pattern_vertices(path, obj, v_id, vt_indexed)
    xyz = uniq_v[point]
    scale = None if two_d else _recover_scale(uv, xyz, faces)
    if scale is not None:
        uv = uv * scale
    return build_garment(
        uv * k,
        faces,
        point,
        xyz=None if two_d else xyz * k,
        source=path,
        kind="obj",
        units_in_file=unit,
        scale_recovered=scale,
        piece_names=declared_piece_names(obj.comments),
    )


def _merged_points(path: Path, obj, two_d: bool) -> tuple[np.ndarray, np.ndarray]:
    """One v per 3D point, and the (V,) point of each v: exact duplicates would hide the
    seams through them, so they are merged (not in our own 2D-only files, whose
    placeholder v may coincide where pieces overlap)."""
    if two_d:
        uniq_v, v_id = obj.v, np.arange(len(obj.v))
    else:
        uniq_v, v_id = unique_rows(obj.v)
    if len(uniq_v) < len(obj.v):
        warnings.warn(
            f"{path}: merged {len(obj.v) - len(uniq_v)} duplicate vertices (identical positions)",
            stacklevel=3,
        )
    return uniq_v, v_id.ravel()


def _pattern_vertices(path: Path, obj, v_id: np.ndarray, vt_indexed: bool
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pattern vertices: one per distinct (3D point, texture vertex) of the face corners
    (texture vertices that coincide are welded, with a warning, except in our own files,
    one vt per pattern vertex). Returns each one's 3D point, its uv, and the faces."""
    corner_v = v_id[obj.f_v.ravel()]
    corner_vt = obj.f_vt.ravel()
    if vt_indexed:
        key = np.column_stack([corner_v, corner_vt])
    else:
        key = np.column_stack([corner_v.astype(float), obj.vt[corner_vt]])
    uniq, inv = unique_rows(key)
    inv = inv.ravel()
    per_corner = np.bincount(corner_vt, minlength=len(obj.vt)).max() <= 1
    if not per_corner:
        by_index = len(np.unique(corner_v * len(obj.vt) + corner_vt))
        if by_index > len(uniq):
            warnings.warn(
                f"{path}: welded {by_index - len(uniq)} duplicate texture vertices",
                stacklevel=3,
            )
    point = uniq[:, 0].astype(np.int64)
    uv = obj.vt[uniq[:, 1]] if vt_indexed else uniq[:, 1:]
    return point, uv, inv.reshape(-1, 3)


def pair_partner(path: Path) -> Path | None:
    """The other file of a Berkeley ``-m``/``-w`` pair, if it exists beside ``path``."""
    stem = path.stem
    for mine, other in (("-m", "-w"), ("-w", "-m")):
        if stem.endswith(mine):
            cand = path.with_name(stem[: -len(mine)] + other + path.suffix)
            if cand.is_file():
                return cand
    return None


def load_obj_pair(pattern: Path, world: Path, *, units: str | None = None) -> Garment:
    """Pattern (-m, z = 0) and world (-w) meshes with identical faces; twins coincide in -w."""
    m = read_obj(pattern)
    w = read_obj(world)
    if len(m.v) != len(w.v):
        raise GarmentError(
            world,
            f"pattern and world files have different vertex counts ({len(m.v)} in "
            f"{pattern.name}, {len(w.v)} here)",
        )
    if m.f_v.shape != w.f_v.shape or not np.array_equal(m.f_v, w.f_v):
        nf = min(len(m.f_v), len(w.f_v))
        diff = np.flatnonzero((m.f_v[:nf] != w.f_v[:nf]).any(axis=1))
        where = f"first at face {int(diff[0]) + 1}" if diff.size else "face counts differ"
        raise GarmentError(world, f"pattern and world files have different faces ({where})")
    unit = units or declared_units(m.comments) or declared_units(w.comments) or "mm"
    k = mm_per_unit(unit)
    if np.abs(m.v[:, 2]).max() > 1e-9 * max(1.0, np.abs(m.v).max()):
        raise GarmentError(
            pattern, "pattern file has non-zero z: expected a flat material-space (-m) mesh"
        )
    _, point = unique_rows(w.v)
    return build_garment(
        m.v[:, :2] * k,
        m.f_v,
        point.ravel(),
        xyz=w.v * k,
        source=pattern,
        kind="obj-pair",
        units_in_file=unit,
    )


def save_obj(g: Garment, path: str | Path) -> None:
    """Write ``g`` as OBJ: one ``v`` per 3D point, one ``vt`` per pattern vertex, in mm.

    Twins share their ``v`` line, so the seams survive the round trip. A 2D-only garment
    gets placeholder ``v`` (the pattern position, z = 0) and a header mark telling the
    importer to ignore them.
    """
    path = Path(path)
    n_points = int(g.point_of_vertex.max()) + 1
    rep = np.zeros(n_points, dtype=np.int64)
    rep[g.point_of_vertex[::-1]] = np.arange(g.n_vertices)[::-1]
    if g.xyz is not None:
        v = g.xyz[rep]
    else:
        v = np.column_stack([g.uv[rep], np.zeros(n_points)])
    lines = [
        "# garment written by the cutting station (solver.garment.save_obj)",
        "# units: mm",
        f"# pieces: {json.dumps(g.piece_names)}",
        f"# {_VT_INDEXED_MARK} (weld corners by vt index, not by value)",
    ]
    if g.xyz is None:
        lines.append(f"# {_TWO_D_MARK} (v are placeholders; vt is the pattern)")
    fv = g.point_of_vertex[g.faces] + 1
    ft = g.faces + 1
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("\n".join(lines) + "\n")
        np.savetxt(fh, v, fmt="v %.12g %.12g %.12g")
        np.savetxt(fh, g.uv, fmt="vt %.12g %.12g")
        corners = np.stack([fv, ft], axis=2).reshape(-1, 6)
        np.savetxt(fh, corners, fmt="f %d/%d %d/%d %d/%d")
