"""Property-based fuzzing of every reader: random bytes, valid documents with one part
replaced by a random JSON shape or an extreme number. Each reader either returns a result
or raises the one-line ``FILE: fault`` error the commands print with exit status 2; never
another exception, never more than a few seconds."""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from gcode.layout import load_layout
from gcode.machine import default_machine, load_machine
from gcode.program import load_program
from solver.garment import load_garment
from solver.nest.instance import load_esicup
from solver.nest.regions import load_keepouts
from solver.placement import Placement
from solver.wallpaper import Wallpaper
from station.config import example_toml, load_config
from untrusted import read_image
from untrusted.structured import parse_toml
from vision.calibration import Calibration

DATA = Path(__file__).resolve().parents[1] / "data"
SECONDS = 5.0  # per input, generous for a loaded 2-core machine

EXAMPLES = os.environ.get("FUZZ_EXAMPLES")  # e.g. 800 for a long random run by hand
FUZZ = settings(max_examples=int(EXAMPLES or 30), deadline=None, derandomize=not EXAMPLES,
                database=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                      HealthCheck.too_slow])

EXTREME = st.sampled_from([0, -1, 1e308, -1e308, 5e-324, 2**63, -(2**63) - 1, 10**25,
                           math.nan, math.inf, -math.inf, 1e-12, 1e12, True, None, "", "x",
                           [], {}, [[1e308, 1e308]], [[0, 0]] * 3])
SHAPES = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner,
                                                                  max_size=4),
    max_leaves=12)


def _machine(path: Path) -> Any:
    return load_machine(path)


def _program(path: Path) -> Any:
    return load_program(path, default_machine())


def _dxf(path: Path) -> Any:
    from solver.nest.dxf_aama import read_dxf_aama

    return read_dxf_aama(path, units="mm")


def _dxf_text() -> str:
    """A small DXF-AAMA file of two pieces, written by the station itself."""
    import tempfile

    from solver.nest.dxf_aama import write_dxf_aama
    from solver.nest.instance import Piece

    pieces = [Piece("front", [[0, 0], [100, 0], [100, 80], [0, 80]]),
              Piece("back", [[0, 0], [60, 0], [30, 50]])]
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "p.dxf"
        write_dxf_aama(pieces, path)
        return path.read_text()


def _toml(tables: Any) -> str:
    """A TOML rendering of tables of scalars and lists (enough for the fuzzed documents)."""
    def value(v: Any) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, float) and not math.isfinite(v):
            return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf")
        if isinstance(v, (list, tuple)):
            return "[" + ", ".join(value(x) for x in v if x is not None) + "]"
        if isinstance(v, dict):
            return "{" + ", ".join(f"{json.dumps(k)} = {value(x)}" for k, x in v.items()
                                   if x is not None) + "}"
        if v is None:
            return '""'
        return json.dumps(v)

    if not isinstance(tables, dict):
        return f"value = {value(tables)}\n"
    lines = []
    for name, table in tables.items():
        if not isinstance(table, dict):
            lines.append(f"{json.dumps(name)} = {value(table)}")
            continue
        lines.append(f"[{json.dumps(name)}]")
        lines += [f"{json.dumps(k)} = {value(v)}" for k, v in table.items()]
    return "\n".join(lines) + "\n"


FABRIC = {"group": "p4m", "w1": [40, 0], "w2": [0, 40], "origin": [0, 0], "units": "mm"}
LAYOUT = {"version": 1, "units": "mm", "width": 500, "length": 500, "gap": 2,
          "pieces": [{"id": "a", "name": "front", "outline": [[10, 10], [90, 10], [90, 90]],
                      "holes": [[[40, 30], [50, 30], [50, 40]]], "marks": [[60, 20]],
                      "notches": [{"at": [50, 10], "direction": [0, 1]}],
                      "grainline": [[20, 20], [80, 20]]}]}
