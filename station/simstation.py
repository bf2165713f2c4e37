"""The simulated station both demos run on: the real daemon and pipeline, on an emulated
GRBL and the synthetic camera, and the job files they copy out of its temporary folders.
"""

from __future__ import annotations

import argparse
import json
import shutil
import threading
from pathlib import Path
from typing import Any

from station.config import EMULATOR_PORT, load_config
from station.daemon import Daemon
from station.pipeline import StationPipeline

__all__ = ["copy_job_files", "read_json_or_empty", "start_simulated_station"]


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
    daemon = Daemon(config, StationPipeline(config, simulate=True))
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
