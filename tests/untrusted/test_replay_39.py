"""A replay of issue 39's red-team reproducers through the `station` command, in process:
every one ends with exit 1 or 2 and one line naming the file or option and the fault, no
traceback, within 20 s, and the test process stays under 4 GiB."""

from __future__ import annotations

import json
import resource
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from station.cli import main
from tests.untrusted.test_reproducers import TSHIRT
from tests.untrusted.test_reproducers_39 import dxf_with_insert

GiB = 1024 ** 3
SQUARE = [[100, 100], [900, 100], [900, 700], [100, 700]]
FABRIC = {"group": "p4m", "w1": [40, 0], "w2": [0, 40], "origin": [0, 0], "units": "mm"}


def _toml(text: str) -> Callable[[Path], list]:
    def argv(tmp: Path) -> list:
        (tmp / "station.toml").write_text(text)
        return ["jobs", "--config", tmp / "station.toml"]
    return argv


def _layout(**piece) -> Callable[[Path], list]:
    def argv(tmp: Path) -> list:
        layout = {"version": 1, "units": "mm", "pieces": [{"outline": SQUARE, **piece}]}
        (tmp / "layout.json").write_text(json.dumps(layout))
        return ["gcode", tmp / "layout.json", "-o", tmp / "x.nc"]
    return argv


def _dxf(codes: str) -> Callable[[Path], list]:
    def argv(tmp: Path) -> list:
        return ["nest", dxf_with_insert(tmp / "piece.dxf", codes), "-o", tmp / "l.json",
                "--width", "1000"]
    return argv


def _obj(edit: Callable[[list[str]], list[str]], command: str = "inspect"
         ) -> Callable[[Path], list]:
    def argv(tmp: Path) -> list:
        bad = tmp / "bad.obj"
        bad.write_text("".join(line + "\n" for line in edit(TSHIRT.read_text().splitlines())))
        if command == "demo":
            return ["demo", "--garment", bad, "--units", "m", "--out", tmp / "out"]
        return ["inspect", bad, "--units", "m"]
    return argv


def _uv_times_1e_minus_9(lines: list[str]) -> list[str]:
    return [f"vt {float(ln.split()[1]) * 1e-9:.12g} {float(ln.split()[2]) * 1e-9:.12g}"
            if ln.startswith("vt ") else ln for ln in lines]


def _cut_to_a_bare_v(lines: list[str]) -> list[str]:
    last_v = max(k for k, ln in enumerate(lines) if ln.startswith("v "))
    return lines[:last_v] + ["v"]


def _fleet_store_on_json(tmp: Path) -> list:
    (tmp / "spec.json").write_text('{"not": "a job store"}')
    return ["fleet", "--store", tmp / "spec.json"]


def _store_a_folder(tmp: Path) -> list:
    (tmp / "jobs.db").mkdir()
    return ["jobs", "--fleet", "--store", tmp / "jobs.db"]


def _fit_png_json(tmp: Path) -> list:
    (tmp / "fabric.json").write_text(json.dumps(FABRIC))
    return ["fit", TSHIRT, "--units", "m", "--fabric", tmp / "fabric.json",
            "--png", tmp / "x.json"]


REPRODUCERS: dict[str, tuple[Callable[[Path], list], str]] = {
    "heartbeat_s 1e300": (_toml("[station]\nheartbeat_s = 1e300\n"), "at most 60"),
    "seam_mm 1e300": (_toml("[allowance]\nseam_mm = 1e300\n"), "at most 1000"),
    "umask 0": (_toml("[store]\numask = 0\n"), "store.umask"),
    "mysql url": (_toml('[store]\nurl = "mysql://root:pw@db/jobs"\n'), "not mysql://"),
    "password in store.url": (_toml('[store]\nurl = "postgresql://root:pw@db/jobs"\n'),
                              "store.url holds a password; put it in PGPASSFILE"),
    "NUL in the station name": (_toml('[station]\nname = "a\\u0000b"\n'), "station.name"),
    "100k marks": (_layout(marks=[[500.0, 400.0]] * 100_000), "marks has 100,000"),
    "20k notches": (_layout(notches=[[500.0, 100.0]] * 20_000), "notches has 20,000"),
    "DXF INSERT scale 0": (_dxf(" 41\n0.0\n 42\n0.0\n"), "xscale 0"),
    "DXF INSERT rotation NaN": (_dxf(" 50\nnan\n"), "rotation nan"),
    "DXF INSERT rotation 1e300": (_dxf(" 50\n1e300\n"), "rotation 1e+300"),
    "OBJ UVs times 1e-9": (_obj(_uv_times_1e_minus_9), "spans only"),
    "OBJ cut to a bare v": (_obj(_cut_to_a_bare_v), "truncated"),
    "demo of an empty garment": (_obj(lambda _: [], "demo"), "empty file"),
    "demo of a pattern of 1e-9": (_obj(_uv_times_1e_minus_9, "demo"), "spans only"),
    "detect --mm-per-px nan": (lambda t: ["detect", t / "none.png", "--mm-per-px", "nan"],
                               "--mm-per-px must be"),
    "detect --mm-per-px 1e-300": (lambda t: ["detect", t / "none.png", "--mm-per-px",
                                             "1e-300"], "--mm-per-px must be"),
    "detect --min-repeat 1e300": (lambda t: ["detect", t / "none.png", "--mm-per-px", "1",
                                             "--min-repeat", "1e300"], "--min-repeat"),
    "calibrate 100000 squares": (lambda t: ["simulate-calibration", "--squares", "100000",
                                            "100000", "-o", t / "c.json"], "--squares"),
    "fit --png x.json": (_fit_png_json, "x.json"),
    "fleet --store a JSON file": (_fleet_store_on_json, "not a job store"),
    "fleet --store not a url": (lambda t: ["fleet", "--store", t / "not a url"],
                                "no job store there"),
    "--store a folder": (_store_a_folder, "jobs.db: no job store there"),
}


def fault_lines(err: str) -> list[str]:
    """stderr without argparse's usage block (``usage:`` and its indented lines)."""
    return [ln for ln in err.splitlines() if ln and not ln.startswith(("usage:", " "))]


@pytest.mark.parametrize("name", list(REPRODUCERS))
def test_red_team_reproducer_is_one_line_and_exit_1_or_2(tmp_path, capsys, name):
    argv, match = REPRODUCERS[name]
    args = [str(a) for a in argv(tmp_path)]
    capsys.readouterr()
    t0 = time.monotonic()
    try:
        code = main(args)
    except SystemExit as exc:  # argparse refuses an option before any work
        code = exc.code
    seconds = time.monotonic() - t0
    err = capsys.readouterr().err
    assert code in (1, 2), err
    assert "Traceback" not in err and ":pw@" not in err
    faults = fault_lines(err)
    assert len(faults) == 1 and match in faults[0], err
    assert seconds < 20
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 < 4 * GiB
