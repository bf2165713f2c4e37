"""JSON and TOML from untrusted sources: no NaN/inf, no huge integers, bounded nesting.

Python's parsers accept ``NaN``, ``Infinity``, integers of thousands of digits and nesting
until the interpreter's recursion limit; here each of those is a one-line InputError, so
code downstream only ever sees finite numbers in shallow trees.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import Any

from untrusted.errors import InputError
from untrusted.files import decode_text, read_bytes
from untrusted.limits import MAX_DEPTH, MAX_INT_DIGITS, MAX_JSON_BYTES, MAX_TOML_BYTES

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

INT_LIMIT = 2**63 - 1


class _Fault(Exception):
    """Raised from a parser hook; turned into an InputError naming the source."""


def _int(text: str) -> int:
    if len(text.lstrip("-")) > MAX_INT_DIGITS:
        raise _Fault(f"integer {text[:12]}... has more than {MAX_INT_DIGITS} digits")
    return int(text)


def _path(keys: tuple) -> str:
    return "".join(f"[{k}]" if isinstance(k, int) else f".{k}" for k in keys).lstrip(".")


def check_tree(value: Any, source: str | Path, *, max_depth: int = MAX_DEPTH) -> Any:
    """``value`` unchanged if it nests at most ``max_depth`` deep and its numbers are finite
    and fit int64; the fault names the key path (``pieces[2].outline[0][1]``). Walks
    containers iteratively, so depth itself cannot crash it."""
    stack: list[tuple[Any, tuple]] = [(value, ())]
    while stack:
        node, keys = stack.pop()
        if len(keys) >= max_depth:
            raise InputError(source, f"nested more than {max_depth} levels deep")
        items = node.items() if isinstance(node, dict) else enumerate(node)
        for key, child in items:
            if isinstance(child, (dict, list)):
                stack.append((child, (*keys, key)))
            elif isinstance(child, float) and not math.isfinite(child):
                raise InputError(source, f"{_path((*keys, key))} = {child}: only finite "
                                 "numbers are accepted")
            elif isinstance(child, int) and not isinstance(child, bool) \
                    and not -INT_LIMIT <= child <= INT_LIMIT:
                raise InputError(source, f"{_path((*keys, key))}: integer out of the 64-bit "
                                 "range")
    return value


def parse_json(text: str, source: str | Path) -> Any:
    """Parsed JSON ``text``; every fault is an InputError naming ``source``."""
    if not text.strip():
        raise InputError(source, "empty file")
    try:
        value = json.loads(text, parse_int=_int)
    except json.JSONDecodeError as exc:
        cut = " (truncated?)" if exc.pos >= len(text.rstrip()) else ""
        raise InputError(source, f"not valid JSON{cut}: {exc.msg} at line {exc.lineno} "
                         f"column {exc.colno}") from None
    except _Fault as exc:
        raise InputError(source, str(exc)) from None
    except RecursionError:
        raise InputError(source, f"nested more than {MAX_DEPTH} levels deep") from None
    if isinstance(value, (dict, list)):
        return check_tree(value, source)
    if isinstance(value, float) and not math.isfinite(value):
        raise InputError(source, f"{value}: only finite numbers are accepted")
    return value


def read_json(path: str | Path, *, what: str = "JSON file", max_bytes: int = MAX_JSON_BYTES
              ) -> Any:
    """The checked content of a JSON file (see :func:`parse_json`)."""
    data = read_bytes(path, what=what, max_bytes=max_bytes)
    return parse_json(decode_text(data, path, what), path)


def parse_toml(text: str, source: str | Path) -> dict[str, Any]:
    """Parsed TOML ``text`` with the same guarantees as :func:`parse_json`."""
    try:
        value = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(source, f"not valid TOML ({exc})") from None
    except (_Fault, ValueError) as exc:  # ValueError: an integer of > 4300 digits
        raise InputError(source, str(exc)) from None
    except RecursionError:
        raise InputError(source, f"nested more than {MAX_DEPTH} levels deep") from None
    return check_tree(value, source)


def read_toml(path: str | Path, *, what: str = "TOML file", max_bytes: int = MAX_TOML_BYTES
              ) -> dict[str, Any]:
    """The checked content of a TOML file (see :func:`parse_toml`)."""
    data = read_bytes(path, what=what, max_bytes=max_bytes)
    return parse_toml(decode_text(data, path, what), path)