PLACEMENT = {"version": 1, "garment": "shirt.obj", "garment_units": "m", "fabric": FABRIC,
             "pieces": [{"index": 0, "name": "a", "angle_deg": 10, "translation_mm": [1, 2]},
                        {"index": 1, "name": "b", "angle_deg": 0, "translation_mm": [0, 0]}]}
CALIBRATION = {"camera_matrix": [[800, 0, 320], [0, 800, 240], [0, 0, 1]],
               "dist_coeffs": [0.0, 0.0, 0.0, 0.0, 0.0], "resolution": [640, 480],
               "homography_undistorted_px_to_mm": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}
KEEPOUTS = {"keepouts": [[[0, 0], [10, 0], [10, 10]]]}

JSON_READERS: dict[str, tuple[Callable[[Path], Any], Any]] = {
    "fabric": (Wallpaper.load, FABRIC),
    "placement": (Placement.load, PLACEMENT),
    "layout": (load_layout, LAYOUT),
    "esicup": (load_esicup, json.loads((DATA / "nesting" / "jakobs1.json").read_text())),
    "keepouts": (load_keepouts, KEEPOUTS),
    "calibration": (Calibration.load, CALIBRATION),
    "spec": (load_garment, json.loads(
        (DATA / "garments" / "garmentcode" / "tshirt_specification.json").read_text())),
}
TOML_READERS: dict[str, tuple[Callable[[Path], Any], Any]] = {
    "machine": (_machine, parse_toml((Path(__file__).resolve().parents[2] / "gcode"
                                      / "default_machine.toml").read_text(), "machine")),
    "config": (load_config, parse_toml(example_toml(), "station.toml")),
}
OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\n" \
      "f 1/1 2/2 3/3\nf 2/2 4/4 3/3\n"
PROGRAM = "G21 G90 G94 G17\nG0 X10 Y10\n(piece 1 begin a front)\nM4 S700\nG1 X50 Y10 F3000\n" \
          "G1 X50 Y50\nG1 X10 Y10\nM5 S0\nG4 P0.01\n(piece 1 end)\nM2\n"
TEXT_READERS: dict[str, tuple[Callable[[Path], Any], str, str]] = {
    "obj": (load_garment, OBJ, ".obj"),
    "program": (_program, PROGRAM, ".nc"),
    "dxf": (_dxf, _dxf_text(), ".dxf"),
}
ALL = {**{k: (f, ".json") for k, (f, _) in JSON_READERS.items()},
       **{k: (f, ".toml") for k, (f, _) in TOML_READERS.items()},
       **{k: (f, s) for k, (f, _, s) in TEXT_READERS.items()},
       "image": (read_image, ".png")}


def outcome(reader: Callable[[Path], Any], path: Path) -> None:
    """The reader returns, or fails with exit-2 material: a one-line ValueError naming it."""
    t0 = time.monotonic()
    try:
        reader(path)
    except (ValueError, FileNotFoundError) as exc:
        text = str(exc)
        assert "\n" not in text and len(text) < 2000, text
        assert text.startswith(str(path)), text
    assert time.monotonic() - t0 < SECONDS


def replace_at(doc: Any, data: st.DataObject, new: Any) -> Any:
    """``doc`` with one randomly chosen node (possibly the root) replaced by ``new``."""
    if not isinstance(doc, (dict, list)) or not doc or data.draw(st.integers(0, 3)) == 0:
        return new
    doc = dict(doc) if isinstance(doc, dict) else list(doc)
    key = data.draw(st.sampled_from(sorted(doc) if isinstance(doc, dict)
                                    else range(len(doc))))
    doc[key] = replace_at(doc[key], data, new)
    return doc


@pytest.mark.parametrize("name", sorted(ALL))
@FUZZ
@given(blob=st.binary(max_size=600))
def test_random_bytes(tmp_path, name, blob):
    reader, suffix = ALL[name]
    path = tmp_path / f"in{suffix}"
    path.write_bytes(blob)
    outcome(reader, path)


