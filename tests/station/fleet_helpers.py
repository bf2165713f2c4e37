"""Stations of a fleet for the tests: real daemons, real claims, real streamers and GRBL
emulators, on jobs small enough that fifty of them run in seconds.

`TinyJobs` is `StationPipeline` with capture and planning replaced by a layout of a few
small squares (a unique spot on the table per job and piece, so the motion traces tell
whose piece each cut was); the cut step is the station's own, markers and all.

Run as ``python -m tests.station.fleet_helpers CONFIG`` it serves one station until
SIGTERM, for the tests that kill a station process.
"""

from __future__ import annotations

import json
import math
import sys
import threading
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from station.config import SCHEMA, Config, load_config
from station.daemon import Daemon, JobControl
from station.jobstore import Job
from station.pipeline import StationPipeline
from station.simstation import simulated_pipeline
from station.steps.capture import Captured

SQUARE_MM = 12.0
PITCH_MM = 40.0
COLUMNS = 38


def spot(job_id: int, piece: int, pieces: int) -> tuple[float, float]:
    """Where piece ``piece`` of job ``job_id`` lies on the table (mm): one spot each."""
    k = job_id * pieces + piece
    return 20.0 + (k % COLUMNS) * PITCH_MM, 20.0 + (k // COLUMNS) * PITCH_MM


def stand_in_garment(tmp: Path) -> str:
    """A garment file for the tiny jobs (a station takes in a job's files before it runs
    it, whoever queued it; TinyJobs never parses them)."""
    path = tmp / "g.obj"
    path.write_text("# stand-in: TinyJobs plans squares\n")
    return str(path)


class TinyJobs(StationPipeline):
    """The real cut on planned-in-a-millisecond jobs of ``pieces`` squares."""

    def check(self, garment: str, fabric: str | None, options: dict[str, Any]) -> None:
        """Nothing to check: the squares are planned from the options alone."""

    def capture(self, job: Job, workdir: Path, control: JobControl) -> Captured:
        control.start_step("photographing")
        return Captured(job.fabric or "no fabric", {})

    def plan(self, job: Job, captured: Captured | None, workdir: Path, control: JobControl
             ) -> SquaresPlan:
        control.start_step("planning")
        fabric = captured.path if captured is not None else job.plan["fabric"]
        n = int(job.options.get("pieces", 3))
        size = float(job.options.get("size", SQUARE_MM))
        pieces = []
        for i in range(n):
            x, y = spot(job.id, i, n)
            name = f"j{job.id}p{i}"
            pieces.append({"id": name, "name": name, "outline": [
                [x, y], [x + size, y], [x + size, y + size], [x, y + size]]})
        layout = workdir / "layout.json"
        layout.write_text(json.dumps({"version": 1, "units": "mm", "width": 1000,
                                      "length": 1600, "gap": 3, "pieces": pieces}))
        return SquaresPlan({"fabric": fabric, "layout": str(layout)},
                           [p["name"] for p in pieces])


class SquaresPlan:
    """The squares' plan as the store keeps it: the real cut reads their LAYOUT.json."""

    def __init__(self, files: dict[str, str], pieces: list[str]) -> None:
        self.files, self.pieces = files, pieces

    def record(self) -> dict[str, Any]:
        return {**self.files, "pieces": self.pieces}


def station_config(tmp: Path, name: str, store: str, port: str | None = None,
                   speed: float = 2000.0, lost_after: float = 3.0) -> Config:
    """A fleet station's configuration: its own emulator (or ``port``) and folders."""
    default = SCHEMA["serial"]["port"].default.replace("speed=50", f"speed={speed:g}")
    port = port or default.replace("name=station", f"name=fleet-{name}-{id(tmp)}")
    return load_config(None, {
        "serial": {"port": port},
        "store": {"url": store, "work_dir": str(tmp / name / "work")},
        "control": {"socket": str(tmp / name / "station.sock")},
        "machine": {"check_mode": False},
        "station": {"name": name, "heartbeat_s": 0.2, "lost_after_s": lost_after,
                    "outage_s": 60.0},
    })


class RunningStation:
    """A daemon of the fleet serving in a thread of this process."""

    def __init__(self, config: Config) -> None:
        self.config = config
        self.daemon = Daemon(config, simulated_pipeline(config, TinyJobs))
        self.daemon.recover()
        self.thread = threading.Thread(target=self.daemon.run_loop, daemon=True,
                                       name=config["station"]["name"])
        self.thread.start()

    @property
    def emulator(self):
        from simulators.grbl import lookup

        name = dict(kv.split("=", 1) for kv in
                    self.config["serial"]["port"].split("?", 1)[1].split("&"))["name"]
        return lookup(name)

    def stop(self) -> None:
        self.daemon.shutdown()
        self.thread.join(30)
        self.daemon.store.close()


def beam_segments(trace) -> np.ndarray:
    """The beam-on feed moves of an emulator trace, (n, 4): x0, y0, x1, y1."""
    seg = [[s.x0, s.y0, s.x1, s.y1] for s in trace if s.power > 0 and not s.rapid]
    return np.array(seg, float).reshape(-1, 4)


def cutting(trace) -> np.ndarray:
    """Per trace segment: the beam cuts along it. Under M4 GRBL gives each 10 ms step
    segment the power of the speed at its end, so the one that brakes to a stop (a notch's
    tip, a reversal, a stroke's end) runs dark for a few hundredths of a millimetre, inside
    the kerf: such a step counts with the feed move it belongs to."""
    return np.array([not s.rapid and (s.power > 0 or math.hypot(s.x1 - s.x0, s.y1 - s.y0)
                                      <= 0.1) for s in trace], bool)


def complete_runs(trace, contour: np.ndarray) -> int:
    """How many uninterrupted beam-on runs of ``trace`` cover the whole closed
    ``contour`` (k, 2) within 0.2 mm: once for a piece cut once."""
    seg = np.array([[s.x0, s.y0, s.x1, s.y1] for s in trace], float).reshape(-1, 4)
    if not len(seg):
        return 0
    on_beam = cutting(trace)
    samples = densify(np.c_[contour, np.roll(contour, -1, axis=0)])
    tree = cKDTree(samples)
    near = on_beam & (np.maximum(tree.query(seg[:, :2])[0], tree.query(seg[:, 2:])[0]) < 0.4)
    edges = np.diff(np.concatenate([[0], near.astype(int), [0]]))
    runs = zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1))
    return sum(bool(cKDTree(densify(seg[a:b])).query(samples)[0].max() < 0.3)
               for a, b in runs)


