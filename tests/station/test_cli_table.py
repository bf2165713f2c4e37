"""`station` lists its commands from one table and imports only the command it runs."""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import subprocess
import sys

from station import commands
from station.commands import COMMANDS


def _registered(module_name: str) -> dict[str, str]:
    """Command name -> one-line help, as the module's register() adds them."""
    module = importlib.import_module(f"{commands.__name__}.{module_name}")
    sub = argparse.ArgumentParser().add_subparsers()
    module.register(sub)
    return {action.dest: action.help for action in sub._choices_actions}


def test_the_table_names_every_command_with_its_module_and_help():
    modules = {info.name for info in pkgutil.iter_modules(commands.__path__)}
    assert {c.module for c in COMMANDS.values()} <= modules, "the table names a lost module"
    for name in sorted(modules):
        in_table = {n: c.help for n, c in COMMANDS.items() if c.module == name}
        assert _registered(name) == in_table, f"station/commands/{name}.py and COMMANDS differ"


def _command_modules_after(argv: list[str]) -> tuple[int, list[str], str]:
    """Run `station ARGV` in a fresh interpreter: exit status, command modules, stderr."""
    code = ("import contextlib, io, sys, station.cli\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            "    try:\n"
            f"        status = station.cli.main({argv!r})\n"
            "    except SystemExit as exc:\n"
            "        status = exc.code\n"
            "print(status, *sorted(m for m in sys.modules if m.startswith('station.commands.')))")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    status, *modules = run.stdout.split()
    return int(status), modules, run.stderr


def test_a_command_imports_its_own_module_only():
    status, modules, _ = _command_modules_after(["status", "--help"])
    assert status == 0
    assert modules == ["station.commands.console"]


def test_help_and_a_bad_command_list_every_command_importing_none():
    status, modules, _ = _command_modules_after(["--help"])
    assert (status, modules) == (0, [])
    status, modules, err = _command_modules_after(["cutt"])
    assert (status, modules) == (2, [])
    assert "invalid choice: 'cutt'" in err
    assert all(f"'{name}'" in err for name in COMMANDS)