@pytest.mark.parametrize("name", sorted(JSON_READERS))
@FUZZ
@given(data=st.data(), new=SHAPES | EXTREME)
def test_json_shapes_and_extreme_numbers(tmp_path, name, data, new):
    reader, doc = JSON_READERS[name]
    path = tmp_path / "in.json"
    path.write_text(json.dumps(replace_at(doc, data, new)))
    outcome(reader, path)


@pytest.mark.parametrize("name", sorted(TOML_READERS))
@FUZZ
@given(data=st.data(), new=SHAPES | EXTREME)
def test_toml_shapes_and_extreme_numbers(tmp_path, name, data, new):
    reader, doc = TOML_READERS[name]
    path = tmp_path / "in.toml"
    path.write_text(_toml(replace_at(doc, data, new)))
    outcome(reader, path)


@pytest.mark.parametrize("name", sorted(TEXT_READERS))
@FUZZ
@given(data=st.data(), token=st.sampled_from(["1e308", "-1e308", "nan", "inf", "0",
                                              "99999999999999999999", "-5", "1/", "/", "",
                                              "G1", "$", "!", "(", "x", "1.5", "\x00"]))
def test_text_with_extreme_tokens(tmp_path, name, data, token):
    reader, text, suffix = TEXT_READERS[name]
    words = text.replace("\n", " \n ").split(" ")
    index = data.draw(st.integers(0, len(words) - 1))
    words[index] = token
    path = tmp_path / f"in{suffix}"
    path.write_text(" ".join(words).replace(" \n ", "\n"))
    outcome(reader, path)


@pytest.mark.parametrize("ext,at,size", [(".png", slice(16, 24), (200_000).to_bytes(4, "big")),
                                         (".bmp", slice(18, 26), (200_000).to_bytes(4, "little"))])
def test_a_huge_image_header_is_refused_before_decoding(tmp_path, ext, at, size):
    import cv2

    ok, encoded = cv2.imencode(ext, np.zeros((4, 4, 3), np.uint8))
    data = bytearray(encoded.tobytes())
    data[at] = size + size
    path = tmp_path / f"bomb{ext}"
    path.write_bytes(bytes(data))
    with pytest.raises(ValueError, match=f"bomb{ext}: image of 200000 x 200000 pixels exceeds"):
        read_image(path)
    path.write_bytes(encoded.tobytes())
    assert read_image(path).shape == (4, 4, 3)


@FUZZ
@given(line=st.binary(max_size=300) | SHAPES.map(lambda v: json.dumps(v).encode()))
def test_control_requests(line):
    """Whatever a client sends, the daemon answers with one JSON object and stays up."""
    from station.control import ControlServer

    server = ControlServer("/nonexistent/station.sock", lambda req: {"echo": req["cmd"]})
    answer = server.answer(line + b"\n")
    assert isinstance(answer, dict) and isinstance(answer["ok"], bool)
    assert answer["ok"] or isinstance(answer["error"], str)
    json.dumps(answer)


TSHIRT = DATA / "garments" / "berkeley" / "tshirt-coarse.obj"


@FUZZ
@given(cut=st.floats(0.0, 1.0))
def test_an_obj_cut_mid_line_is_refused_never_read_as_another_garment(tmp_path, cut):
    """A copy cut short anywhere but at a line's end is a one-line error (a line cut right
    after its keyword, a bare ``v``, once read as 8 pieces instead of 6)."""
    data = TSHIRT.read_bytes()
    k = int(cut * (len(data) - 2)) + 1
    while data[k - 1:k] in (b"\n", b" ", b"\t", b"\r"):
        k -= 1  # end inside a line's text: the case no reader may take as complete
    line = data[data.rfind(b"\n", 0, k) + 1:k]
    assume(line.split()[:1] in ([b"v"], [b"vt"], [b"vn"], [b"f"]))  # a data line, cut
    path = tmp_path / "cut.obj"
    path.write_bytes(data[:k])
    with pytest.raises(ValueError) as refused:
        load_garment(path, units="m")
    text = str(refused.value)
    assert text.startswith(str(path)) and "\n" not in text, text