def coverage(trace, contour: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Samples of the closed ``contour`` (k, 2), how many beam-on runs of ``trace`` cover
    each within 0.3 mm, and how many runs touch it: a piece resumed where it stopped is
    covered by two runs that overlap only where the second joins the first."""
    samples = densify(np.c_[contour, np.roll(contour, -1, axis=0)])
    seg = np.array([[s.x0, s.y0, s.x1, s.y1] for s in trace], float).reshape(-1, 4)
    covered = np.zeros(len(samples), int)
    if not len(seg):
        return samples, covered, 0
    on_beam = np.array([s.power > 0 and not s.rapid for s in trace])
    tree = cKDTree(samples)
    near = on_beam & (np.maximum(tree.query(seg[:, :2])[0], tree.query(seg[:, 2:])[0]) < 0.4)
    edges = np.diff(np.concatenate([[0], near.astype(int), [0]]))
    runs = 0
    for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True):
        hit = cKDTree(densify(seg[a:b])).query(samples)[0] < 0.3
        covered += hit
        runs += bool(hit.any())
    return samples, covered, runs


def densify(seg: np.ndarray, step: float = 0.25) -> np.ndarray:
    """Points at most ``step`` mm apart along segments (n, 4)."""
    n = np.maximum(1, np.ceil(np.hypot(*(seg[:, 2:] - seg[:, :2]).T) / step)).astype(int)
    k = np.repeat(np.arange(len(seg)), n + 1)
    t = (np.arange(len(k)) - np.repeat(np.cumsum(n + 1) - (n + 1), n + 1)) / n[k]
    return seg[k, :2] * (1 - t[:, None]) + seg[k, 2:] * t[:, None]


def piece_contour(job_id: int, piece: int, pieces: int, kerf: float,
                  size: float = SQUARE_MM) -> np.ndarray:
    """The square the cutter follows: the outline offset out by half the kerf (mm)."""
    x, y = spot(job_id, piece, pieces)
    h = kerf / 2
    return np.array([[x - h, y - h], [x + size + h, y - h], [x + size + h, y + size + h],
                     [x - h, y + size + h]])


def main(argv: list[str]) -> int:
    """Serve one fleet station from a station.toml (for the kill tests)."""
    from station.daemon import setup_logging

    setup_logging()
    config = load_config(argv[0])
    return Daemon(config, simulated_pipeline(config, TinyJobs)).serve()


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
