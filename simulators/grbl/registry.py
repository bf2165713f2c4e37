"""Named emulator instances, so a test can reopen the same machine after a disconnect."""

from __future__ import annotations

import threading

from simulators.grbl.emulator import GrblEmulator

_LOCK = threading.Lock()
_MACHINES: dict[str, GrblEmulator] = {}


def get_or_create(name: str | None, **options) -> tuple[GrblEmulator, bool]:
    """The machine called `name` (created with `options` if new); (machine, created)."""
    if name is None:
        return GrblEmulator(**options), True
    with _LOCK:
        machine = _MACHINES.get(name)
        if machine is not None:
            return machine, False
        machine = GrblEmulator(name=name, **options)
        _MACHINES[name] = machine
        return machine, True


def lookup(name: str) -> GrblEmulator | None:
    with _LOCK:
        return _MACHINES.get(name)


def forget(name: str) -> None:
    """Stop and drop a named machine (tests call this to clean up)."""
    with _LOCK:
        machine = _MACHINES.pop(name, None)
    if machine is not None:
        machine.close()
