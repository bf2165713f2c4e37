"""station.toml: the one configuration file of a station, checked in full at startup.

A bad configuration must fail when the daemon starts, not in the middle of a cut, so every
key has a type and a range here, unknown sections and keys are errors (a typo would
otherwise silently fall back to a default), and each error names the file, the key and
what is expected.
"""

from __future__ import annotations

import grp
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import untrusted
from station.storeengine import PASSWORD_ADVICE, holds_password
from untrusted.limits import MAX_PASSES, MAX_SOCKET_PATH_BYTES

#: how a bite's pieces follow the print under them (`[roll] follow_print`,
#: `station.steps.bites.localise`)
FOLLOW_PRINT = ("rigid", "affine")

#: the widest seam allowance any setting may ask for (a hem of a heavy coat is ~80 mm)
MAX_ALLOWANCE_MM = 1000.0


@dataclass(frozen=True)
class Key:
    """One configuration key: its type, default (None = required) and allowed range."""

    kind: type
    default: Any
    help: str
    minimum: float | None = None
    maximum: float | None = None
    choices: tuple[str, ...] | None = None


#: The GRBL emulator set up as the default machine (laser mode, soft limits and homing
#: on): the port that `station serve --simulate` and the demos supply when the
#: configuration names none. Never a default: a real station names its own port.
EMULATOR_PORT = ("grblsim://?name=station&speed=50&force_origin=1&settings=32:1,130:1600,"
                 "131:1000,20:1,22:1,23:3,110:12000,111:12000,120:1500,121:1500")

