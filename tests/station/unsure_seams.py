"""CAD exports whose inferred seams are unsure, for the tests of "confirm seams".

A clean CAD-like export of the bundled GPG tee (every seam notched on both sides, every
piece named) is inferred with full confidence, so no job would wait to have its seams
confirmed. A CAD that notches the body but not the sleeves leaves the sleeves' seams to
their lengths and shapes (0.68 against the body's 0.93-1); one that notches nothing leaves
them all so (the body's 0.31-0.39, under the station's default 0.5)."""

from __future__ import annotations

from pathlib import Path

import ezdxf


def without_notches(path: Path, piece: str = "") -> Path:
    """Rewrite the DXF at ``path`` with no notch (layer 4) on the pieces whose name holds
    ``piece`` (every piece when empty)."""
    doc = ezdxf.readfile(path)
    for block in doc.blocks:
        if any(piece in text.dxf.text.lower() for text in block.query("TEXT")):
            for notch in list(block.query('POINT[layer=="4"]')):
                block.delete_entity(notch)
    doc.saveas(path)
    return path
