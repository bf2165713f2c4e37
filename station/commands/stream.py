"""`station stream`: send a program to a GRBL controller and report what was cut."""

from __future__ import annotations

import argparse
import importlib
import json
import sys

from station.errors import UserError

# Where pyserial finds the GRBL emulator's URL scheme, if the simulators are installed.
_URL_HANDLERS = ("simulators.grbl",)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "stream",
        help="stream a program to a GRBL controller (serial port, pty or pyserial URL)",
        description="Character-counting streamer for GRBL 1.1. Checks the program against the "
        "machine profile and the controller's settings first; stops safely (feed hold, reset, "
        "laser off) on any error or alarm; a piece counts as cut only when its sync point "
        "answered.",
    )
    p.add_argument("program", metavar="JOB.nc", help="program written by `station gcode`")
    p.add_argument("--port", required=True,
                   help="serial device, pseudo-terminal, or pyserial URL (grblsim://...)")
    p.add_argument("--baud", type=int, default=115200, help="baud rate (default 115200)")
    p.add_argument("--machine", metavar="MACHINE.toml",
                   help="machine profile (default: the built-in laser table)")
    p.add_argument("--check", action="store_true",
                   help="run the program in GRBL's check mode ($C): parse only, no motion")
    p.add_argument("--unlock", action="store_true",
                   help="send $X if the controller starts in alarm (make the machine safe first)")
    p.add_argument("--no-settings-check", action="store_true",
                   help="do not compare the controller's $$ settings with the profile")
    p.add_argument("--trace", metavar="TRACE.csv",
                   help="with the emulator (grblsim://): write its executed motion, one segment "
                   "a line, x0,y0,x1,y1,feed,power,rapid in the program's work coordinates")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def open_port(url: str, baud: int):
    import serial

    """Open a device path or pyserial URL (emulator handlers registered when available)."""
    for pkg in _URL_HANDLERS:
        try:
            importlib.import_module(pkg)
        except ImportError:
            continue
        if pkg not in serial.protocol_handler_packages:
            serial.protocol_handler_packages.append(pkg)
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


def run(args: argparse.Namespace) -> int:
    # Imported here so that `station --help` and the other commands start fast.
    from gcode.grbl import check_settings
    from gcode.machine import default_machine, load_machine
    from gcode.program import load_program
    from gcode.stream import Streamer, StreamError

    machine = load_machine(args.machine) if args.machine else default_machine()
    program = load_program(args.program, machine)
    port = open_port(args.port, args.baud)
    emulator = getattr(port, "emulator", None)
    if args.trace and emulator is None:
        port.close()
        raise UserError(f"{args.port}: --trace needs the emulator (a grblsim:// port): a real "
                        "controller does not report its executed motion")
    bar = _Bar()
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
        result = streamer.run(program, check=args.check)
    except StreamError as exc:
        raise UserError(str(exc)) from None
    finally:
        bar.done()
        if args.trace and emulator is not None:
            from simulators.grbl.trace import write_trace

            emulator.wait_idle(5.0)  # a stopped job still brakes: trace all of it
            write_trace(emulator, args.trace)
        try:
            port.close()
        except Exception:  # noqa: BLE001 - closing a vanished port must not mask the result
            pass
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
    return 0 if result.completed else 1