SCHEMA: dict[str, dict[str, Key]] = {
    "serial": {
        "port": Key(str, "", "the GRBL controller: serial device, pty or pyserial URL "
                    "(`station serve` needs it; `serve --simulate` and the demo supply the "
                    "GRBL emulator)"),
        "baud": Key(int, 115200, "baud rate", minimum=1200, maximum=4_000_000),
    },
    "camera": {
        "source": Key(str, "simulated", '"simulated", a device index, a video file or a '
                      "GStreamer pipeline"),
        "calibration": Key(str, "", "calibration JSON (empty: the simulated camera's truth)"),
        "frames": Key(int, 4, "frames averaged per capture", minimum=1, maximum=100),
        "confirm_below": Key(float, 0.9, "detected print confidence below which the job "
                             "waits at 'confirm fabric' for `station confirm`", minimum=0.0,
                             maximum=1.0),
        "min_repeat_mm": Key(float, 3.0, "shortest repeat of a print; a finer one is the "
                             "weave and the cloth is plain", minimum=0.0, maximum=2000.0),
    },
    "machine": {
        "profile": Key(str, "", "machine profile TOML (empty: the built-in 1600 x 1000 laser)"),
        "check_mode": Key(bool, True, "validate every program with $C before cutting"),
        "fabric_origin": Key(list, [0.0, 0.0], "table position (mm) of the fabric's corner"),
    },
    "store": {
        "url": Key(str, "", "shared job store: postgresql://user@host/db (empty: the "
                   "SQLite file at path)"),
        "path": Key(str, "station-data/jobs.db", "SQLite job store"),
        "work_dir": Key(str, "station-data/jobs", "per-job files (frames, plans, G-code)"),
        "umask": Key(int, 0o027, "the daemon's umask (0o027: job files 0640, folders 0750; "
                     "it must keep every permission from others: 0o007 at least)",
                     minimum=0o007, maximum=0o777),
    },
    "station": {
        "name": Key(str, "", "this station's name in a fleet sharing one job store (empty: "
                    "a lone station taking every job in order)"),
        "heartbeat_s": Key(float, 0.5, "heartbeat and remote-command poll interval",
                           minimum=0.05, maximum=60.0),
        "lost_after_s": Key(float, 30.0, "a station silent this long is lost: its job "
                            "becomes interrupted", minimum=1.0, maximum=86_400.0),
        "outage_s": Key(float, 600.0, "how long to hold the machine and wait for an "
                        "unreachable database server before failing", minimum=1.0,
                        maximum=86_400.0),
    },
    "control": {
        "socket": Key(str, "station-data/station.sock", "Unix socket of the operator console"),
        "group": Key(str, "", "group allowed to use the socket besides the station's user"),
        "submit_folders": Key(list, [], "folders submissions may come from (empty: any "
                              "folder the station's user can read)"),
        "check_seconds": Key(float, 120.0, "time allowed to read and check one submission",
                             minimum=1.0, maximum=3600.0),
        "check_memory_mb": Key(int, 4096, "memory allowed to read and check one submission",
                               minimum=64, maximum=1 << 20),
    },
    "console": {  # the web console (station.web): loopback, a token for any change
        "listen": Key(str, "127.0.0.1:8410", "HOST:PORT of the web console (empty: none); "
                      "beyond loopback only with a token_file"),
        "token_file": Key(str, "station-data/console.token", "the token changes need (made "
                          "0640 for the control group if missing; empty: read-only console)"),
    },
    "align": {
        "method": Key(str, "global", "alignment method", choices=("paper", "global")),
        "restarts": Key(int, 15, "random restarts", minimum=1, maximum=10_000),
        "seed": Key(int, 0, "random seed", minimum=0, maximum=2**32 - 1),
        "reflect": Key(bool, False, "allow mirror-symmetric fits across seams"),
        "grain_tolerance_deg": Key(float, 1.0, "keep each piece's grain within this many "
                                   "degrees of the fabric's grain (negative: turn freely)",
                                   minimum=-1.0, maximum=180.0),
        "nap": Key(bool, False, "one-way print or napped fabric: every grain at 0 degrees"),
        "symmetry": Key(bool, True, "left/right pairs keep the print mirrored (or in the same "
                        "place where the print has no mirror along the grain)"),
        "fabric_grain_deg": Key(float, 0.0, "the fabric's grain in fabric space (0: along "
                                "the roll); a fabric's FABRIC.json grain_deg wins",
                                minimum=-360.0, maximum=360.0),
        "up": Key(str, "auto", "the drapes' up axis", choices=("auto", "x", "y", "z", "-x",
                                                               "-y", "-z")),
    },
    "seams": {  # a CAD pattern's seams, inferred (solver.seams)
        "confirm_below": Key(float, 0.5, "a DXF pattern's inferred seam less confident than "
                             "this holds the job at 'confirm seams' for `station confirm` "
                             "(0: never)", minimum=0.0, maximum=1.0),
    },
    "reshape": {
        "enabled": Key(bool, False, "nudge the pieces' shapes for a perfect fit"),
        "max_move_mm": Key(float, 10.0, "largest move of any pattern vertex when reshaping",
                           minimum=0.1, maximum=1000.0),
    },
    "nest": {
        "width_mm": Key(float, 1000.0, "usable fabric width across the table", minimum=1.0,
                        maximum=100_000.0),
        "length_mm": Key(float, 1600.0, "usable fabric length along the table", minimum=1.0,
                         maximum=100_000.0),
        "gap_mm": Key(float, 3.0, "gap between pieces and to the fabric edge", minimum=0.0,
                      maximum=1000.0),
        "seconds": Key(float, 10.0, "time for nesting", minimum=0.1, maximum=3600.0),
    },
    "roll": {  # a marker cut in bites (station.steps.bites)
        "follow_print": Key(str, "affine", "how each piece is placed on the print found "
                            "under it: affine (with the print's bow, skew and stretch, up to "
                            "3 %: they are the cloth's own, weft bow and tension, so the piece "
                            "follows the yarns and is true when the cloth lies relaxed) or "
                            "rigid (turned and moved only: a print misregistered on straight "
                            "cloth; what it leaves is named per piece)", choices=FOLLOW_PRINT),
    },
    "allowance": {
        "seam_mm": Key(float, 10.0, "seam allowance on every sewn edge (mm)", minimum=0.0,
                       maximum=MAX_ALLOWANCE_MM),
        "hem_mm": Key(float, 20.0, "allowance on hems: bottom, sleeve and leg ends (mm)",
                      minimum=0.0, maximum=MAX_ALLOWANCE_MM),
        "opening_mm": Key(float, 10.0, "allowance on other open edges: necklines, waists, "
                          "finished with a facing or band (mm)", minimum=0.0,
                          maximum=MAX_ALLOWANCE_MM),
        "notch_depth_mm": Key(float, 3.0, "notch slit depth (mm; never over half the "
                              "allowance)", minimum=0.0, maximum=MAX_ALLOWANCE_MM),
        "notch_spacing_mm": Key(float, 200.0, "balance notches along a seam at most this "
                                "far apart (mm; 0: only at seam ends)", minimum=0.0,
                                maximum=100_000.0),
    },
    # Every program the station cuts uses these (over the machine profile's [cut]); the
    # profile's ranges apply (power up to max_s, feed from min_cut_feed to max_feed).
    "cut": {
        "kerf_mm": Key(float, 0.2, "cut width", minimum=0.0, maximum=20.0),
        "feed_mm_min": Key(float, 3000.0, "cutting feed", minimum=1.0, maximum=200_000.0),
        "power": Key(float, 700.0, "laser power S", minimum=0.0, maximum=100_000.0),
        "passes": Key(int, 1, "passes per contour", minimum=1, maximum=MAX_PASSES),
    },
}


