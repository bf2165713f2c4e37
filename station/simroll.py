"""The simulated roll outlives the simulated station's process (issue 35, recovery).

A real roll does not move back when the daemon dies: the cloth lies where the conveyor
left it, and the daemon that comes back must find it there. The simulated conveyor
lives in the daemon's process, so its poses (where the roll lies on the table, every
advance kept as truth) are written to ``simulated-roll.json`` in the station's work
folder after each move, and a simulated station started on that folder finds the cloth
where the last one left it.

A move takes the time the machine profile's conveyor would (its feed, or its mm per
second), and the cloth moves when the move is over, all at once: a daemon killed during
the move finds the roll unmoved, as a conveyor whose command was sent but never ran (a
power cut, a reset) leaves it. After the move the roll settles for ``SETTLE_S`` before
the conveyor answers, as a real one does before the photograph.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

from gcode.machine import Machine
from simulators.roll import Conveyor, Pose
from station.config import Config
from station.steps.roll import conveyor_mm_per_s

ROLL_STATE_FILE = "simulated-roll.json"
SETTLE_S = 0.25


@dataclass
class KeptConveyor(Conveyor):
    """`simulators.roll.Conveyor` whose poses are written to ``path`` after every move
    (None: kept in memory only), each move taking ``mm_per_s`` (0: no time at all)."""

    path: Path | None = None
    mm_per_s: float = 0.0

    def advance(self, commanded_mm: float, *, slip: float | None = None,
                skew: float | None = None) -> Pose:
        if self.mm_per_s > 0:
            time.sleep(abs(commanded_mm) / self.mm_per_s)  # killed now: the roll never moved
        pose = super().advance(commanded_mm, slip=slip, skew=skew)
        if self.path is not None:
            save_poses(self.poses, self.path)
        if self.mm_per_s > 0:
            time.sleep(SETTLE_S)
        return pose


def roll_state_path(config: Config) -> Path:
    """Where the simulated station keeps its roll: beside its jobs' folders."""
    return config.resolve(config["store"]["work_dir"]) / ROLL_STATE_FILE


def kept_conveyor(config: Config, machine: Machine | None, pivot: tuple[float, float],
                  seed: int = 0) -> KeptConveyor:
    """The simulated station's conveyor, at the poses its work folder kept (a fresh roll
    when there are none, or when they were kept for another table's pivot). A restarted
    station draws its slips from the seed moved on by the advances already made, so it
    does not replay the first advance's."""
    path = roll_state_path(config)
    poses = load_poses(path)
    if any(p.pivot != tuple(pivot) for p in poses):
        poses = []
    return KeptConveyor(pivot=tuple(pivot), seed=seed + max(len(poses) - 1, 0), poses=poses,
                        path=path,
                        mm_per_s=conveyor_mm_per_s(machine) if machine is not None else 0.0)


def save_poses(poses: list[Pose], path: Path) -> None:
    """Written whole, then renamed: a kill mid-write leaves the poses before."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps({"poses": [[p.along, p.across, p.angle_deg, *p.pivot]
                                         for p in poses]}))
    tmp.replace(path)


def load_poses(path: Path) -> list[Pose]:
    """The poses `save_poses` wrote ([] when there are none)."""
    if not path.is_file():
        return []
    return [Pose(float(a), float(c), float(d), (float(x), float(y)))
            for a, c, d, x, y in json.loads(path.read_text())["poses"]]
