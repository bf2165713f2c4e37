"""`station serve`: the daemon (with ``--simulate``, against the simulated camera and GRBL)."""

from __future__ import annotations

import argparse
import logging
import os

from station.cliargs import add_config_argument, load_config_arg
from station.config import EMULATOR_PORT, Config
from station.daemon import Daemon, setup_logging
from station.errors import UserError
from station.pipeline import StationPipeline


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "serve", help="run the station daemon",
        description="Take jobs in order: photograph, detect, align, nest, program and cut. "
        "Stops safely on SIGTERM (feed hold, laser off, state saved).")
    add_config_argument(p)
    p.add_argument("--simulate", action="store_true",
                   help="dry run: synthetic camera and GRBL emulator, otherwise the same code")
    p.add_argument("--once", action="store_true", help="exit when the queue is empty")
    p.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    config = checked_config(args)
    os.umask(config["store"]["umask"])  # before any file: job files 0640, folders 0750
    if args.simulate:
        # Only a dry run loads the simulators (107 ms on top of the daemon, measured): a
        # real daemon never imports them, so pyserial never knows grblsim:// there.
        from station.simstation import simulated_pipeline

        pipeline = simulated_pipeline(config)
    else:
        pipeline = StationPipeline(config)
    daemon = Daemon(config, pipeline)
    # only once every check at start has passed: a refused start leaves logging as it was
    setup_logging(logging.DEBUG if args.verbose else logging.INFO)
    return daemon.serve(once=args.once)


def checked_config(args: argparse.Namespace) -> Config:
    """The station's configuration, its port checked before anything starts: a real
    station names its controller; a dry run gets the emulator unless it names a pty."""
    if not args.simulate:
        config = load_config_arg(args)
        port = config["serial"]["port"]
        if not port:
            where = config.path or "the built-in defaults (no station.toml)"
            raise UserError(f"serial.port is not set in {where}: name the GRBL controller's "
                            "port (e.g. port = \"/dev/ttyUSB0\" under [serial]), or try the "
                            "station with `station serve --simulate`")
        if port.startswith("grblsim://"):
            raise UserError(f"serial.port {port.split('?', 1)[0]} is the GRBL emulator: a "
                            "dry run is `station serve --simulate`")
        return config
    simulated = {"camera": {"source": "simulated"}}
    config = load_config_arg(args, simulated)
    port = config["serial"]["port"]
    if not port:
        return load_config_arg(args, {**simulated, "serial": {"port": EMULATOR_PORT}})
    if not port.startswith(("grblsim://", "/dev/pts")):
        raise UserError(f"--simulate needs a simulated port (grblsim://...), the "
                        f"configuration names {port}")
    return config
