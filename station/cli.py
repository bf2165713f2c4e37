"""The `station` console command: discovers subcommands in `station.commands`."""

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import sys
import warnings

from station import commands
from station.errors import UserError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="station",
        description="Cutting-station controller: aligns printed fabric across garment seams "
        "and cuts the pieces on a GRBL laser or knife.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        module = importlib.import_module(f"{commands.__name__}.{info.name}")
        module.register(sub)
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
    args = build_parser().parse_args(argv)
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
