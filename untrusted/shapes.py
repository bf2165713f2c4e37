"""Type, shape and range checks of parsed untrusted values, before any work uses them.

Each takes the ``source`` (file name) and ``where`` (key path, e.g. ``pieces[3].outline``)
so the error says exactly what is wrong where: ``FILE: WHERE: fault``.
"""

from __future__ import annotations

import math
from collections.abc import Sized
from pathlib import Path
from typing import Any

import numpy as np

from untrusted.errors import InputError
from untrusted.limits import MAX_COORD_MM, MAX_PANEL_POINTS


def _kind(value: Any) -> str:
    return {dict: "an object", list: "a list", str: "a string", bool: "true/false",
            type(None): "null"}.get(type(value), type(value).__name__)


def mapping(value: Any, source: str | Path, where: str = "the content") -> dict[str, Any]:
    """``value`` if it is a JSON object / TOML table."""
    if not isinstance(value, dict):
        raise InputError(source, f"{where} must be an object, got {_kind(value)}")
    return value


def sequence(value: Any, source: str | Path, where: str, *, max_len: int,
             min_len: int = 0) -> list[Any]:
    """``value`` if it is a list of ``min_len``..``max_len`` elements."""
    if not isinstance(value, list):
        raise InputError(source, f"{where} must be a list, got {_kind(value)}")
    if not min_len <= len(value) <= max_len:
        raise InputError(source, f"{where} has {len(value):,} elements; expected at least "
                         f"{min_len:,} and at most {max_len:,}")
    return value


def number(value: Any, source: str | Path, where: str, *, lo: float = -math.inf,
           hi: float = math.inf, lo_open: bool = False) -> float:
    """A finite float in ``[lo, hi]`` (``(lo, hi]`` if ``lo_open``); bools are not numbers."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(source, f"{where} must be a number, got {_kind(value)}")
    x = float(value) if abs(value) < 1e308 else (math.inf if value > 0 else -math.inf)
    if not math.isfinite(x):
        raise InputError(source, f"{where} must be finite, got {value!r}")
    if x < lo or x > hi or (lo_open and x == lo):
        low = f"above {lo:g}" if lo_open else f"at least {lo:g}"
        raise InputError(source, f"{where} = {x:g} is out of range ({low} and at most {hi:g})")
    return x


def integer(value: Any, source: str | Path, where: str, *, lo: int, hi: int) -> int:
    """An integer in ``[lo, hi]``; a float with an integral value (2.0) is accepted."""
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    if isinstance(value, bool) or not isinstance(value, int):
        raise InputError(source, f"{where} must be an integer, got {_kind(value)}")
    if not lo <= value <= hi:
        shown = str(value) if abs(value) < 10**15 else f"{float(value):.3g}"
        raise InputError(source, f"{where} = {shown} is out of range ({lo:,} to {hi:,})")
    return value


def text(value: Any, source: str | Path, where: str, *, max_len: int = 1000) -> str:
    """A string of at most ``max_len`` characters."""
    if not isinstance(value, str):
        raise InputError(source, f"{where} must be a string, got {_kind(value)}")
    if len(value) > max_len:
        raise InputError(source, f"{where} is longer than {max_len} characters")
    return value


def points(value: Any, source: str | Path, where: str, *, dim: int = 2, min_len: int = 1,
           max_len: int = MAX_PANEL_POINTS, max_abs: float = MAX_COORD_MM) -> np.ndarray:
    """(n, dim) float array of finite coordinates within ``max_abs``.

    The length is checked before NumPy sees the value, so no list can make it allocate more
    than ``max_len * dim`` floats.
    """
    if not isinstance(value, (list, tuple)):
        raise InputError(source, f"{where} must be a list of {dim}-number points, "
                         f"got {_kind(value)}")
    if not min_len <= len(value) <= max_len:
        raise InputError(source, f"{where} has {len(value):,} points; expected at least "
                         f"{min_len:,} and at most {max_len:,}")
    try:
        arr = np.array(value)  # ragged lists fail here; text, null or bools give other kinds
    except (TypeError, ValueError, OverflowError):
        arr = np.zeros((0,), object)
    if arr.dtype.kind not in "iuf" or arr.shape != (len(value), dim):
        kind = "a coordinate is not a number" if arr.dtype.kind not in "iuf" and \
            arr.shape == (len(value), dim) else f"each point needs {dim} numbers"
        raise InputError(source, f"{where} must be a list of [{', '.join('xyz'[:dim])}] "
                         f"points: {kind}")
    return _bounded(arr.astype(float), source, where, max_abs)


def vector(value: Any, source: str | Path, where: str, *, dim: int = 2,
           max_abs: float = MAX_COORD_MM) -> np.ndarray:
    """(dim,) float array, e.g. ``[x, y]``."""
    if not isinstance(value, (list, tuple)) or len(value) != dim:
        raise InputError(source, f"{where} must be a list of {dim} numbers")
    return points([value], source, where, dim=dim, max_abs=max_abs)[0]


def matrix(value: Any, source: str | Path, where: str, shape: tuple[int, int], *,
           max_abs: float = MAX_COORD_MM) -> np.ndarray:
    """A ``shape`` float array given as a list of rows."""
    if not isinstance(value, (list, tuple)) or len(value) != shape[0]:
        raise InputError(source, f"{where} must be a {shape[0]} x {shape[1]} matrix")
    return points(value, source, where, dim=shape[1], min_len=shape[0], max_len=shape[0],
                  max_abs=max_abs)


def _bounded(arr: np.ndarray, source: str | Path, where: str, max_abs: float) -> np.ndarray:
    if bool(np.any(np.isnan(arr))) or not bool(np.all(np.abs(arr) <= max_abs)):
        raise InputError(source, f"{where} holds a coordinate that is not finite or beyond "
                         f"{max_abs:g}")
    return arr


def count(value: Sized, source: str | Path, where: str, *, limit: int) -> None:
    """Err if ``value`` has more than ``limit`` elements."""
    if len(value) > limit:
        raise InputError(source, f"{where}: {len(value):,} exceeds the limit of {limit:,}")
