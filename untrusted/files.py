"""Reading an untrusted file: it must exist, be a regular file, fit its size limit and
(for text) be UTF-8, before a single byte is parsed."""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from pathlib import Path

from untrusted.errors import InputError


class MissingInput(InputError, FileNotFoundError):
    """The file is not there (still a FileNotFoundError for callers that test for it)."""


#: bytes read at a time; also the most a lying file (one whose size says 0) can cost
CHUNK = 1 << 20


def read_bytes(path: str | Path, *, what: str, max_bytes: int) -> bytes:
    """The content of ``path``; a folder, device, unreadable or oversized file is an InputError.

    The limit holds for the bytes actually read, not for what the file's size claims: a
    file in /proc says 0 bytes and gives gigabytes, so reading stops one chunk past the
    size the file stated (see :func:`chunks`).
    """
    return b"".join(chunks(path, what=what, max_bytes=max_bytes))


def copy_file(src: str | Path, dst: str | Path, *, what: str, max_bytes: int) -> int:
    """Copy a regular file of at most ``max_bytes`` to ``dst`` (created, never followed if
    it exists as a link); the bytes copied. A refused source leaves no ``dst``."""
    dst = Path(dst)
    fd = os.open(dst, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o640)
    done = 0
    try:
        with os.fdopen(fd, "wb") as out:
            for chunk in chunks(src, what=what, max_bytes=max_bytes):
                out.write(chunk)
                done += len(chunk)
    except BaseException:
        dst.unlink(missing_ok=True)
        raise
    return done


def chunks(path: str | Path, *, what: str, max_bytes: int) -> Iterator[bytes]:
    """The bytes of a regular file in chunks, stopping with an InputError as soon as more
    came than ``max_bytes`` or than the size the file stated when opened."""
    path = Path(path)
    fd = _open_regular(path, what=what, max_bytes=max_bytes)
    try:
        stated = os.fstat(fd).st_size
        total = 0
        while True:
            try:
                chunk = os.read(fd, CHUNK)
            except OSError as exc:
                raise InputError(path, f"cannot read the {what} ({exc.strerror})") from None
            if not chunk:
                return
            total += len(chunk)
            if total > max_bytes:
                raise InputError(path, f"{what} exceeds the limit of {max_bytes:,} bytes")
            if total > stated:
                raise InputError(path, f"{what} gives more bytes than its size of {stated:,} "
                                 "(a device or /proc file, or one still being written)")
            yield chunk
    finally:
        os.close(fd)


def _open_regular(path: Path, *, what: str, max_bytes: int) -> int:
    """A descriptor of ``path`` once it is known to be a regular file within the limit (a
    FIFO is opened without blocking, then refused)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY | os.O_CLOEXEC)
    except FileNotFoundError:
        raise MissingInput(path, f"{what} not found") from None
    except IsADirectoryError:
        raise InputError(path, f"is a folder, expected a {what}") from None
    except OSError as exc:
        raise InputError(path, f"cannot open the {what} ({exc.strerror})") from None
    try:
        _check_stat(path, os.fstat(fd), what=what, max_bytes=max_bytes)
    except BaseException:
        os.close(fd)
        raise
    return fd


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
