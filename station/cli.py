"""The `station` console command: discovers subcommands in `station.commands`."""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

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


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (UserError, ValueError, FileNotFoundError) as exc:
        print(f"station {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"station {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # `station ... | head` closed the pipe: not a fault
        sys.stdout = None  # nothing more can be written; silence the flush at exit
        return 0


if __name__ == "__main__":
    sys.exit(main())
