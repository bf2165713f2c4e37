"""The simulated station's roll shows what the GRBL emulator really burnt (issue 35): the
kerfs are cut into the cloth where the roll lay, travel with it on each advance, and are
still there for a restarted station."""

from __future__ import annotations

import numpy as np

from simulators.grbl.registry import forget, get_or_create
from station.config import load_config
from station.simstation import SimulatedRoll

NAME = "kerf-test"


def _darkest_column(photo: np.ndarray, rows: slice) -> int:
    """The column whose pixels in ``rows`` are darkest on average (the kerf across them)."""
    return int(np.argmin(photo[rows].astype(float).mean(axis=(0, 2))))


def test_the_simulated_roll_shows_the_emulators_kerfs_where_the_cloth_carries_them(tmp_path):
    emulator, _ = get_or_create(NAME, speed=1000.0, force_origin=True,
                                settings={32: 1, 130: 1600, 131: 1000})
    try:
        config = load_config(None, {"serial": {"port": f"grblsim://?name={NAME}"},
                                    "nest": {"length_mm": 800.0, "width_mm": 500.0},
                                    "store": {"path": str(tmp_path / "jobs.db"),
                                              "work_dir": str(tmp_path / "jobs")}})
        roll = SimulatedRoll(config)
        ox, oy = roll.origin
        # a cut across the roll, 700 mm along the fabric, from 100 to 400 mm across it
        emulator.receive(f"G21 G90\nG0 X{ox + 700:g} Y{oy + 100:g}\nM3 S800\n"
                         f"G1 X{ox + 700:g} Y{oy + 400:g} F3000\nM5\n".encode())
        assert emulator.wait_idle(10)
        rows = slice(150, 350)
        photo = roll.photograph()
        assert _darkest_column(photo, rows) == 700
        assert _darkest_column(photo, slice(420, 500)) != 700  # not cut there
        roll.advance(600.0)  # the conveyor slips: the kerf lies where the cloth went
        along = roll.conveyor.pose.along
        assert abs(_darkest_column(roll.photograph(), rows) - (700 - along)) <= 1.0
        # a restarted station finds the roll where it was, the kerf still cut into it
        again = SimulatedRoll(config)
        assert abs(_darkest_column(again.photograph(), rows) - (700 - along)) <= 1.0
    finally:
        forget(NAME)