class ConfigError(ValueError):
    """A fault in station.toml, naming the file and the key."""


@dataclass(frozen=True)
class Config:
    """The checked configuration: ``config["section"]["key"]``; paths are resolved."""

    path: Path | None
    values: dict[str, dict[str, Any]]

    def __getitem__(self, section: str) -> dict[str, Any]:
        return self.values[section]

    def resolve(self, value: str) -> Path:
        """A path from the file, relative to the file's folder (or the working folder)."""
        p = Path(value).expanduser()
        if p.is_absolute() or self.path is None:
            return p
        return self.path.parent / p


def defaults() -> Config:
    return Config(None, {s: {k: key.default for k, key in keys.items()}
                         for s, keys in SCHEMA.items()})


def load_config(path: str | Path | None, overrides: dict[str, dict[str, Any]] | None = None
                ) -> Config:
    """Read and check station.toml (None: the defaults); ``overrides`` win over the file."""
    raw: dict[str, Any] = {}
    where = "defaults"
    if path is not None:
        path = Path(path)
        where = str(path)
        try:
            raw = untrusted.read_toml(path, what="configuration file")
        except untrusted.MissingInput:
            raise ConfigError(f"{path}: no such configuration file") from None
        except untrusted.InputError as exc:
            raise ConfigError(str(exc)) from None
    for section, keys in (overrides or {}).items():
        raw.setdefault(section, {}).update(keys)
    values: dict[str, dict[str, Any]] = {}
    for section, given in raw.items():
        if section not in SCHEMA:
            raise ConfigError(f"{where}: unknown section [{section}]; known sections: "
                              f"{', '.join(SCHEMA)}")
        if not isinstance(given, dict):
            raise ConfigError(f"{where}: [{section}] must be a table of keys")
    for section, keys in SCHEMA.items():
        given = raw.get(section, {})
        unknown = sorted(set(given) - set(keys))
        if unknown:
            raise ConfigError(f"{where}: unknown key {section}.{unknown[0]}; [{section}] "
                              f"takes {', '.join(keys)}")
        values[section] = {name: _check(where, section, name, key, given.get(name, key.default))
                           for name, key in keys.items()}
    config = Config(path, values)
    _check_control(config, where)
    return config


