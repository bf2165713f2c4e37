"""The simulated station `station serve --simulate` and both demos run on: the real
daemon and pipeline, on an emulated GRBL and the synthetic camera, and the job files the
demos copy out of its temporary folders. The one place the station's own work meets the
simulators: production modules take their camera and port from their caller.
"""

from __future__ import annotations

import argparse
import json
import shutil
import threading
from pathlib import Path
from typing import Any

import numpy as np
import serial

import simulators.grbl  # noqa: F401  (registers the emulator's grblsim:// URLs)
from gcode.machine import Machine
from simulators.camera import Sheet, SyntheticCamera
from simulators.classics import classic_print
from simulators.grbl.protocol_grblsim import parse_url
from simulators.grbl.registry import lookup
from simulators.grbl.trace import trace_rows
from simulators.roll import LaidPrint, RollCamera, RollPrint
from station.config import EMULATOR_PORT, Config, load_config
from station.daemon import Daemon
from station.pipeline import StationPipeline
from station.simroll import kept_conveyor, roll_state_path, save_poses
from station.steps.capture import CameraOpener
from station.steps.cut import PortOpener, serial_port
from station.steps.program import fabric_origin
from vision.camera import Camera, open_camera

__all__ = ["SimulatedRoll", "copy_job_files", "open_simulated_camera", "open_simulated_port",
           "read_json_or_empty", "roll_by_hand", "roll_print", "simulated_camera",
           "simulated_pipeline", "simulated_roll", "start_simulated_station"]

#: what was cut into the simulated roll, (n, 4) cloth mm, beside its poses
KERFS_FILE = "simulated-kerfs.npy"
#: the simulated camera's print, and where its lattice's origin lies on the fabric
PRINT, REPEAT_MM, PRINT_ORIGIN = "plaid", 80.0, (13.0, 21.0)


def roll_print(config: Config, print_name: str = PRINT, repeat_mm: float = REPEAT_MM
               ) -> RollPrint:
    """The simulated roll's print: the plaid, bowing, skewing and stretching along the
    roll (`simulators.roll.RollPrint`), across the configured fabric width."""
    return RollPrint(classic_print(print_name, repeat_mm, origin=PRINT_ORIGIN),
                     float(config["nest"]["width_mm"]))


def simulated_camera(config: Config, print_name: str = PRINT, repeat_mm: float = REPEAT_MM,
                     seed: int = 3) -> SyntheticCamera:
    """The dry run's camera: the start of the simulated roll covering the usable fabric,
    its print as it lies (bowed, as the bites will see it: `simulators.roll.LaidPrint`),
    seen from above."""
    n = config["nest"]
    ox, oy = (float(v) for v in config["machine"]["fabric_origin"])
    sheet = Sheet(LaidPrint(roll_print(config, print_name, repeat_mm)),
                  size=(n["length_mm"], n["width_mm"]), shift=(ox, oy))
    return SyntheticCamera(sheet, seed=seed)


def open_simulated_camera(config: Config) -> Camera:
    """The synthetic camera, averaging as many frames as the configuration says."""
    return open_camera(simulate=True, sim_factory=lambda: simulated_camera(config),
                       average=config["camera"]["frames"])


def open_simulated_port(config: Config) -> serial.SerialBase:
    """The configured port, the emulator's grblsim:// URLs understood (or a pty)."""
    return serial_port(config)


