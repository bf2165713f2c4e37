"""The file level of DXF-AAMA / ASTM D6673 pattern files: blocks, texts, units, rings.

A pattern CAD (Gerber AccuMark, Lectra, CLO) writes AutoCAD R12 DXF where every piece is a
BLOCK placed by one INSERT, the meaning of an entity is its layer number, and TEXT entities
say ``Piece Name:``, ``Size:``, ``Quantity:``, ``Units:``. ezdxf parses the bytes; this
module only refuses what no pattern CAD writes (checked by :mod:`untrusted` first) and
turns the pieces' layers into arrays. Both the garment reader (:mod:`solver.garment.dxf`)
and the nesting reader (:mod:`solver.nest.dxf_aama`) stand on it.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

import ezdxf
import numpy as np

import untrusted
from solver.units import mm_per_unit

# ezdxf narrates every R12 file it reads at INFO ("creating ACAD_COLOR dictionary", ...):
# nothing a station's log should carry per pattern read; its warnings still come through.
logging.getLogger("ezdxf").setLevel(logging.WARNING)

__all__ = ["BadPlacement", "chain_rings", "read_blocks", "reflect", "texts", "units_scale"]

_INSUNITS_MM = {1: 25.4, 2: 304.8, 4: 1.0, 5: 10.0, 6: 1000.0}
_TEXT = re.compile(r"^\s*([A-Za-z ]+?)\s*:\s*(.*?)\s*$")


def texts(entities) -> dict[str, str]:
    """The ``Key: value`` TEXTs of some entities, keys lower-case, first one kept."""
    out: dict[str, str] = {}
    for e in entities:
        if e.dxftype() == "TEXT":
            m = _TEXT.match(e.dxf.text)
            if m:
                out.setdefault(m.group(1).lower(), m.group(2))
    return out


def units_scale(doc, path: Path, units: str | None) -> tuple[float, str]:
    """(mm per file unit, where that came from): ``units`` overrides the file's ``Units:``
    text (ENGLISH = inches, METRIC = mm), then $INSUNITS; a file that says nothing is refused
    rather than guessed, since inches read as mm make every piece 25 times too small."""
    if units is not None:
        return mm_per_unit("in" if units == "inch" else units), f"{units} (--units)"
    declared = texts(doc.modelspace()).get("units", "").upper()
    if declared.startswith("ENGLISH") or declared.startswith("INCH"):
        return 25.4, "in (the file's Units: ENGLISH)"
    if declared.startswith("METRIC"):
        return 1.0, "mm (the file's Units: METRIC)"
    code = doc.header.get("$INSUNITS", 0)
    if code in _INSUNITS_MM:
        return _INSUNITS_MM[code], f"$INSUNITS {code}"
    raise ValueError(f"{path}: the file does not say its units (no 'Units:' text, no $INSUNITS);"
                     " give them with --units mm or in")


def chain_rings(parts: list[np.ndarray], tol: float) -> list[np.ndarray]:
    """Join open polylines end to end into closed rings (AccuMark splits the boundary)."""
    parts = [p for p in parts if len(p) >= 2]
    rings = []
    while parts:
        cur = parts.pop(0)
        grown = True
        while grown and np.linalg.norm(cur[0] - cur[-1]) > tol:
            grown = False
            for k, p in enumerate(parts):
                if np.linalg.norm(p[0] - cur[-1]) <= tol:
                    cur = np.vstack([cur, p[1:]])
                elif np.linalg.norm(p[-1] - cur[-1]) <= tol:
                    cur = np.vstack([cur, p[::-1][1:]])
                elif np.linalg.norm(p[-1] - cur[0]) <= tol:
                    cur = np.vstack([p, cur[1:]])
                elif np.linalg.norm(p[0] - cur[0]) <= tol:
                    cur = np.vstack([p[::-1], cur[1:]])
                else:
                    continue
                parts.pop(k)
                grown = True
                break
        if len(cur) >= 4 and np.linalg.norm(cur[0] - cur[-1]) <= tol:
            rings.append(cur[:-1])
        elif len(cur) >= 3:
            rings.append(cur)  # an open boundary: closed by its last segment
    return rings


def reflect(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """``points`` (k,2) mirrored in the line through ``line[0]`` and ``line[1]``."""
    a, b = line
    d = (b - a) / np.linalg.norm(b - a)
    v = points - a
    return a + 2 * np.outer(v @ d, d) - v


class BadPlacement(ValueError):
    """An INSERT whose placement no pattern CAD writes (kept apart from ezdxf's own errors)."""


# A piece is placed at scale 1 (rarely a grading or unit factor) and turned within a turn;
# beyond these bounds the transform is degenerate or its float rounding meaningless.
_SCALE_RANGE = (1e-6, 1e6)
_MAX_ROTATION_DEG = 3600.0


def _check_placement(ins, path: Path) -> None:
    """Refuse an INSERT of scale 0, NaN or huge, or of a NaN or huge rotation, by name."""
    where = f"{path}: INSERT of block {str(ins.dxf.name)[:80]!r}"
    for axis in ("xscale", "yscale", "zscale"):
        s = float(ins.dxf.get(axis, 1.0))
        if not _SCALE_RANGE[0] <= abs(s) <= _SCALE_RANGE[1]:  # False for NaN
            raise BadPlacement(f"{where}: {axis} {s:g} is not usable (its size must be "
                               f"{_SCALE_RANGE[0]:g} to {_SCALE_RANGE[1]:g})")
    turn = float(ins.dxf.get("rotation", 0.0))
    if not abs(turn) <= _MAX_ROTATION_DEG:
        raise BadPlacement(f"{where}: rotation {turn:g} degrees is not usable (at most "
                           f"{_MAX_ROTATION_DEG:g} either way)")


def read_blocks(path: str | Path):
    """(document, checked path, [(block name, placed entities)]) of every INSERTed piece
    (a block with a boundary on layer 1 or 84); any malformed file is one ValueError."""
    path = untrusted.check_file(path, what="DXF file", max_bytes=untrusted.limits.MAX_DXF_BYTES)
    out = []
    try:
        doc = ezdxf.readfile(path)
        for ins in doc.modelspace().query("INSERT"):
            _check_placement(ins, path)
            ents = list(ins.virtual_entities())  # applies the INSERT's placement
            if any(str(e.dxf.layer) in ("1", "84") for e in ents):
                out.append((ins.dxf.name, ents))
    except BadPlacement:
        raise
    except OSError as exc:
        raise ValueError(f"{path}: not a readable DXF file ({exc})") from None
    except (ezdxf.DXFError, ValueError, TypeError, IndexError, KeyError, AttributeError,
            OverflowError) as exc:
        # ezdxf meets malformed bytes with assorted errors: all mean "not a valid DXF"
        raise ValueError(f"{path}: not a valid DXF file ({type(exc).__name__}: "
                         f"{' '.join(str(exc).split())[:200]})") from None
    return doc, path, out
