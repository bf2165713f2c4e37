"""Errors raised by the garment importers.

Every fault is reported as one line, ``"FILE: fault"``, so that the station's console can
print it verbatim and the operator knows which file to fix and what is wrong with it.
"""

from __future__ import annotations

from pathlib import Path

from untrusted import InputError


class GarmentError(InputError):
    """Bad garment input: one line naming the file and the fault (the reading layer's
    :class:`untrusted.InputError`, so every reader's faults are caught alike)."""

    def __init__(self, path: str | Path | None, fault: str) -> None:
        super().__init__("<garment>" if path is None else path, fault)
        self.path = None if path is None else str(path)
        if path is None:
            self.args = (self.fault,)
