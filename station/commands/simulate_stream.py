"""`station simulate-stream`: `station stream` to the GRBL emulator, with its motion traced.

Importing this module registers pyserial's ``grblsim://`` handler (`simulators.grbl`): only
simulation entry points reach the emulator, so a real station cannot stream to it by a
slip of its configuration.
"""

from __future__ import annotations

import argparse

import simulators.grbl  # noqa: F401  (registers grblsim:// with pyserial)
from simulators.grbl.trace import write_trace
from station.commands.stream import add_stream_arguments, load_job, open_port, stream_and_report
from station.config import EMULATOR_PORT
from station.errors import UserError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "simulate-stream", help="stream a program to the GRBL emulator, tracing its motion",
        description="`station stream` on the emulated GRBL 1.1h controller (grblsim://), "
        "optionally writing the motion it executed.")
    p.add_argument("--port", default=EMULATOR_PORT,
                   help="the emulator's URL, grblsim://?speed=S&settings=... (default: the "
                   "emulated laser table of `station serve --simulate`)")
    add_stream_arguments(p)
    p.add_argument("--trace", metavar="TRACE.csv",
                   help="write the emulator's executed motion, one segment a line, "
                   "x0,y0,x1,y1,feed,power,rapid in the program's work coordinates")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    machine, program = load_job(args)
    port = open_port(args.port, args.baud)
    emulator = getattr(port, "emulator", None)
    if args.trace and emulator is None:
        port.close()
        raise UserError(f"{args.port}: --trace needs the emulator (a grblsim:// port): a real "
                        "controller does not report its executed motion")

    def trace() -> None:
        emulator.wait_idle(5.0)  # a stopped job still brakes: trace all of it
        write_trace(emulator, args.trace)

    return stream_and_report(args, port, machine, program,
                             before_close=trace if args.trace else None)
