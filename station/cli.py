"""The `station` console command: the commands named in `station.commands.COMMANDS`."""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import warnings
from collections.abc import Sequence

from station import commands
from station.commands import COMMANDS
from station.errors import UserError


def build_parser(argv: Sequence[str] = ()) -> argparse.ArgumentParser:
    """The parser for one call: the command named in ``argv`` in full, the others by name.

    Only the chosen command's module is imported (by name, through importlib): importing
    every command module to build every parser made every call pay for the whole house
    (`station --help` took 0.17 to 0.26 s and 366 modules; now 0.035 s and 89).
    Every other command is a stub with its name and help, enough for `station --help`
    and for argparse's "invalid choice" message to list them all.
    """
    parser = argparse.ArgumentParser(
        prog="station",
        description="Cutting-station controller: aligns printed fabric across garment seams "
        "and cuts the pieces on a GRBL laser or knife.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    chosen = next((arg for arg in argv if not arg.startswith("-")), None)
    module = COMMANDS[chosen].module if chosen in COMMANDS else None
    registered = False
    for name, command in COMMANDS.items():
        if command.module != module:
            sub.add_parser(name, help=command.help)
        elif not registered:  # the module's first command: its register() adds them all
            importlib.import_module(f"{commands.__name__}.{module}").register(sub)
            registered = True
    return parser


def one_line(exc: BaseException) -> str:
    """The exception's text on one line, at most 500 characters."""
    text = " ".join(str(exc).split())
    return text if len(text) <= 500 else text[:497] + "..."


def _warn_on_one_line(command: str):
    """Every warning a command raises as one ``station CMD: warning: ...`` line on stderr,
    like its errors (Python's own format adds the file, line and source of the call)."""
    def show(message, category, filename, lineno, file=None, line=None) -> None:
        print(f"station {command}: warning: {one_line(message)}", file=sys.stderr)
    return show


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    args = build_parser(argv).parse_args(argv)
    with warnings.catch_warnings():  # the command's warnings only, then Python's way again
        warnings.showwarning = _warn_on_one_line(args.command)
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    """The command, every fault one line on stderr and an exit status."""
    try:
        return int(args.func(args) or 0)
    except (UserError, ValueError, FileNotFoundError) as exc:
        print(f"station {args.command}: error: {one_line(exc)}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # `station ... | head` closed the pipe: not a fault
        sys.stdout = None  # nothing more can be written; silence the flush at exit
        return 0
    except OSError as exc:  # a folder, a device or a permission where a file was expected
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"station {args.command}: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2
    except (RecursionError, MemoryError, OverflowError) as exc:  # input beyond any checker
        print(f"station {args.command}: error: input too large or too deep "
              f"({type(exc).__name__}: {one_line(exc)})", file=sys.stderr)
        return 2
    except Exception as exc:  # a bug, not the operator's fault: still one line, exit 70
        if os.environ.get("STATION_TRACEBACK"):
            raise
        print(f"station {args.command}: internal error: {type(exc).__name__}: {one_line(exc)} "
              "(STATION_TRACEBACK=1 shows where)", file=sys.stderr)
        return 70
    except KeyboardInterrupt:
        print(f"station {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
