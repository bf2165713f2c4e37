"""The operator's answer to a job waiting at "confirm seams" (`station confirm N`).

A CAD pattern carries no seams; the station infers them (:mod:`solver.seams`) and, when
one is unsure, the job waits with the seams drawn numbered in ``seams.png`` and listed in
``seams.json`` (a ``--seams`` file: pieces by name, edge ends as points). The operator
accepts them as they are, or sends a corrected file; either becomes the job's
``seams-confirmed.json``, which planning then reads as the operator's word (declared
seams, vetoes) and does not ask again. Seams sent with the job (``station submit P.dxf
--seams S.json``, job option ``seams``) are the operator's word from the start. The
file's shape and piece names are checked here, before the job goes on; its points are
checked against the pattern when planning reads it.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import untrusted

__all__ = ["SEAMS_CONFIRMED", "SEAMS_FOUND", "SEAMS_PICTURE", "checked_seams", "confirm_seams"]

SEAMS_FOUND = "seams.json"  # the seams as inferred, in the --seams form
SEAMS_CONFIRMED = "seams-confirmed.json"  # the operator's word: planning reads it
SEAMS_PICTURE = "seams.png"  # every seam numbered in its own colour on both pieces
MAX_SEAMS = 1000  # as a --seams file may hold


def confirm_seams(folder: Path, correction: Any = None) -> str:
    """Record the operator's seams for the job whose files are in ``folder``: those found
    (``correction`` None) or the corrected ``--seams`` document; the message to log.
    A ValueError names what is wrong, and nothing is recorded."""
    found = untrusted.mapping(untrusted.read_json(folder / SEAMS_FOUND, what="seams found"),
                              str(folder / SEAMS_FOUND))
    pieces = set(found.get("pieces") or [])
    if correction is None:
        doc, message = found, f"seams confirmed as found ({len(found.get('seams', []))})"
    else:
        doc = checked_seams(correction, pieces, "the seams sent")
        only = "" if doc.get("infer", True) else ", no others"
        message = (f"seams corrected by the operator ({len(doc.get('seams', []))} declared, "
                   f"{len(doc.get('not_seams', []))} vetoed{only})")
    (folder / SEAMS_CONFIRMED).write_text(json.dumps(doc, indent=2))
    return message


def checked_seams(doc: Any, pieces: set[str], src: str) -> dict[str, Any]:
    """A ``--seams`` document (sent by value, called ``src`` in errors) whose every piece
    the job has; its points are checked against the pattern when planning reads it."""
    doc = untrusted.mapping(doc, src)
    unknown = sorted(set(doc) - {"seams", "not_seams", "pieces", "infer"})
    if unknown:
        raise untrusted.InputError(src, f"unknown key {unknown[0]!r} (seams, not_seams, "
                                   "infer)")
    if not isinstance(doc.get("infer", True), bool):
        raise untrusted.InputError(src, "infer: true or false (false: these seams only)")
    named = []
    for k, item in enumerate(untrusted.sequence(doc.get("seams", []), src, "seams",
                                                max_len=MAX_SEAMS)):
        item = untrusted.mapping(item, src, f"seams[{k}]")
        named += [(f"seams[{k}].{key}", item.get(key)) for key in ("a", "b")]
    for k, pair in enumerate(untrusted.sequence(doc.get("not_seams", []), src, "not_seams",
                                                max_len=MAX_SEAMS)):
        pair = untrusted.sequence(pair, src, f"not_seams[{k}]", min_len=2, max_len=2)
        named += [(f"not_seams[{k}]", name) for name in pair]
    for where, name in named:
        if not isinstance(name, str) or name not in pieces:
            raise untrusted.InputError(src, f"{where}: no piece {str(name)[:80]!r} (pieces: "
                                       f"{', '.join(sorted(pieces)[:20])})")
    return doc
