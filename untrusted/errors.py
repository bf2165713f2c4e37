"""The one error type of untrusted input: a single line ``FILE: fault``."""

from __future__ import annotations

from pathlib import Path


class InputError(ValueError):
    """A fault in a file or request from outside; ``str()`` is the one line to print.

    A ValueError, so every command's existing ``FILE: fault`` / exit-2 path shows it.
    """

    def __init__(self, source: str | Path, fault: str) -> None:
        self.source = str(source)
        self.fault = " ".join(str(fault).split())  # one line, whatever the fault text held
        super().__init__(f"{self.source}: {self.fault}")
