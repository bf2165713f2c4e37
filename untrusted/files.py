"""Reading an untrusted file: it must exist, be a regular file, fit its size limit and
(for text) be UTF-8, before a single byte is parsed."""

from __future__ import annotations

import os
import stat
from pathlib import Path

from untrusted.errors import InputError


class MissingInput(InputError, FileNotFoundError):
    """The file is not there (still a FileNotFoundError for callers that test for it)."""


def read_bytes(path: str | Path, *, what: str, max_bytes: int) -> bytes:
    """The content of ``path``; a folder, device, unreadable or oversized file is an InputError.

    The size is checked on the open descriptor before reading, and the read itself is capped,
    so a file that grows meanwhile (or a FIFO) cannot make it read without end.
    """
    path = Path(path)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        raise MissingInput(path, f"{what} not found") from None
    except IsADirectoryError:
        raise InputError(path, f"is a folder, expected a {what}") from None
    except OSError as exc:
        raise InputError(path, f"cannot open the {what} ({exc.strerror})") from None
    try:
        _check_stat(path, os.fstat(fd), what=what, max_bytes=max_bytes)
        with os.fdopen(os.dup(fd), "rb") as fh:
            data = fh.read(max_bytes + 1)
    except OSError as exc:
        raise InputError(path, f"cannot read the {what} ({exc.strerror})") from None
    finally:
        os.close(fd)
    if len(data) > max_bytes:
        raise InputError(path, f"{what} exceeds the limit of {max_bytes:,} bytes")
    return data


def check_file(path: str | Path, *, what: str, max_bytes: int) -> Path:
    """``path`` if it names a regular file within ``max_bytes``, for readers (like ezdxf's)
    that must open the file themselves."""
    path = Path(path)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise MissingInput(path, f"{what} not found") from None
    except OSError as exc:
        raise InputError(path, f"cannot open the {what} ({exc.strerror})") from None
    _check_stat(path, st, what=what, max_bytes=max_bytes)
    return path


def _check_stat(path: Path, st: os.stat_result, *, what: str, max_bytes: int) -> None:
    """A folder, a device or FIFO, or a file over ``max_bytes`` is an InputError."""
    if stat.S_ISDIR(st.st_mode):
        raise InputError(path, f"is a folder, expected a {what}")
    if not stat.S_ISREG(st.st_mode):
        raise InputError(path, f"is not a regular file, expected a {what}")
    if st.st_size > max_bytes:
        raise InputError(path, f"{what} of {st.st_size:,} bytes exceeds the limit of "
                         f"{max_bytes:,}")


def decode_text(data: bytes, source: str | Path, what: str) -> str:
    """UTF-8 text (a leading BOM is dropped); a bad byte is an InputError naming its offset."""
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(source, f"{what} is not UTF-8 text (byte 0x{data[exc.start]:02x} at "
                         f"offset {exc.start})") from None


def read_text(path: str | Path, *, what: str, max_bytes: int) -> str:
    """:func:`read_bytes` decoded as UTF-8."""
    return decode_text(read_bytes(path, what=what, max_bytes=max_bytes), path, what)
