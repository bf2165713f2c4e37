"""Errors raised by the garment importers.

Every fault is reported as one line, ``"FILE: fault"``, so that the station's console can
print it verbatim and the operator knows which file to fix and what is wrong with it.
"""

from __future__ import annotations

from pathlib import Path


class GarmentError(ValueError):
    """Bad garment input: one line naming the file and the fault."""

    def __init__(self, path: str | Path | None, fault: str) -> None:
        self.path = None if path is None else str(path)
        self.fault = fault
        super().__init__(fault if path is None else f"{path}: {fault}")
