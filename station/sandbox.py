"""Running untrusted work (reading and meshing a submitted garment) in a forked child with
its memory and time bounded, so that no submission can exhaust or stall the daemon.

The daemon's threads only wait on a pipe meanwhile (without the GIL), so the control socket
keeps answering; a child that runs out of memory or time is killed and reported as one line.
"""

from __future__ import annotations

import os
import resource
import select
import signal
import time
from collections.abc import Callable
from typing import Any

_PAGE = os.sysconf("SC_PAGE_SIZE")


class SandboxError(ValueError):
    """The work failed, or broke its limits: the message is one line for the operator."""


def _address_space() -> int:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[0]) * _PAGE


def _child(func: Callable[..., Any], args: tuple, memory_bytes: int, out: int) -> None:
    try:
        limit = _address_space() + memory_bytes
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
        try:
            func(*args)
            message = "ok:"
        except MemoryError:
            message = "error:needs more than the memory allowed for checking a submission"
        except (ValueError, OSError) as exc:
            message = "error:" + " ".join(str(exc).split())
        except BaseException as exc:  # a bug in the check: still one line
            message = f"error:{type(exc).__name__}: {' '.join(str(exc).split())}"
        os.write(out, message.encode()[:8192])
    finally:
        os._exit(0)


def run_limited(func: Callable[..., Any], *args: Any, seconds: float, memory_bytes: int,
                on_child: Callable[[int | None], None] | None = None) -> None:
    """``func(*args)`` in a child process; its faults come back as :class:`SandboxError`.

    ``on_child(pid)`` is told the child's pid when it starts and ``None`` when it is gone,
    so an owner that stops can kill it.
    """
    read_end, write_end = os.pipe()
    pid = os.fork()
    if pid == 0:  # pragma: no cover - runs in the child
        os.close(read_end)
        _child(func, args, memory_bytes, write_end)
    os.close(write_end)
    if on_child is not None:
        on_child(pid)
    chunks: list[bytes] = []
    deadline = time.monotonic() + seconds
    timed_out = False
    try:
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                timed_out = True
                break
            ready, _, _ = select.select([read_end], [], [], min(left, 1.0))
            if ready:
                chunk = os.read(read_end, 8192)
                if not chunk:
                    break
                chunks.append(chunk)
    finally:
        os.close(read_end)
        if timed_out:
            os.kill(pid, signal.SIGKILL)
        _, status = os.waitpid(pid, 0)
        if on_child is not None:
            on_child(None)
    if timed_out:
        raise SandboxError(f"checking took longer than {seconds:g} s")
    message = b"".join(chunks).decode(errors="replace")
    if message.startswith("ok:"):
        return
    if message.startswith("error:"):
        raise SandboxError(message[len("error:"):])
    sig = os.WTERMSIG(status) if os.WIFSIGNALED(status) else None
    raise SandboxError("the check crashed" + (f" (signal {sig})" if sig else "")
                       + "; it may need more memory than allowed")
