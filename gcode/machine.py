"""Machine profiles (TOML): work area, feeds, power and cutting parameters.

Profiles are checked when loaded, Klipper-style: unknown keys, wrong types and values out
of range are errors naming the file and the key, so a typo fails before anything is cut.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from importlib import resources
from pathlib import Path
from typing import Any

import untrusted

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10 (pyproject pulls in tomli there)
    import tomli as tomllib

__all__ = ["CONVEYOR_KINDS", "POWER_MODES", "ConveyorParams", "CutParams", "KnifeParams",
           "Machine", "default_machine", "load_machine"]


#: The laser's spindle word for each ``[cut] power_mode``. Under GRBL's laser mode ($32=1)
#: M4 scales the power with the current speed (the same energy per millimetre through
#: every acceleration and corner); M3 keeps the programmed S whatever the speed.
POWER_MODES = {"dynamic": "M4", "constant": "M3"}


@dataclass(frozen=True)
class CutParams:
    """How to cut: feed, power, passes, kerf, tolerance, notches, marks, tabs."""

    feed: float = 3000.0
    power: float = 700.0
    power_mode: str = "dynamic"  # "dynamic": M4, GRBL scales S with the speed; "constant": M3
    passes: int = 1
    air_assist: bool = True
    kerf: float = 0.2
    tolerance: float = 0.05
    arcs: bool = True
    lead_in: float = 0.0
    notch: str = "slit"
    notch_depth: float = 3.0
    notch_width: float = 2.0
    mark_size: float = 1.0
    mark_power: float = 300.0
    tabs: int = 0
    tab_width: float = 3.0


@dataclass(frozen=True)
class KnifeParams:
    """Knife or drag-knife: Z heights for tool up/down and the corner rule."""

    z_up: float = 5.0
    z_down: float = -1.0
    plunge_feed: float = 600.0
    corner_angle: float = 30.0


#: how a profile's conveyor advances the roll: "" none (the operator advances it),
#: "gcode" a command with ``{mm}`` for the length, "axis" a relative move of a rotary or
#: feed axis, "relay" an output switched on for as long as the roll takes to move
CONVEYOR_KINDS = ("", "gcode", "axis", "relay")


@dataclass(frozen=True)
class ConveyorParams:
    """The conveyor that advances the roll between bites (issue 35); ``kind`` "" has none."""

    kind: str = ""
    command: str = ""  # "gcode": e.g. "M100 L{mm}" ({mm} is the advance, 3 decimals)
    axis: str = "A"  # "axis": the conveyor's axis letter, moved relative (G91) by the advance
    feed: float = 3000.0  # "axis": mm/min of the roll
    relay_on: str = "M8"  # "relay": the output that runs the conveyor, and off again
    relay_off: str = "M9"
    mm_per_s: float = 50.0  # "relay": how far the roll moves per second of the relay on

    def lines(self, mm: float) -> list[str]:
        """The G-code lines that advance the roll by ``mm``; the caller syncs after them
        (``G4 P0``) so that the photograph sees the roll at rest."""
        if self.kind == "gcode":
            return [line.strip() for line in self.command.format(mm=f"{mm:.3f}").split(";")]
        if self.kind == "axis":
            return ["G91", f"G1 {self.axis}{mm:.3f} F{self.feed:g}", "G90"]
        if self.kind == "relay":
            return [self.relay_on, f"G4 P{mm / self.mm_per_s:.3f}", self.relay_off]
        raise ValueError("the machine profile has no conveyor: the operator advances the roll")


def _check_conveyor(c: ConveyorParams, src: str) -> None:
    checks = [
        (c.kind in CONVEYOR_KINDS, f"[conveyor] kind must be one of {CONVEYOR_KINDS[1:]} "
                                   "(or absent: the operator advances the roll)"),
        (c.kind != "gcode" or "{mm}" in c.command,
         "[conveyor] a \"gcode\" conveyor needs command with {mm}, the advance"),
        (c.kind != "axis" or c.axis in ("A", "B", "C"),
         f"[conveyor] axis {c.axis!r} must be A, B or C (X, Y and Z move the tool)"),
        (c.kind != "relay" or (c.relay_on.strip() and c.relay_off.strip()),
         "[conveyor] a \"relay\" conveyor needs relay_on and relay_off"),
    ]
    for ok, msg in checks:
        if not ok:
            raise ValueError(f"{src}: {msg}")
    if c.kind == "gcode":
        try:
            c.command.format(mm="0")  # a stray brace fails here, not between two bites
        except (KeyError, IndexError, ValueError) as exc:
            raise ValueError(f"{src}: [conveyor] command {c.command!r}: {exc!r}") from None


@dataclass(frozen=True)
class Machine:
    """A GRBL machine profile (millimetres, mm/min)."""

    name: str = "GRBL laser table 1600x1000"
    tool: str = "laser"
    work_area: tuple[float, float, float, float] = (0.0, 0.0, 1600.0, 1000.0)
    max_feed: float = 12000.0
    rapid_feed: float = 12000.0
    acceleration: float = 1500.0
    max_s: float = 1000.0
    laser_mode: bool = True
    park: tuple[float, float] = (0.0, 0.0)
    rx_buffer: int = 128
    min_cut_feed: float = 300.0
    cut: CutParams = field(default_factory=CutParams)
    knife: KnifeParams = field(default_factory=KnifeParams)
    conveyor: ConveyorParams = field(default_factory=ConveyorParams)
    source: str = "<built-in>"

    def with_cut(self, **changes: Any) -> Machine:
        """A copy with some cutting parameters changed (validated like the TOML)."""
        m = replace(self, cut=replace(self.cut, **changes))
        _check(m)  # the cut against the machine too: feed, power, min_cut_feed
        return m


#: Stated range of every number, by section and key: (low, high, low end included).
#: WHY: a profile is the only thing between a typo and the machine: `inf` or 1e30 passes
#: "> 0" but writes moves off the table, S words GRBL cannot hold, or buffer overruns.
MAX_TABLE_MM = 10000.0  # no cutting table is 10 m long
MAX_TEXT = 40  # a profile's texts (its name): "(machine NAME tool knife pieces N)" fits 79
RANGES: dict[tuple[str, str], tuple[float, float, bool]] = {
    ("machine", "work_area"): (-MAX_TABLE_MM, MAX_TABLE_MM, True),
    ("machine", "park"): (-MAX_TABLE_MM, MAX_TABLE_MM, True),
    ("machine", "max_feed"): (0.0, 60000.0, False),
    ("machine", "rapid_feed"): (0.0, 60000.0, False),
    ("machine", "acceleration"): (0.0, 50000.0, False),
    ("machine", "max_s"): (0.0, 100000.0, False),  # GRBL's $30
    ("machine", "rx_buffer"): (16, 128, True),  # GRBL 1.1's serial receive buffer is 128 bytes
    ("machine", "min_cut_feed"): (0.0, 60000.0, False),
    ("cut", "feed"): (0.0, 60000.0, False),
    ("cut", "power"): (0.0, 100000.0, True),
    ("cut", "passes"): (1, 20, True),
    ("cut", "kerf"): (0.0, 5.0, True),
    ("cut", "tolerance"): (0.0, 1.0, False),
    ("cut", "lead_in"): (0.0, 50.0, True),
    ("cut", "notch_depth"): (0.0, 50.0, False),
    ("cut", "notch_width"): (0.0, 50.0, False),
    ("cut", "mark_size"): (0.0, 20.0, False),
    ("cut", "mark_power"): (0.0, 100000.0, True),
    ("cut", "tabs"): (0, 100, True),
    ("cut", "tab_width"): (0.0, 50.0, False),
    ("knife", "z_up"): (-500.0, 500.0, True),
    ("knife", "z_down"): (-500.0, 500.0, True),
    ("knife", "plunge_feed"): (0.0, 60000.0, False),
    ("knife", "corner_angle"): (0.0, 180.0, False),
    ("conveyor", "feed"): (0.0, 60000.0, False),
    ("conveyor", "mm_per_s"): (0.0, 10000.0, False),
}


def _check_range(section: str, key: str, value: Any, source: str) -> None:
    """Refuse a non-finite or out-of-range number, naming file, section and key."""
    rng = RANGES.get((section, key))
    values = value if isinstance(value, tuple) else (value,)
    for v in values:
        if isinstance(v, bool) or not isinstance(v, int | float):
            continue
        if not math.isfinite(v):
            raise ValueError(f"{source}: [{section}] {key} = {value!r}: must be a finite number")
        if rng is not None:
            lo, hi, closed = rng
            if not ((lo <= v if closed else lo < v) and v <= hi):
                raise ValueError(f"{source}: [{section}] {key} = {value!r}: must be in "
                                 f"{'[' if closed else '('}{lo:g}, {hi:g}]")


def _coerce(cls: type, table: dict, section: str, source: str) -> dict:
    known = {f.name: f for f in fields(cls)}
    out: dict[str, Any] = {}
    for key, val in table.items():
        if key not in known:
            raise ValueError(f"{source}: unknown key {key!r} in [{section}] "
                             f"(known: {', '.join(sorted(k for k in known if k != 'source'))})")
        default = getattr(cls(), key) if key not in ("cut", "knife") else None
        try:
            if isinstance(default, bool):
                if not isinstance(val, bool):
                    raise TypeError("expected true or false")
                out[key] = val
            elif isinstance(default, int):
                if isinstance(val, bool) or not isinstance(val, int):
                    raise TypeError("expected an integer")
                out[key] = val
            elif isinstance(default, float):
                if isinstance(val, bool) or not isinstance(val, int | float):
                    raise TypeError("expected a number")
                out[key] = float(val)
            elif isinstance(default, tuple):
                if not isinstance(val, list) or len(val) != len(default):
                    raise TypeError(f"expected a list of {len(default)} numbers")
                out[key] = tuple(float(v) for v in val)
            elif isinstance(default, str):
                if not isinstance(val, str):
                    raise TypeError("expected a string")
                if len(val) > MAX_TEXT:  # the name goes into a GRBL line of at most 79
                    raise ValueError(f"at most {MAX_TEXT} characters")
                out[key] = val
            else:
                out[key] = val
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{source}: [{section}] {key} = {val!r}: {exc}") from None
        _check_range(section, key, out[key], source)
    return out


def _check_cut(c: CutParams, source: str) -> None:
    for f in fields(CutParams):
        _check_range("cut", f.name, getattr(c, f.name), source)
    checks = [
        (c.feed > 0, "feed must be > 0"),
        (c.power >= 0, "power must be >= 0"),
        (1 <= c.passes <= untrusted.limits.MAX_PASSES,
         f"passes must be >= 1 and <= {untrusted.limits.MAX_PASSES}"),
        (c.kerf >= 0, "kerf must be >= 0"),
        (c.tolerance > 0, "tolerance must be > 0"),
        (c.lead_in >= 0, "lead_in must be >= 0"),
        (c.notch in ("slit", "v"), "notch must be \"slit\" or \"v\""),
        (c.power_mode in POWER_MODES,
         "power_mode must be \"dynamic\" (M4) or \"constant\" (M3)"),
        (c.notch_depth > 0, "notch_depth must be > 0"),
        (c.notch_width > 0, "notch_width must be > 0"),
        (c.mark_size > 0, "mark_size must be > 0"),
        (c.mark_power >= 0, "mark_power must be >= 0"),
        (c.tabs >= 0, "tabs must be >= 0"),
        (c.tab_width > 0, "tab_width must be > 0"),
    ]
    for ok, msg in checks:
        if not ok:
            raise ValueError(f"{source}: [cut] {msg}")


def _check(m: Machine) -> None:
    src = m.source
    x0, y0, x1, y1 = m.work_area
    checks = [
        (m.tool in ("laser", "knife"), "[machine] tool must be \"laser\" or \"knife\""),
        (x1 > x0 and y1 > y0, "[machine] work_area must be [x_min, y_min, x_max, y_max] "
                              "with x_max > x_min and y_max > y_min"),
        (m.max_feed > 0 and m.rapid_feed > 0, "[machine] max_feed and rapid_feed must be > 0"),
        (m.acceleration > 0, "[machine] acceleration must be > 0"),
        (m.max_s > 0, "[machine] max_s must be > 0"),
        (m.rx_buffer >= 16, "[machine] rx_buffer must be >= 16"),
        (x1 - x0 <= MAX_TABLE_MM and y1 - y0 <= MAX_TABLE_MM,
         f"[machine] work_area must be under {MAX_TABLE_MM / 1000:g} m on each side"),
        (m.min_cut_feed <= m.cut.feed,
         f"[cut] feed {m.cut.feed:g} is below min_cut_feed {m.min_cut_feed:g}"),
        (x0 <= m.park[0] <= x1 and y0 <= m.park[1] <= y1,
         "[machine] park must lie inside work_area"),
        (m.cut.feed <= m.max_feed, f"[cut] feed {m.cut.feed:g} exceeds max_feed {m.max_feed:g}"),
        (m.tool != "laser" or m.cut.power <= m.max_s,
         f"[cut] power {m.cut.power:g} exceeds max_s {m.max_s:g}"),
        (m.tool != "laser" or m.cut.mark_power <= m.max_s,
         f"[cut] mark_power {m.cut.mark_power:g} exceeds max_s {m.max_s:g}"),
        (m.tool != "laser" or m.laser_mode,
         "[machine] a laser profile needs laser_mode = true (GRBL $32=1)"),
        (m.knife.z_up > m.knife.z_down, "[knife] z_up must be above z_down"),
        (m.knife.plunge_feed > 0, "[knife] plunge_feed must be > 0"),
        (0 < m.knife.corner_angle <= 180, "[knife] corner_angle must be in (0, 180]"),
    ]
    for ok, msg in checks:
        if not ok:
            raise ValueError(f"{src}: {msg}")
    _check_cut(m.cut, src)
    _check_conveyor(m.conveyor, src)


def machine_from_dict(data: dict, source: str = "<dict>") -> Machine:
    """Build and check a profile from a TOML-shaped dict."""
    unknown = set(data) - {"machine", "cut", "knife", "conveyor"}
    if unknown:
        raise ValueError(f"{source}: unknown section(s) {sorted(unknown)} "
                         "(known: [machine], [cut], [knife], [conveyor])")
    for sec in ("machine", "cut", "knife", "conveyor"):
        if sec in data and not isinstance(data[sec], dict):
            raise ValueError(f"{source}: [{sec}] must be a table")
    mtab = dict(data.get("machine", {}))
    for k in ("cut", "knife", "conveyor", "source"):
        if k in mtab:
            raise ValueError(f"{source}: unknown key {k!r} in [machine]")
    cut = CutParams(**_coerce(CutParams, data.get("cut", {}), "cut", source))
    knife = KnifeParams(**_coerce(KnifeParams, data.get("knife", {}), "knife", source))
    conveyor = ConveyorParams(**_coerce(ConveyorParams, data.get("conveyor", {}), "conveyor",
                                        source))
    m = Machine(**_coerce(Machine, mtab, "machine", source), cut=cut, knife=knife,
                conveyor=conveyor, source=source)
    _check(m)
    return m


def load_machine(path: str | Path) -> Machine:
    """Read and check a machine profile TOML file."""
    return machine_from_dict(untrusted.read_toml(path, what="machine profile"), str(path))


def default_machine() -> Machine:
    """The built-in profile (``gcode/default_machine.toml``): a 1600 x 1000 mm laser table."""
    text = resources.files("gcode").joinpath("default_machine.toml").read_text(encoding="utf-8")
    return machine_from_dict(tomllib.loads(text), "gcode/default_machine.toml")
