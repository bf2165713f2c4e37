"""Malformed inputs of issue 39's red team, through the `station` command: exit 2, one line
naming the file and the fault, no traceback (they ended in exit 70 before)."""

from __future__ import annotations

from pathlib import Path

import ezdxf
import pytest

from station.cli import main
from tests.untrusted.test_reproducers import TSHIRT, refused

# the INSERT as ezdxf writes it at the origin; the fault is spliced in after it, since
# ezdxf itself would not write a scale of 0
_ORIGIN = "FRONT\n 10\n0.0\n 20\n0.0\n 30\n0.0\n"


RECTANGLE = [(0.0, 0.0), (100.0, 0.0), (100.0, 50.0), (0.0, 50.0)]


def dxf_with_insert(path: Path, extra_group_codes: str = "", *, outline=RECTANGLE,
                    quantity: str = "1") -> Path:
    """A one-piece DXF-AAMA file whose INSERT carries ``extra_group_codes`` (41-43 scale,
    50 rotation)."""
    doc = ezdxf.new("R12")
    doc.modelspace().add_text("Units: METRIC", dxfattribs={"layer": "1", "height": 5})
    block = doc.blocks.new(name="FRONT")
    block.add_polyline2d(outline, close=True, dxfattribs={"layer": "1"})
    for k, line in enumerate(["Piece Name: front", f"Quantity: {quantity}"]):
        block.add_text(line, dxfattribs={"layer": "1", "height": 3, "insert": (0, -5 * k - 5)})
    doc.modelspace().add_blockref("FRONT", (0, 0), dxfattribs={"layer": "1"})
    doc.saveas(path)
    text = path.read_text()
    assert text.count(_ORIGIN) == 1
    path.write_text(text.replace(_ORIGIN, _ORIGIN + extra_group_codes))
    return path


@pytest.mark.parametrize("codes,match", [
    (" 41\n0.0\n 42\n0.0\n", "xscale 0 is not usable"),
    (" 42\n0.0\n", "yscale 0 is not usable"),
    (" 41\n1e300\n 42\n1e300\n", "xscale 1e+300 is not usable"),
    (" 41\ninf\n", "xscale inf"),
    (" 50\nnan\n", "rotation nan degrees is not usable"),
    (" 50\n1e300\n", "rotation 1e+300 degrees is not usable"),
    (" 50\n-inf\n", "rotation -inf degrees"),
])
def test_dxf_insert_of_degenerate_scale_or_rotation(tmp_path, capsys, codes, match):
    bad = dxf_with_insert(tmp_path / "piece.dxf", codes)
    last = refused(capsys, bad, "nest", bad, "-o", tmp_path / "l.json", "--width", "1000",
                   match=match)
    assert "INSERT of block 'FRONT'" in last


@pytest.mark.parametrize("outline,quantity,match", [
    (RECTANGLE[:2] + [(100.0, float("nan")), (0.0, 50.0)], "1",
     "piece 'front': a boundary point is not a finite number"),
    (RECTANGLE, "inf", "piece 'front': quantity is over 10000 copies"),
    (RECTANGLE, "1e9", "piece 'front': quantity is over 10000 copies"),
])
def test_dxf_block_of_a_nan_point_or_endless_quantity(tmp_path, capsys, outline, quantity,
                                                      match):
    bad = dxf_with_insert(tmp_path / "piece.dxf", outline=outline, quantity=quantity)
    refused(capsys, bad, "nest", bad, "-o", tmp_path / "l.json", "--width", "1000",
            match=match)


def test_dxf_insert_of_a_plain_placement_is_read(tmp_path, capsys):
    """The check refuses only the degenerate: a turned, mirrored, doubled piece nests."""
    good = dxf_with_insert(tmp_path / "piece.dxf", " 41\n-2.0\n 42\n2.0\n 50\n450.0\n")
    assert main(["nest", str(good), "-o", str(tmp_path / "l.json"), "--width", "1000"]) == 0


def test_obj_texture_coordinates_scaled_1e_minus_9(tmp_path, capsys):
    bad = tmp_path / "tiny-uv.obj"
    bad.write_text("".join(_shrunk_vt(line) + "\n" for line in TSHIRT.read_text().splitlines()))
    refused(capsys, bad, "inspect", bad, "--units", "m", match="sewing pattern spans only")


def _shrunk_vt(line: str) -> str:
    if not line.startswith("vt "):
        return line
    u, v = (float(x) * 1e-9 for x in line.split()[1:3])
    return f"vt {u:.12g} {v:.12g}"


@pytest.mark.parametrize("content", ["", "garbage \x01\x02 nonsense\nzz\n"])
def test_demo_with_a_bad_garment_starts_no_station(tmp_path, capsys, content):
    bad = tmp_path / "bad.obj"
    bad.write_text(content)
    refused(capsys, bad, "demo", "--garment", bad, "--units", "m", "--out", tmp_path / "out",
            match="bad.obj: ")
    assert not (tmp_path / "out").exists()  # refused before any work
