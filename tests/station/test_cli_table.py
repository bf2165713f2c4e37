"""`station` lists its commands from one table and imports only the command it runs."""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import subprocess
import sys

from station import commands
from station.cli import main
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


def _simulation_entry_point(module: str) -> bool:
    return any(word in module for word in ("demo", "sim", "simulat"))


def test_only_simulation_commands_load_the_simulators():
    """A real station's commands neither import `simulators` nor give pyserial the
    emulator's grblsim:// scheme; the simulate-*, sim-grbl and demo commands do."""
    real = sorted({c.module for c in COMMANDS.values()
                   if not _simulation_entry_point(c.module)})
    code = ("import importlib, sys, serial\n"
            f"for name in {real!r}:\n"
            "    importlib.import_module('station.commands.' + name)\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] == 'simulators'),\n"
            "      'simulators.grbl' in serial.protocol_handler_packages)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[] False"
    assert {"demo", "sim_grbl", "simulate_calibration", "simulate_stream"} <= \
        {c.module for c in COMMANDS.values() if _simulation_entry_point(c.module)}


def test_stream_refuses_the_emulator_and_names_the_simulation(tmp_path, capsys):
    program = tmp_path / "job.nc"
    program.write_text("G21 G90\nG0 X10 Y10\nM2\n")
    assert main(["stream", str(program), "--port", "grblsim://?speed=1000"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "grblsim://: the GRBL emulator is a simulation" in err
    assert "station simulate-stream" in err
