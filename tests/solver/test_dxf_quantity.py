"""``Quantity:`` as both flavours write it: AAMA's count (an even one cut as left/right
pairs) and ASTM D6673's ``a,b`` (``a`` as drawn, ``b`` mirrored). The ASTM export of a
Gerber style was refused ("Quantity '1,0' is not a number") before."""

from __future__ import annotations

import numpy as np
import pytest

from solver.garment.dxf import DxfPattern, DxfPiece, _quantity, read_dxf_pattern

SQUARE = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 50.0], [0.0, 80.0]])


def _cut(text: str) -> list[tuple[str, bool]]:
    total, flipped = _quantity(text, "t")
    piece = DxfPiece("P", None, total, SQUARE, flipped=flipped)
    return [(p.name, p.mirrored) for p in DxfPattern([piece], [], None, "mm", "t").cut_list()]


def test_aama_counts_and_astm_pairs() -> None:
    assert _quantity("2", "t") == (2, None) and _quantity(" 1,1 ", "t") == (2, 1)
    assert _cut("2") == _cut("1,1") == [("P L", False), ("P R", True)]
    assert _cut("1") == _cut("1,0") == [("P", False)]
    assert _cut("2,0") == [("P #1", False), ("P #2", False)]  # two alike, no pair
    assert _cut("1,2") == [("P #1", False), ("P #2", True), ("P #3", True)]
    assert _cut("0,0") == []
    for bad in ("1,x", "1.5,1", "-1,1"):
        with pytest.raises(ValueError, match="Quantity"):
            _quantity(bad, "t")


def test_the_astm_export_cuts_as_the_aama_one(shared_data) -> None:
    folder = shared_data / "garments" / "astm_aama_dxf"
    aama, astm = (read_dxf_pattern(folder / f, size=["36", "44"]).cut_list()
                  for f in ("ORILEGWB_AAMA.DXF", "ORILEGWB_ASTM.DXF"))
    assert [(p.name, p.mirrored) for p in astm] == [(p.name, p.mirrored) for p in aama] == [
        ("ORILEG WB WB 36", False), ("ORILEG WB WB 44", False), ("ORILEG WB LL 36 L", False),
        ("ORILEG WB LL 36 R", True), ("ORILEG WB LL 44 L", False), ("ORILEG WB LL 44 R", True)]
    for a, b in zip(aama, astm, strict=True):
        assert np.abs(a.cut - b.cut).max() < 0.05  # the same lines, to the file's rounding
