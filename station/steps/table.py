"""The table window: where on the machine's work area the fabric's marker may be cut.

station.toml says where the fabric lies (`[machine] fabric_origin`) and how much of it
the marker may use (`[nest] width_mm` across the table, `length_mm` along it, the window
of one bite); the machine profile says where the tool can go (`[machine] work_area`).
They are checked against each other once, when the daemon starts and when a job is
submitted, so that a roll wider than the table is refused in one line before anything
is planned, never by the program's checker after aligning and nesting (issue 35).
"""

from __future__ import annotations

from dataclasses import dataclass

from gcode.machine import Machine
from station.config import Config, ConfigError

#: rounding slack (mm) when a window ends exactly on the work area's edge
EDGE_SLACK_MM = 1e-6


@dataclass(frozen=True)
class TableWindow:
    """The fabric's window on the table, machine mm: x along the roll, y across it."""

    x0: float
    y0: float
    length: float
    width: float

    @property
    def x1(self) -> float:
        return self.x0 + self.length

    @property
    def y1(self) -> float:
        return self.y0 + self.width


def config_window(config: Config) -> TableWindow:
    """The window ``config`` asks for, unchecked (`table_window` checks it)."""
    ox, oy = (float(v) for v in config["machine"]["fabric_origin"])
    nest = config["nest"]
    return TableWindow(ox, oy, float(nest["length_mm"]), float(nest["width_mm"]))


def table_window(config: Config, machine: Machine) -> TableWindow:
    """The checked window of ``config`` on ``machine``; a ConfigError names the keys and
    both numbers when the window leaves the work area."""
    window = config_window(config)
    ox, oy = window.x0, window.y0
    ax0, ay0, ax1, ay1 = (float(v) for v in machine.work_area)
    where = config.path or "station.toml"
    profile = machine.source
    if not (ax0 - EDGE_SLACK_MM <= ox <= ax1 and ay0 - EDGE_SLACK_MM <= oy <= ay1):
        raise ConfigError(f"{where}: machine.fabric_origin [{ox:g}, {oy:g}] lies outside the "
                          f"work area [{ax0:g}, {ay0:g}, {ax1:g}, {ay1:g}] of the machine "
                          f"profile {profile}")
    if window.y1 > ay1 + EDGE_SLACK_MM:
        raise ConfigError(f"{where}: nest.width_mm {window.width:g} is wider than the table: "
                          f"the machine profile {profile} cuts {ay1 - oy:g} mm across from "
                          f"fabric_origin y {oy:g} (work area y {ay0:g} to {ay1:g})")
    if window.x1 > ax1 + EDGE_SLACK_MM:
        raise ConfigError(f"{where}: nest.length_mm {window.length:g} is longer than the "
                          f"table: the machine profile {profile} cuts {ax1 - ox:g} mm along "
                          f"from fabric_origin x {ox:g}")
    return window
