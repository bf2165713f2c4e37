"""`station stream`: send a program to a GRBL controller and report what was cut.

The controller is a serial device, a pseudo-terminal or a pyserial URL. The GRBL
emulator's ``grblsim://`` is not one of them: `station simulate-stream`
(`station.commands.simulate_stream`) streams to it, with the same code from here.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable

import serial

from gcode.grbl import check_settings
from gcode.machine import Machine, default_machine, load_machine
from gcode.program import Program, load_program
from gcode.stream import Streamer, StreamError, StreamResult
from station.errors import UserError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "stream",
        help="stream a program to a GRBL controller (serial port, pty or pyserial URL)",
        description="Character-counting streamer for GRBL 1.1. Checks the program against the "
        "machine profile and the controller's settings first; stops safely (feed hold, reset, "
        "laser off) on any error or alarm; a piece counts as cut only when its sync point "
        "answered.",
    )
    p.add_argument("--port", required=True,
                   help="serial device, pseudo-terminal, or pyserial URL (e.g. socket://)")
    add_stream_arguments(p)
    p.set_defaults(func=run)


def add_stream_arguments(p: argparse.ArgumentParser) -> None:
    """The program and how to stream it: shared with simulate-stream."""
    p.add_argument("program", metavar="JOB.nc", help="program written by `station gcode`")
    p.add_argument("--baud", type=int, default=115200, help="baud rate (default 115200)")
    p.add_argument("--machine", metavar="MACHINE.toml",
                   help="machine profile (default: the built-in laser table)")
    p.add_argument("--check", action="store_true",
                   help="run the program in GRBL's check mode ($C): parse only, no motion")
    p.add_argument("--unlock", action="store_true",
                   help="send $X if the controller starts in alarm (make the machine safe first)")
    p.add_argument("--no-settings-check", action="store_true",
                   help="do not compare the controller's $$ settings with the profile")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def run(args: argparse.Namespace) -> int:
    if args.port.startswith("grblsim://"):
        raise UserError(f"{args.port.split('?', 1)[0]}: the GRBL emulator is a simulation: "
                        "stream to it with `station simulate-stream`")
    machine, program = load_job(args)
    return stream_and_report(args, open_port(args.port, args.baud), machine, program)


def load_job(args: argparse.Namespace) -> tuple[Machine, Program]:
    """The machine profile and the program checked against it, before any port opens."""
    machine = load_machine(args.machine) if args.machine else default_machine()
    return machine, load_program(args.program, machine)


def open_port(url: str, baud: int) -> serial.SerialBase:
    """A device path or a pyserial URL of a handler installed in this process."""
    try:
        return serial.serial_for_url(url, baudrate=baud, timeout=0.02)
    except (serial.SerialException, ValueError) as exc:
        raise UserError(f"{url}: cannot open port: {exc}") from None


class _Bar:
    """A one-line progress bar on stderr when it is a terminal."""

    def __init__(self) -> None:
        self.tty = sys.stderr.isatty()

    def __call__(self, p) -> None:
        if not self.tty:
            return
        width = 30
        fill = int(round(p.fraction * width))
        eta = "--:--" if p.eta_seconds is None else f"{int(p.eta_seconds // 60)}:" \
                                                     f"{int(p.eta_seconds % 60):02d}"
        sys.stderr.write(f"\r[{'#' * fill}{'.' * (width - fill)}] {p.fraction * 100:5.1f}% "
                         f"{p.lines_acked}/{p.lines_total} lines  pieces cut {p.pieces_cut}  "
                         f"ETA {eta}  {p.state or ''}   ")
        sys.stderr.flush()

    def done(self) -> None:
        if self.tty:
            sys.stderr.write("\n")


def stream_and_report(args: argparse.Namespace, port: serial.SerialBase, machine: Machine,
                      program: Program, *, before_close: Callable[[], None] | None = None
                      ) -> int:
    """Stream ``program`` on ``port`` and report it; ``before_close`` runs after the run
    (stopped or not) while the port is still open. Exit status 1 when it did not complete."""
    bar = _Bar()
    try:
        result = _stream(args, port, machine, program, bar)
    finally:
        bar.done()
        if before_close is not None:
            before_close()
        try:
            port.close()
        except Exception:  # noqa: BLE001 - closing a vanished port must not mask the result
            pass
    _report(args, result)
    return 0 if result.completed else 1


def _stream(args: argparse.Namespace, port: serial.SerialBase, machine: Machine,
            program: Program, bar: _Bar) -> StreamResult:
    try:
        streamer = Streamer(port, rx_buffer=machine.rx_buffer, on_progress=bar,
                            acceleration=machine.acceleration, rapid_feed=machine.rapid_feed,
                            name=args.port)
        try:
            streamer.connect()
        except StreamError as exc:
            if not (args.unlock and "ALARM" in str(exc)):
                raise UserError(str(exc)) from None
            streamer.unlock()
        if not args.no_settings_check:
            faults = check_settings(streamer.read_settings(), machine)
            if faults:
                raise UserError(f"{args.port}: controller settings disagree with the profile "
                                f"{machine.source}: " + "; ".join(faults))
        return streamer.run(program, check=args.check)
    except StreamError as exc:
        raise UserError(str(exc)) from None


def _report(args: argparse.Namespace, result: StreamResult) -> None:
    out = {
        "completed": result.completed,
        "reason": result.reason,
        "check": result.check,
        "lines_total": result.lines_total,
        "lines_sent": result.lines_sent,
        "lines_acked": result.lines_acked,
        "errors": len(result.errors),
        "alarms": len(result.alarms),
        "pieces": len(result.pieces),
        "pieces_cut": result.pieces_cut,
        "seconds": round(result.seconds, 3),
        "fault": result.fault,
        "error_details": result.errors,
        "alarm_details": result.alarms,
        "piece_states": [{"number": p.number, "id": p.id, "state": p.state}
                         for p in result.pieces],
    }
    if args.json:
        print(json.dumps(out))
    else:
        what = "checked" if args.check else "streamed"
        print(f"{args.program}: {what} {result.lines_acked}/{result.lines_total} lines, "
              f"{result.pieces_cut}/{len(result.pieces)} pieces cut, {len(result.errors)} "
              f"errors, {len(result.alarms)} alarms, {result.seconds:.1f} s: {result.reason}")
        if result.fault:
            f = result.fault
            print(f"stopped at line {f['line']}: {f['detail']} (machine at {f['position']})",
                  file=sys.stderr)