class SimulatedRoll:
    """The dry run's roll between bites: the camera's print on a roll that bows, skews and
    stretches along its length (`simulators.roll.RollPrint`), on a conveyor that slips,
    photographed through the table window only, at 1 mm per pixel. The conveyor's poses
    are the truth of where every bite was cut on the cloth. What the station's GRBL
    emulator burnt is cut into the cloth where the roll lay (`RollCamera.burn`) before
    each photograph and each advance, so the photographs show the kerfs the station may
    measure an advance from. The kerfs are kept beside the roll's poses
    (``KERFS_FILE``): a restarted station finds them on the cloth where the last one
    cut them."""

    mm_per_px = 1.0

    def __init__(self, config: Config, seed: int = 0, *, by_hand: bool = False,
                 machine: Machine | None = None) -> None:
        n = config["nest"]
        length, width = float(n["length_mm"]), float(n["width_mm"])
        self.print = roll_print(config)
        # kept in the work folder: a restarted station finds the cloth where it was, with
        # what was cut into it (a fresh roll has no kerfs)
        self.kerfs_path = roll_state_path(config).with_name(KERFS_FILE)
        if not roll_state_path(config).is_file():
            self.kerfs_path.unlink(missing_ok=True)
        self.conveyor = kept_conveyor(config, machine, (length / 2, width / 2), seed)
        self.camera = RollCamera(self.print, self.conveyor, (0.0, 0.0, length, width),
                                 self.mm_per_px, seed=seed)
        if self.kerfs_path.is_file():
            self.camera.kerfs.append(np.load(self.kerfs_path))
        # by hand: the job waits for the operator, whose hands slip like the conveyor
        self.feed = None if by_hand else self.advance
        self.origin = fabric_origin(config)
        self.emulator = _emulator_name(str(config["serial"]["port"]))
        self._burnt = len(self._trace())  # cut before this roll was laid: not on it

    def advance(self, mm: float) -> None:
        self.burn()
        self.conveyor.advance(mm)

    def photograph(self):
        self.burn()
        return self.camera.photograph()

    def burn(self) -> None:
        """Cut into the cloth, where the roll lies now, what the emulator burnt since the
        last call (its trace in work mm, the fabric's corner at ``origin``)."""
        rows = self._trace()[self._burnt:]
        self._burnt += len(rows)
        burning = rows[(rows[:, 5] > 0) & (rows[:, 6] == 0)]
        if len(burning):
            self.camera.burn(burning[:, :4] - np.tile(self.origin, 2))
            self.kerfs_path.parent.mkdir(parents=True, exist_ok=True)
            tmp = self.kerfs_path.with_suffix(".tmp.npy")
            np.save(tmp, np.concatenate(self.camera.kerfs))
            tmp.replace(self.kerfs_path)
            save_poses(self.conveyor.poses, self.conveyor.path)  # the roll is in use now

    def _trace(self) -> np.ndarray:
        """(n, 7) the emulator's trace (`simulators.grbl.trace.trace_rows`); none when the
        port is not an emulator of this process."""
        emulator = None if self.emulator is None else lookup(self.emulator)
        return np.zeros((0, 7)) if emulator is None else trace_rows(emulator)

    def settle(self) -> None:
        """Nothing to wait for: a move the simulated conveyor had not finished died with
        the process that commanded it (`station.simroll`)."""

    def truth(self) -> list[dict[str, float]]:
        """Each advance as the conveyor really made it (the simulator's truth), to hold
        the station's measurements against."""
        poses = self.conveyor.poses
        return [{"advance_mm": round(b.along - a.along, 3),
                 "skew_deg": round(b.angle_deg - a.angle_deg, 4)}
                for a, b in zip(poses, poses[1:])]


def _emulator_name(port: str) -> str | None:
    """The named emulator a grblsim:// ``port`` opens (None: another port, or unnamed)."""
    try:
        options, _, _ = parse_url(port)
    except ValueError:
        return None
    return options.get("name")


def simulated_roll(config: Config, machine: Machine, _open_camera: CameraOpener,
                   _open_port: PortOpener) -> SimulatedRoll:
    """The simulated station's roll (`SimulatedRoll`), for `StationPipeline`'s open_roll."""
    return SimulatedRoll(config, machine=machine)


def roll_by_hand(config: Config, machine: Machine, _open_camera: CameraOpener,
                 _open_port: PortOpener) -> SimulatedRoll:
    """`simulated_roll` with no conveyor: the job waits for the operator at each advance."""
    return SimulatedRoll(config, by_hand=True, machine=machine)


def simulated_pipeline(config: Config, cls: type[StationPipeline] = StationPipeline, *,
                       by_hand: bool = False) -> StationPipeline:
    """The station's pipeline (or ``cls``, a subclass) on the simulated camera, GRBL and
    roll (``by_hand``: advanced by the operator)."""
    return cls(config, open_camera=open_simulated_camera, open_port=open_simulated_port,
               open_roll=roll_by_hand if by_hand else simulated_roll)


def start_simulated_station(args: argparse.Namespace, emulator: str, overrides: dict[str, Any],
                            *, thread: str = "daemon") -> tuple[Any, threading.Thread]:
    """A daemon on its own simulated camera and GRBL (the emulator named ``emulator``), with
    the demo's alignment, reshaping and nesting settings, recovered and running in the
    thread ``thread``: the one start of both demos. ``overrides``: its store, socket and
    station sections."""
    port = EMULATOR_PORT.replace("speed=50", f"speed={args.speed:g}")
    config = load_config(None, {
        "serial": {"port": port.replace("name=station", f"name={emulator}")},
        "align": {"restarts": args.restarts},
        "reshape": {"enabled": not args.no_reshape},
        "nest": {"seconds": args.nest_seconds},
        **overrides,
    })
    daemon = Daemon(config, simulated_pipeline(config,
                                               by_hand=getattr(args, "by_hand", False)))
    daemon.recover()
    daemon.control.start()
    worker = threading.Thread(target=daemon.run_loop, name=thread, daemon=True)
    worker.start()
    return daemon, worker


def copy_job_files(workdir: Path, target: Path, names) -> list[str]:
    """Copy the job's files ``names`` that exist out of its folder (the store's folders
    are temporary) into ``target``; returns the names copied, in the order given."""
    copied = [name for name in names if (workdir / name).is_file()]
    for name in copied:
        shutil.copyfile(workdir / name, target / name)
    return copied


def read_json_or_empty(path: Path) -> dict[str, Any]:
    """A job's JSON file for the demo's report; {} when the job did not get to write it."""
    try:
        return json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return {}
