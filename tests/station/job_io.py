"""What one job's steps read and load inside the daemon's process: the proof that they hand
each other objects, not files (issue 16).

Counters are wrapped around the real functions (nothing is stubbed): every call of the
garment loader, and every file opened for reading that the job wrote earlier (through
Python's ``open``, ``Path.read_text``, ``os.open`` (how untrusted input is read) and
``cv2.imread``; writes through the same and ``cv2.imwrite``). Only the named threads count:
the daemon's job thread and its streamer; not the control thread's intake, whose copy of
the submitted garment is the job's input, nor the demo reading the job's files for the
operator afterwards.
"""

from __future__ import annotations

import builtins
import io
import os
import threading
from collections import Counter
from pathlib import Path

import cv2
import pytest

import solver.garment


class JobIO:
    """Garment loads and read-backs seen in ``threads`` while installed."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch, threads: tuple[str, ...]):
        self.threads = threads
        self.garment_loads: list[str] = []
        self.written: set[str] = set()
        self.read_back: Counter[str] = Counter()
        real_open, real_load = builtins.open, solver.garment.load_garment
        real_imread, real_imwrite = cv2.imread, cv2.imwrite
        real_os_open = os.open
        writing = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_APPEND | os.O_TRUNC

        def counting_os_open(path, flags, *args, **kwargs):
            self._saw(path, "w" if flags & writing else "r")
            return real_os_open(path, flags, *args, **kwargs)

        def counting_open(file, mode="r", *args, **kwargs):
            self._saw(file, mode)
            return real_open(file, mode, *args, **kwargs)

        def counting_load(path, *args, **kwargs):
            if self._counted():
                self.garment_loads.append(str(path))
            return real_load(path, *args, **kwargs)

        def counting_imread(path, *args, **kwargs):
            self._saw(path, "r")
            return real_imread(path, *args, **kwargs)

        def counting_imwrite(path, *args, **kwargs):
            self._saw(path, "w")
            return real_imwrite(path, *args, **kwargs)

        monkeypatch.setattr(builtins, "open", counting_open)
        monkeypatch.setattr(io, "open", counting_open)  # what pathlib opens with
        monkeypatch.setattr(os, "open", counting_os_open)
        monkeypatch.setattr(solver.garment, "load_garment", counting_load)
        monkeypatch.setattr(cv2, "imread", counting_imread)
        monkeypatch.setattr(cv2, "imwrite", counting_imwrite)

    def _counted(self) -> bool:
        return threading.current_thread().name in self.threads

    def _saw(self, file, mode: str) -> None:
        if isinstance(file, int) or not self._counted():
            return
        path = os.path.abspath(os.fspath(file))
        if any(m in mode for m in "wax+"):
            self.written.add(path)
        elif path in self.written:
            self.read_back[Path(path).name] += 1