def _check_no_password(url: str, where: str) -> None:
    """A password written in station.toml is refused, never echoed: the file is read by
    the operators' group and copied into bug reports; libpq reads it from elsewhere."""
    if not url:
        return
    try:
        password = holds_password(url)
    except ValueError as exc:
        raise ConfigError(f"{where}: store.url: {exc}") from None
    if password:
        raise ConfigError(f"{where}: store.url holds a password; {PASSWORD_ADVICE} "
                          "(the URL keeps only user, host and database)")


def _check_control(config: Config, where: str) -> None:
    """The socket path must fit a Unix socket address and the group must exist, so that
    ``station serve`` fails at startup with the key named, not deep inside bind()."""
    sock = os.fsencode(config.resolve(config["control"]["socket"]).absolute())
    if len(sock) > MAX_SOCKET_PATH_BYTES:
        raise ConfigError(f"{where}: control.socket resolves to a path of {len(sock)} bytes; "
                          f"a Unix socket path holds at most {MAX_SOCKET_PATH_BYTES}")
    name = config["station"]["name"]
    if len(name) > 64 or not all(ch.isprintable() for ch in name):
        raise ConfigError(f"{where}: station.name must be at most 64 printable characters, "
                          f"got {name[:64]!r}")
    url = config["store"]["url"]
    if url and not url.startswith(("postgresql://", "postgres://")):
        scheme = url.split("://", 1)[0] if "://" in url else ""
        raise ConfigError(f"{where}: store.url must be a postgresql:// URL"
                          + (f", not {scheme[:20]}://..." if scheme else "")
                          + " (leave it empty for the SQLite file at store.path)")
    _check_no_password(url, where)
    group = config["control"]["group"]
    if group:
        try:
            grp.getgrnam(group)
        except KeyError:
            raise ConfigError(f"{where}: control.group {group!r} is not a group on this "
                              "machine") from None
    folders = config["control"]["submit_folders"]
    if not all(isinstance(f, str) and f and len(f) <= 4096 for f in folders) or \
            len(folders) > 100:
        raise ConfigError(f"{where}: control.submit_folders must be a list of folder paths")
    origin = config["machine"]["fabric_origin"]
    if len(origin) != 2 or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                   and abs(v) <= 1e6 for v in origin):
        raise ConfigError(f"{where}: machine.fabric_origin must be [x, y] in mm, got {origin!r}")


def _check(where: str, section: str, name: str, key: Key, value: Any) -> Any:
    label = f"{where}: {section}.{name}"
    if key.kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if key.kind is not bool and isinstance(value, bool) or not isinstance(value, key.kind):
        raise ConfigError(f"{label} must be {key.kind.__name__} ({key.help}), "
                          f"got {value!r}")
    if isinstance(value, float) and not math.isfinite(value):
        raise ConfigError(f"{label} must be a finite number, got {value!r}")
    if name == "umask" and value & 0o007 != 0o007:
        raise ConfigError(f"{label} must keep every permission from others (0o007 set, e.g. "
                          f"0o027), got 0o{value:03o}")
    if key.minimum is not None and value < key.minimum:
        raise ConfigError(f"{label} must be at least {key.minimum:g}, got {value!r}")
    if key.maximum is not None and value > key.maximum:
        raise ConfigError(f"{label} must be at most {key.maximum:g}, got {value!r}")
    if isinstance(value, str) and len(value) > 4096:
        raise ConfigError(f"{label} is longer than 4096 characters")
    if key.choices is not None and value not in key.choices:
        raise ConfigError(f"{label} must be one of {', '.join(key.choices)}, got {value!r}")
    return value


def example_toml() -> str:
    """A complete station.toml with every key, its default and what it means."""
    lines = ["# station.toml: every key with its default", ""]
    for section, keys in SCHEMA.items():
        lines.append(f"[{section}]")
        for name, key in keys.items():
            value = key.default
            text = (f"0o{value:03o}" if name == "umask" else str(value).lower()
                    if isinstance(value, bool)
                    else f'"{value}"' if isinstance(value, str) else repr(value))
            lines.append(f"{name} = {text}  # {key.help}")
        lines.append("")
    return "\n".join(lines)
