"""`station serve`: the daemon (with ``--simulate``, against the simulated camera and GRBL)."""

from __future__ import annotations

import argparse
import logging
import os

from station.cliargs import add_config_argument, load_config_arg


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
    from station.daemon import Daemon, setup_logging
    from station.pipeline import StationPipeline

    setup_logging(logging.DEBUG if args.verbose else logging.INFO)
    overrides = {"camera": {"source": "simulated"}} if args.simulate else None
    config = load_config_arg(args, overrides)
    if args.simulate and "grblsim://" not in config["serial"]["port"] and \
            not config["serial"]["port"].startswith("/dev/pts"):
        raise ValueError(f"--simulate needs a simulated port (grblsim://...), the configuration "
                         f"names {config['serial']['port']}")
    os.umask(config["store"]["umask"])  # before any file: job files 0640, folders 0750
    if args.simulate:  # the simulators, only when the user asked for a simulation
        from station.simstation import simulated_pipeline

        pipeline = simulated_pipeline(config)
    else:
        pipeline = StationPipeline(config)
    daemon = Daemon(config, pipeline)
    return daemon.serve(once=args.once)
