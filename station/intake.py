"""Taking in a submission: bounded request fields, inputs copied at submit time, and the
pipeline's check run in a child process with limits (see :mod:`station.sandbox`).

Only one check runs at a time; further submissions wait their turn in their own connection
thread, so a burst of huge submissions costs one bounded child, never the daemon's memory.
"""

from __future__ import annotations

import math
import os
import re
import secrets
import shutil
import signal
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import untrusted
from solver.garment.obj import pair_partner
from station.control import ControlError
from station.order import is_order_file, order_patterns
from station.sandbox import SandboxError, run_limited

#: files that travel with a garment: a Berkeley -m/-w partner is found by name, and the
#: licence README must stay beside the copy (see station.render.garment_credit)
_COMPANIONS = ("README.txt", "BERKELEY-README.txt")
MAX_OPTIONS = 16
#: integer job options and their ranges (10^9 alignment restarts allocated 23 GB)
INT_OPTIONS = {"restarts": (1, 10_000), "seed": (0, 2**32 - 1)}

Check = Callable[[str, "str | None", dict[str, Any]], None]


class Intake:
    """Admits submissions into ``folder`` (one sub-folder per submission)."""

    def __init__(self, folder: Path, check: Check | None, *, seconds: float,
                 memory_bytes: int, allowed: list[Path] | None = None) -> None:
        self.folder = folder
        self.check = check
        self.allowed = [p.resolve() for p in allowed or []]
        self.seconds = seconds
        self.memory_bytes = memory_bytes
        self._turn = threading.Semaphore(1)
        self._child: int | None = None

    def stop(self) -> None:
        """Kill a check in progress (the daemon is stopping; its submitter gets an error)."""
        pid = self._child
        if pid is not None:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass

    def _track(self, pid: int | None) -> None:
        self._child = pid

    def admit(self, req: dict[str, Any]) -> tuple[str, str | None, dict[str, Any]]:
        """(garment copy, fabric copy or None, options) of an accepted submission."""
        garment = _source(req.get("garment"), "garment")
        fabric = req.get("fabric")
        if fabric is not None:
            fabric = _source(fabric, "fabric")
        for path in (garment, fabric):
            if path is not None and self.allowed and \
                    not any(path.is_relative_to(folder) for folder in self.allowed):
                raise ControlError(f"{path}: submissions are accepted only from "
                                   f"{', '.join(map(str, self.allowed))}")
        options = _options(req.get("options"))
        target = self.folder / secrets.token_hex(6)
        g_copy: Path | None = None
        f_copy: Path | None = None
        try:
            target.mkdir(parents=True)
            g_copy = (_copy_order(garment, target, self.allowed) if is_order_file(garment)
                      else _copy_garment(garment, target))
            if fabric is not None:
                (target / "fabric").mkdir()
                f_copy = target / "fabric" / fabric.name
                untrusted.copy_file(fabric, f_copy, what="fabric",
                                    max_bytes=untrusted.limits.MAX_JSON_BYTES)
            if self.check is not None:
                with self._turn:
                    run_limited(self.check, str(g_copy), None if f_copy is None else str(f_copy),
                                options, seconds=self.seconds, memory_bytes=self.memory_bytes,
                                on_child=self._track)
        except (SandboxError, OSError, untrusted.InputError) as exc:
            message = withhold_content(str(exc), [c for c in (g_copy, f_copy) if c])
            shutil.rmtree(target, ignore_errors=True)
            raise ControlError(_named(message, garment, g_copy, fabric, f_copy)) from None
        return str(g_copy), None if f_copy is None else str(f_copy), options


def _source(value: Any, what: str) -> Path:
    """The submitted path, resolved (its content is read only by the bounded copy)."""
    if not isinstance(value, str) or not value or len(value) > 4096 or "\0" in value:
        raise ControlError(f"{what} must be a file path")
    path = Path(value)
    if not path.exists():
        raise ControlError(f"{value}: no such {what} file")
    return path.resolve()


_QUOTED = re.compile(r"'([^']{2,200})'|\"([^\"]{2,200})\"")


def withhold_content(message: str, copies: list[Path]) -> str:
    """``message`` with every quoted fragment that the submitted files (their copies)
    contain replaced: a refusal names the file and the fault, never what the file holds
    (the station may read files its submitter cannot)."""
    fragments = {m.group(1) or m.group(2) for m in _QUOTED.finditer(message)}
    found: set[str] = set()
    for copy in copies if fragments else []:
        try:
            for chunk in untrusted.files.chunks(copy, what="file",
                                                max_bytes=untrusted.limits.MAX_OBJ_BYTES):
                found |= {f for f in fragments if f.encode() in chunk}
        except untrusted.InputError:
            continue
    for fragment in found:
        message = message.replace(f"'{fragment}'", "(content withheld)")
        message = message.replace(f'"{fragment}"', "(content withheld)")
    return message


def _options(value: Any) -> dict[str, Any]:
    """Job options: a small flat object of short scalars, except the few structured ones
    (`STRUCTURED`), each of a bounded shape; the pipeline's check reads their meaning."""
    options = value or {}
    if not isinstance(options, dict) or len(options) > MAX_OPTIONS:
        raise ControlError(f"options must be a JSON object of at most {MAX_OPTIONS} keys")
    for key, v in options.items():
        if len(key) > 100:
            raise ControlError(f"option {key[:100]!r}...: name longer than 100 characters")
        if key in STRUCTURED and v is not None:
            if not STRUCTURED[key](v):
                raise ControlError(f"option {key} must be {SHAPES[key]}")
            continue
        if not _scalar(v):
            raise ControlError(f"option {key!r} must be a short number, text or true/false")
        if key in INT_OPTIONS and v is not None:
            lo, hi = INT_OPTIONS[key]
            if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
                raise ControlError(f"option {key} must be an integer {lo:,} to {hi:,}, "
                                   f"got {v!r}")
    return dict(options)


