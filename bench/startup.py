"""Start-up of the `station` command: what each call pays before it does any work.

`station` imports only the module of the command it runs (`station.cli.build_parser`), and
a command's module imports its stack at the top; this measures, per command, the CPU
seconds of the whole process (median of several runs) and the modules it imported.

Run: ``python -m bench startup``.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys

COMMANDS = (["--help"], ["status", "--help"], ["submit", "--help"], ["serve", "--help"],
            ["stream", "--help"], ["nest", "--help"], ["simulate-stream", "--help"])
RUNS = 9

_COUNT = ("import contextlib, io, sys, station.cli\n"
          "with contextlib.suppress(SystemExit), contextlib.redirect_stdout(io.StringIO()):\n"
          "    station.cli.main({argv!r})\n"
          "print(len(sys.modules))")


def cpu_seconds(argv: list[str]) -> float:
    """Median user+system CPU seconds of ``station ARGV`` in a fresh interpreter."""
    runs = []
    for _ in range(RUNS):
        before = os.times()
        subprocess.run([sys.executable, "-m", "station.cli", *argv], check=False,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        after = os.times()
        runs.append(after.children_user - before.children_user
                    + after.children_system - before.children_system)
    return statistics.median(runs)


def modules_imported(argv: list[str]) -> int:
    """len(sys.modules) after ``station ARGV`` (Python itself starts with about 70)."""
    out = subprocess.run([sys.executable, "-c", _COUNT.format(argv=argv)], check=True,
                         capture_output=True, text=True).stdout
    return int(out)


def main() -> None:
    print(f"| command | CPU s (median of {RUNS}) | modules imported |")
    print("| --- | --- | --- |")
    for argv in COMMANDS:
        print(f"| `station {' '.join(argv)}` | {cpu_seconds(argv):.2f} | "
              f"{modules_imported(argv)} |", flush=True)


if __name__ == "__main__":
    main()
