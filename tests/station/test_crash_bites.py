"""SIGKILL of the daemon between and within the bites of a marker longer than the table
(issue 35, recovery): the job resumes at the right bite, finds the print again, advances
the roll once and cuts nothing twice.

The model is `test_crash`: the GRBL emulator on a pseudo-terminal in this process (its
trace is the witness of what was cut), and `station serve --simulate` processes killed
and restarted, here on a small table with the simulated roll. The roll's cloth outlives
the daemon as a real roll does (`station.simroll` keeps its poses in the work folder),
and its conveyor takes the time the machine profile's says, the cloth moving only when
the move is over: a kill during the move leaves an advance sent and never run.
"""

from __future__ import annotations

import json
import os
import signal
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from solver.nest.layout import Layout
from station.config import load_config
from station.control import request
from station.daemon import wait_until
from station.jobstore import JobStore
from station.simroll import ROLL_STATE_FILE, kept_conveyor, load_poses, roll_state_path
from station.steps.bites import RollTrack, load_bites
from station.steps.cutbites import BITE_PIECES_FILE, STATE_FILE
from station.steps.program import fabric_origin, machine_layout, program_of, station_machine

from .test_crash import Station, check_cut_exactly_once

#: the simulated roll's print (`station.simstation`): a pmm plaid, 80 x 60 mm
FABRIC = {"group": "pmm", "w1": [80, 0], "w2": [0, 60], "origin": [13, 21], "units": "mm"}
CONVEYOR_MM_S = 500.0  # an advance of ~340 mm takes 0.7 s: time to kill it before it runs