def _scalar(v: Any) -> bool:
    return (v is None or isinstance(v, bool) or (isinstance(v, str) and len(v) <= 100)
            or (isinstance(v, int) and abs(v) < 2**53)
            or (isinstance(v, float) and math.isfinite(v)))


def _piece(v: Any) -> bool:
    """A piece or seam line: its name (short text) or its index."""
    return (isinstance(v, str) and 0 < len(v) <= 100) or \
        (isinstance(v, int) and not isinstance(v, bool) and 0 <= v < MAX_NAMED)


def _numbers_by_name(lo: float, hi: float) -> Callable[[Any], bool]:
    def ok(v: Any) -> bool:
        return isinstance(v, dict) and len(v) <= MAX_NAMED and all(
            _piece(k) and isinstance(x, (int, float)) and not isinstance(x, bool)
            and math.isfinite(x) and lo <= x <= hi for k, x in v.items())
    return ok


def _names(v: Any) -> bool:
    return isinstance(v, list) and len(v) <= MAX_NAMED and all(_piece(x) for x in v)


def _pairs(v: Any) -> bool:
    return isinstance(v, dict) and set(v) <= {"pairs", "not_pairs"} and all(
        isinstance(ps, list) and len(ps) <= MAX_NAMED and all(
            isinstance(p, list) and len(p) == 2 and all(_piece(x) for x in p) for p in ps)
        for ps in v.values())


def _point_pair(v: Any) -> bool:
    return isinstance(v, list) and len(v) == 2 and all(
        isinstance(p, list) and len(p) == 2 and all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
            for x in p) for p in v)


def _seams(v: Any) -> bool:
    """A CAD pattern's seams as `station inspect --seams` takes them (and seams.json)."""
    if not isinstance(v, dict) or not set(v) <= {"seams", "not_seams", "pieces"}:
        return False
    seams = v.get("seams", [])
    return _names(v.get("pieces", [])) and _pairs({"not_pairs": v.get("not_seams", [])}) \
        and isinstance(seams, list) and len(seams) <= MAX_NAMED and all(
            isinstance(s, dict) and _piece(s.get("a")) and _piece(s.get("b"))
            and _point_pair(s.get("a_ends")) and _point_pair(s.get("b_ends")) for s in seams)


#: at most this many named entries in one structured option (pieces, seam lines)
MAX_NAMED = 1000
#: the structured job options (what `station submit` sends) and their shapes
STRUCTURED: dict[str, Callable[[Any], bool]] = {
    "allowance": _numbers_by_name(0.0, 1000.0), "grain_lines": _numbers_by_name(-360.0, 360.0),
    "bias": _names, "pairs": _pairs, "seams": _seams}
SHAPES = {"allowance": '{"seam line": mm 0 to 1000}',
          "grain_lines": '{"piece": degrees -360 to 360}',
          "bias": '["piece", ...]',
          "pairs": '{"pairs": [[piece, piece], ...], "not_pairs": [...]}',
          "seams": '{"seams": [{"a": piece, "a_ends": [[x, y], [x, y]], "b": ..., '
                   '"b_ends": ...}], "not_seams": [[piece, piece], ...]}'}


def _copy_order(order: Path, target: Path, allowed: list[Path]) -> Path:
    """Copy an order file and every pattern it names, at the same relative places, into
    ``target``: the order then reads its patterns beside it, as it did where it came
    from. A pattern that resolves outside the allowed folders is refused like a garment."""
    copy = target / order.name
    untrusted.copy_file(order, copy, what="order file",
                        max_bytes=untrusted.limits.MAX_TOML_BYTES)
    for rel in order_patterns(copy):
        source = (order.parent / rel).resolve()
        if allowed and not any(source.is_relative_to(folder) for folder in allowed):
            raise untrusted.InputError(order, f"pattern {rel} lies outside "
                                       f"{', '.join(map(str, allowed))}")
        (target / rel).parent.mkdir(parents=True, exist_ok=True)
        _copy_garment(source, (target / rel).parent, name=Path(rel).name)
    return copy


def _copy_garment(garment: Path, target: Path, *, name: str | None = None) -> Path:
    """Copy the garment (with its pair partner and licence note) into ``target``."""
    copy = target / (name or garment.name)
    limit = untrusted.limits.MAX_OBJ_BYTES
    untrusted.copy_file(garment, copy, what="garment", max_bytes=limit)
    partner = pair_partner(garment) if garment.suffix.lower() == ".obj" else None
    for extra in [partner] + [garment.parent / n for n in _COMPANIONS]:
        if extra is not None and extra.exists() and not (target / extra.name).exists():
            untrusted.copy_file(extra, target / extra.name, what="companion file",
                                max_bytes=limit)
    return copy


def _named(message: str, garment: Path, g_copy: Path | None, fabric: Path | None,
           f_copy: Path | None) -> str:
    """The check's message with the copies' paths replaced by the files the operator sent."""
    for copy, original in ((g_copy, garment), (f_copy, fabric)):
        if copy is not None and original is not None:
            message = message.replace(str(copy), str(original))
    return message
