"""The operator's word on seams: a JSON file that declares seams or vetoes them.

    {"seams": [{"a": "FRONT", "a_ends": [[x, y], [x, y]],
                "b": "BACK",  "b_ends": [[x, y], [x, y]]}],
     "not_seams": [["FRONT", "SLEEVE"]],
     "infer": true}

Pieces by name, edge ends as points (mm, the pattern's own coordinates as the file draws
the piece): each is taken to the nearest point of the piece's sew line. A declared seam
runs counter-clockwise on piece ``a`` from its first end to its second, and is sewn to
``b`` the other way round (right side to right side), as :class:`Seam` says. The seams
the file does not declare are inferred around them, unless ``"infer": false``: then the
file is the operator's whole list (what the console sends when a seam found is struck
out, so that it is not found again).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import untrusted
from solver.seams.match import Seam
from solver.seams.outline import SewPiece, arc_position

__all__ = ["SeamsWord", "read_seams_file"]


@dataclass(frozen=True)
class SeamsWord:
    """What a seams file says: seams declared, piece pairs vetoed, and whether the seams it
    does not declare are still to be inferred."""

    declared: list[Seam] = field(default_factory=list)
    vetoed: set[frozenset[int]] = field(default_factory=set)
    infer_others: bool = True


def _piece(names: dict[str, int], name, src: str, where: str) -> int:
    name = untrusted.text(name, src, where, max_len=200)
    if name not in names:
        raise untrusted.InputError(src, f"{where}: no piece {name!r} (pieces: "
                                   f"{', '.join(list(names)[:20])})")
    return names[name]


def _span(piece: SewPiece, ends, src: str, where: str) -> tuple[float, float]:
    pts = untrusted.points(ends, src, where, min_len=2, max_len=2)
    s0, s1 = arc_position(piece, pts).tolist()
    return s0, s1 if s1 > s0 else s1 + piece.length


def read_seams_file(path: str | Path, pieces: list[SewPiece]) -> SeamsWord:
    """The declared seams, vetoed piece pairs and ``infer`` of a seams file, checked
    before any work."""
    src = str(path)
    doc = untrusted.mapping(untrusted.read_json(path, what="seams file"), src)
    names = {p.name: i for i, p in enumerate(pieces)}
    declared = []
    for k, item in enumerate(untrusted.sequence(doc.get("seams", []), src, "seams",
                                                max_len=1000)):
        item = untrusted.mapping(item, src, f"seams[{k}]")
        a = _piece(names, item.get("a"), src, f"seams[{k}].a")
        b = _piece(names, item.get("b"), src, f"seams[{k}].b")
        a0, a1 = _span(pieces[a], item.get("a_ends"), src, f"seams[{k}].a_ends")
        b0, b1 = _span(pieces[b], item.get("b_ends"), src, f"seams[{k}].b_ends")
        declared.append(Seam(a, a0, a1, b, b0, b1, 0.5 * (a1 - a0 + b1 - b0), 1.0,
                             source="declared"))
    vetoed = set()
    for k, pair in enumerate(untrusted.sequence(doc.get("not_seams", []), src, "not_seams",
                                                max_len=1000)):
        pair = untrusted.sequence(pair, src, f"not_seams[{k}]", min_len=2, max_len=2)
        vetoed.add(frozenset(_piece(names, n, src, f"not_seams[{k}]") for n in pair))
    infer = doc.get("infer", True)
    if not isinstance(infer, bool):
        raise untrusted.InputError(src, "infer: true or false (false: these seams only)")
    return SeamsWord(declared, vetoed, infer)
