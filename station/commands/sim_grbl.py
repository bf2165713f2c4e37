"""`station sim-grbl --pty`: serve the GRBL 1.1h emulator on a pseudo-terminal."""

from __future__ import annotations

import argparse
import signal
import sys
import threading

from simulators.grbl import Faults, GrblEmulator
from simulators.grbl.pty import PtyBridge


def _line_code(text: str) -> tuple[int, int]:
    line, sep, code = text.partition(":")
    if not sep or not line.isdigit() or not code.isdigit():
        raise argparse.ArgumentTypeError(f"expected LINE:CODE, got {text!r}")
    return int(line), int(code)


def _setting(text: str) -> tuple[int, float]:
    key, sep, value = text.lstrip("$").partition("=")
    try:
        return int(key), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected N=VALUE (a $N setting), got {text!r}") from None


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "sim-grbl",
        help="serve the GRBL 1.1 emulator on a pseudo-terminal",
        description="Run an emulated GRBL 1.1h controller and serve it on a pseudo-terminal. "
        "The first line on stdout is the device path; any sender (a terminal, pyserial, "
        "`station stream`) can open it like a real controller. Serves until SIGINT/SIGTERM.",
    )
    p.add_argument("--pty", action="store_true", required=True,
                   help="serve on a pseudo-terminal (the only transport)")
    p.add_argument("--speed", type=float, default=1.0,
                   help="simulated seconds per wall-clock second (default 1)")
    p.add_argument("--link", metavar="PATH",
                   help="also make PATH a symlink to the device (kept across reconnects)")
    p.add_argument("--setting", type=_setting, action="append", default=[], metavar="N=V",
                   help="preset a $N setting before boot, e.g. 22=1 (homing) or 32=1 (laser)")
    p.add_argument("--force-origin", action="store_true",
                   help="build option HOMING_FORCE_SET_ORIGIN: homing sets the origin at 0")
    p.add_argument("--error-at", type=_line_code, action="append", default=[],
                   metavar="LINE:CODE", help="answer line LINE with error:CODE")
    p.add_argument("--alarm-at", type=_line_code, action="append", default=[],
                   metavar="LINE:CODE", help="raise ALARM:CODE at line LINE")
    for name, what in (("drop-byte-at", "drop received byte N"),
                       ("flip-byte-at", "flip bit 0 of received byte N"),
                       ("reset-at", "soft-reset when line N arrives"),
                       ("disconnect-at", "close the pty when line N arrives (reopened after)"),
                       ("power-cut-at", "power cut when line N arrives")):
        p.add_argument(f"--{name}", type=int, action="append", default=[], metavar="N",
                       help=what)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    # ValueError (not station.cli.UserError): also reported cleanly under `python -m station.cli`,
    # where cli.py runs as __main__ and its UserError is another class.

    if not args.speed > 0:
        raise ValueError(f"--speed must be > 0, got {args.speed}")
    faults = Faults(
        error_at=dict(args.error_at), alarm_at=dict(args.alarm_at),
        drop_byte_at=set(args.drop_byte_at), flip_byte_at=set(args.flip_byte_at),
        reset_at=set(args.reset_at), disconnect_at=set(args.disconnect_at),
        power_cut_at=set(args.power_cut_at),
    )
    try:
        # a sender on the pty cannot know the speed to pace its polls by: never paced
        emulator = GrblEmulator(speed=args.speed, faults=faults, force_origin=args.force_origin,
                                settings=dict(args.setting), paced=False)
    except ValueError as exc:
        raise ValueError(f"--setting: {exc}") from None
    bridge = PtyBridge(emulator, link=args.link)
    stop = threading.Event()

    def on_signal(signum, frame):  # only set a flag; the serve loop acts on it
        stop.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    print(bridge.path, flush=True)
    print(f"station sim-grbl: serving GRBL 1.1h on {bridge.path}"
          f" (speed x{args.speed:g})", file=sys.stderr, flush=True)

    def on_reopen(path: str) -> None:
        print(path, flush=True)
        print(f"station sim-grbl: reconnected on {path}", file=sys.stderr, flush=True)

    try:
        bridge.serve(stop, on_reopen=on_reopen)
    finally:
        bridge.close()
        emulator.close()
    return 0