def tube_obj(panels: int = 4, along: float = 100.0, across: float = 200.0) -> str:
    """OBJ text of a small garment: a tube of ``panels`` flat panels ``along`` x
    ``across`` mm, each sewn to the next along its long sides (a prism in 3D; vertices
    shared along the seams, the pattern's vt one panel beside the other)."""
    cols, rows, gap = 2, 3, 30.0
    radius = along / (2 * np.sin(np.pi / panels))
    corners = [radius * np.array([np.cos(a), np.sin(a)])
               for a in 2 * np.pi * np.arange(panels) / panels]
    verts: list[str] = []
    ids: dict[tuple[int, int, int], int] = {}

    def vertex(panel: int, c: int, r: int) -> int:
        key = ((panel + c // cols) % panels, 0, r) if c in (0, cols) else (panel, c, r)
        if key not in ids:
            a, b = corners[panel], corners[(panel + 1) % panels]
            x, y = a + (b - a) * c / cols
            verts.append(f"v {x:.4f} {y:.4f} {across * r / rows:.4f}")
            ids[key] = len(verts)
        return ids[key]

    uvs, faces = [], []
    for p in range(panels):
        uv = {}
        for c in range(cols + 1):
            for r in range(rows + 1):
                uvs.append(f"vt {p * (along + gap) + along * c / cols:.4f} {across * r / rows:.4f}")
                uv[c, r] = len(uvs)
        for c in range(cols):
            for r in range(rows):
                quad = [(c, r), (c + 1, r), (c + 1, r + 1), (c, r + 1)]
                for tri in ((0, 1, 2), (0, 2, 3)):
                    faces.append("f " + " ".join(f"{vertex(p, *quad[k])}/{uv[quad[k]]}"
                                                 for k in tri))
    return "\n".join(["# units: mm", *verts, *uvs, *faces]) + "\n"


class RollStation(Station):
    """`test_crash.Station` running `station serve --simulate`: a 400 x 320 mm table
    window on the simulated roll, a relay conveyor of ``CONVEYOR_MM_S``."""

    SERVE = ("serve", "--simulate")

    def __init__(self, tmp: Path, speed: float) -> None:
        super().__init__(tmp, speed)
        profile = tmp / "machine.toml"
        profile.write_text(resources.files("gcode").joinpath("default_machine.toml")
                           .read_text() + f'kind = "relay"\nmm_per_s = {CONVEYOR_MM_S}\n')
        self.config_path.write_text(
            f'[serial]\nport = "{os.path.realpath(tmp / "ttyGRBL")}"\n'  # --simulate: a pty
            f'[store]\npath = "{tmp / "jobs.db"}"\nwork_dir = "{tmp / "work"}"\n'
            f'[control]\nsocket = "{tmp / "station.sock"}"\n'
            f'[machine]\nprofile = "{profile}"\n'
            "[align]\nrestarts = 1\n[nest]\nseconds = 0.3\nlength_mm = 400\nwidth_mm = 320\n")
        self.fabric.write_text(json.dumps(FABRIC))
        self.garment = tmp / "tube.obj"
        self.garment.write_text(tube_obj())
        self._store: JobStore | None = None

    def poses(self) -> list:
        """The simulated roll's poses as its file keeps them (the first: where it lay)."""
        return load_poses(self.tmp / "work" / ROLL_STATE_FILE)

    def journal(self, job: int) -> dict:
        path = self.tmp / "work" / f"job-{job}" / STATE_FILE
        return json.loads(path.read_text()) if path.is_file() else {}

    @property
    def store(self) -> JobStore:
        """The job store the daemons share, opened once it exists (closed with the
        station)."""
        if self._store is None:
            self._store = JobStore(self.tmp / "jobs.db")
        return self._store

    def bite_events(self, job: int) -> list[str]:
        return [e["message"] for e in self.store.events(job) if e["kind"] == "bite"]

    def close(self) -> None:
        if self._store is not None:
            self._store.close()
        super().close()

    def kill_when(self, ready, what: str) -> None:
        assert wait_until(ready, 120, 0.005), (what, self.daemon_log())
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait()

    def restart_and_resume(self, job: int) -> None:
        self.start()
        st = self.status(job)
        assert st["state"] == "paused" and "interrupted" in st["reason"], st
        self.resume(job)


@pytest.fixture
def roll_station(tmp_path):
    s = RollStation(tmp_path, speed=60.0)
    yield s
    s.close()


def test_kills_between_and_within_bites_advance_the_roll_once_and_cut_each_piece_once(
        roll_station):
    s = roll_station
    s.start()
    job = request(s.socket, "submit", garment=str(s.garment), fabric=str(s.fabric),
                  options={})["job"]["id"]
    # 1. The advance to the second bite journalled and sent, the conveyor still moving:
    #    killed.
    s.kill_when(lambda: s.journal(job).get("advancing") == 1 and s.bite_events(job),
                "the advance journalled and sent")
    assert len(s.poses()) <= 1, "the roll moved: the kill came too late"
    s.restart_and_resume(job)
    # 2. The next daemon finds the roll where it was, and advances it: killed once the
    #    cloth has moved, before the advance is measured.
    s.kill_when(lambda: len(s.poses()) == 2, "the roll advanced")
    assert s.journal(job)["advancing"] == 1 and len(s.journal(job)["measured"]) == 1
    s.restart_and_resume(job)
    # 3. The advance measured, the second bite's first piece cut: killed within the bite.
    record = s.store.job(job).plan
    plan = load_bites(Layout.load(record["layout"]), Path(record["bites"]))
    second = set(plan.bites[1].pieces)
    assert len(plan.bites) == 2 and len(second) >= 2, plan.summary()

    def one_of_the_second_bite_cut() -> bool:
        return sum(p["state"] == "cut" and p["name"] in second
                   for p in s.store.pieces(job)) == 1

    s.kill_when(one_of_the_second_bite_cut, "a piece of the second bite cut")
    s.restart_and_resume(job)
    assert wait_until(lambda: s.status(job)["state"] == "done", 120), \
        (s.status(job), s.daemon_log())

    # The roll advanced once, and the station measured that advance from the print.
    poses = s.poses()
    assert len(poses) == 2
    journal = s.journal(job)
    measured = journal["measured"][1]
    assert measured["advance_measured_mm"] == pytest.approx(poses[1].along - poses[0].along,
                                                            abs=0.3)
    assert measured["skew_deg"] == pytest.approx(poses[1].angle_deg, abs=0.05)
    events = s.bite_events(job)
    asked = ["advancing the roll", "the roll had not moved", "advancing the roll",
             "advance "]  # sent, never run; found unmoved; sent again; measured once
    assert len(events) == len(asked), events
    assert all(m.startswith(f"bite 2 of 2: {a}") for m, a in zip(events, asked)), events
    pieces = s.store.pieces(job)
    assert {p["name"]: p["bite"] for p in pieces} == plan.bite_of()

    # Each piece cut exactly once, by the machine's own trace, where its bite lay.
    config = load_config(s.config_path)
    machine = station_machine(config)
    tracks = [RollTrack(), RollTrack(np.asarray(journal["track"], float))]
    for bite, track in zip(plan.bites, tracks, strict=True):  # what each cut was handed
        cut = json.loads((s.tmp / "work" / f"job-{job}" / BITE_PIECES_FILE.format(
            index=bite.index)).read_text())  # (no photograph, so no local maps)
        np.testing.assert_allclose(cut["track"], track.marker_to_window, atol=1e-9)

    def program_of_piece(name: str):
        bite = plan.bites[plan.bite_of()[name]]
        marker = machine_layout(tracks[bite.index].bite_layout(plan, bite),
                                fabric_origin(config), record["layout"])
        return program_of(marker, machine, {name}, title="bite")[0]

    check_cut_exactly_once(s, job, program_of_piece)


def test_the_simulated_roll_lies_where_the_last_process_left_it(tmp_path):
    config = load_config(None, {"store": {"work_dir": str(tmp_path / "work")}})
    first = kept_conveyor(config, None, (200.0, 160.0))
    first.advance(300.0)
    again = kept_conveyor(config, None, (200.0, 160.0))  # a restarted station
    assert again.poses == first.poses
    second = again.advance(300.0).along - first.poses[1].along - 300.0
    first_slip = first.poses[1].along - 300.0
    assert abs(second) <= 3.0 and second != first_slip  # not the first advance replayed
    assert len(load_poses(roll_state_path(config))) == 3
    assert kept_conveyor(config, None, (100.0, 160.0)).poses[1:] == []  # another table
