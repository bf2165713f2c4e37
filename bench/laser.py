"""GRBL laser mode under the watchdog (issue 32): what a healthy machine reports under M4,
and whether the station's programs cut to the end with every watchdog on.

Every Berkeley garment's cut lines (arcs fitted, as the station writes them) and two
programs made to be hard (sharp spikes; a wavy edge in 0.3 mm lines, no arcs) are streamed
through the emulator, which reports ``FS:`` as GRBL 1.1 does (the prepared segment's speed
and S x speed / F). Per program: did it complete with every piece cut, how many reports
showed the beam on, how many of them below 90 % of S (ramps at starts, corners and stops),
and the largest gap between the reported S and S x reported feed / F (the watchdog allows
2 % of S + 0.5 + 2 ms of acceleration).

Run: ``python -m bench laser``.
"""

from __future__ import annotations

import time

import numpy as np
import serial

import simulators.grbl  # noqa: F401  (registers grblsim://)
from bench.stream import _big_table, _garments, _shelf_layout
from gcode.grbl import Status
from gcode.layout import Layout, LayoutPiece
from gcode.program import Program, build_program
from gcode.stream import Streamer
from gcode.toolpath import build_toolpaths
from solver.garment import load_garment

SETTINGS = "settings=32:1,130:6000,131:3000,110:12000,111:12000,120:1500,121:1500,10:3"


def _hard_programs() -> dict[str, Program]:
    angle = np.linspace(0.0, 2 * np.pi, 48, endpoint=False)
    radius = np.where(np.arange(48) % 2 == 0, 40.0, 20.0)[:, None]
    star = 60.0 + radius * np.c_[np.cos(angle), np.sin(angle)]
    t = np.linspace(0.0, 2 * np.pi, 700, endpoint=False)
    wavy = np.c_[200 + (30 + 1.5 * np.sin(40 * t)) * np.cos(t),
                 60 + (30 + 1.5 * np.sin(40 * t)) * np.sin(t)]
    machine = _big_table().with_cut(arcs=False)
    out = {}
    for name, ring in (("star, 24 spikes", star), ("wavy edge, 0.3 mm lines", wavy)):
        layout = Layout(pieces=[LayoutPiece(id=name, name=name, outline=ring)], gap=0.0,
                        source="bench")
        out[name] = build_program(build_toolpaths(layout, machine), machine)
    return out


def _garment_programs() -> dict[str, Program]:
    machine = _big_table()
    out = {}
    for path in _garments():
        g = load_garment(path, units="m")
        layout = _shelf_layout([g.piece_outline(i) for i in range(g.n_pieces)], 5800.0)
        out[path.stem] = build_program(build_toolpaths(layout, machine), machine)
    return out


def _stream(prog: Program, speed: float) -> tuple[bool, int, list[tuple[float, float]], float]:
    port = serial.serial_for_url(f"grblsim://?speed={speed}&{SETTINGS}", timeout=0.02)
    reports: list[Status] = []
    st = Streamer(port, response_timeout=5.0, stall_timeout=5.0, on_status=reports.append)
    st.connect(quiet=0.05)
    t0 = time.perf_counter()
    res = st.run(prog)
    wall = time.perf_counter() - t0
    port.close()
    on = [(r.feed or 0.0, r.speed) for r in reports if r.state == "Run" and r.speed]
    return res.completed and res.pieces_cut == len(prog.pieces), res.pieces_cut, on, wall


def main() -> None:
    power, feed = 700.0, 3000.0
    print("\n### Laser mode (M4) under the watchdog, emulator as GRBL 1.1 reports it")
    print("| program | speed | pieces | completed | beam-on reports | below 90 % of S | "
          "max S - S F/F_p | wall s |")
    print("|---|---|---|---|---|---|---|---|")
    runs = [(name, prog, speed) for name, prog in _hard_programs().items() for speed in (1, 50)]
    runs += [(name, prog, 50) for name, prog in _garment_programs().items()]
    for name, prog, speed in runs:
        done, cut, on, wall = _stream(prog, speed)
        f = np.array([r[0] for r in on])
        s = np.array([r[1] for r in on])
        gap = float(np.max(np.abs(s - power * np.minimum(f, feed) / feed))) if len(s) else 0.0
        low = int((s < 0.9 * power).sum())
        print(f"| {name} | {speed} | {cut}/{len(prog.pieces)} | {'yes' if done else 'NO'} | "
              f"{len(s)} | {low} ({low / max(len(s), 1):.0%}) | {gap:.2f} | {wall:.1f} |")


if __name__ == "__main__":
    main()
