"""The operator console's Unix-domain socket: one JSON request, one JSON answer per line.

Only the station's own user and the configured group may talk to the daemon: the socket
file is mode 0660, and each connection's peer credentials (``SO_PEERCRED``) are checked
again, so a permissive umask or a copied socket path cannot open the door. Handlers run in
their own threads and only read the job store or set flags, so every request is answered
within a second even while the daemon is cutting.
"""

from __future__ import annotations

import grp
import json
import logging
import os
import socket
import socketserver
import struct
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from untrusted import InputError, decode_text, parse_json
from untrusted.limits import MAX_REQUEST_BYTES, MAX_SOCKET_PATH_BYTES

log = logging.getLogger("station.control")

Handler = Callable[[dict[str, Any]], dict[str, Any]]
MAX_REQUEST = MAX_REQUEST_BYTES  # one request line, refused before it is buffered whole
MAX_CONNECTIONS = 32  # concurrent console connections; more are told to retry
IDLE_SECONDS = 300.0  # a connection silent this long is closed
MAX_ANSWER_BYTES = 256 << 20  # what a client accepts back (job lists, logs)


class ControlError(Exception):
    """A bad request: answered with ``{"ok": false, "error": ...}``; nothing changed."""


def peer_credentials(sock: socket.socket) -> tuple[int, int, int]:
    """(pid, uid, gid) of the process at the other end of a Unix socket."""
    creds = sock.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED, struct.calcsize("3i"))
    return struct.unpack("3i", creds)


class ControlServer:
    """Serves ``handler`` on a Unix socket in background threads."""

    def __init__(self, path: str | Path, handler: Handler, group: str = "") -> None:
        self.path = Path(path)
        self.handler = handler
        self.allowed_uids = {os.getuid()}
        self.allowed_gid = grp.getgrnam(group).gr_gid if group else None
        self._server: socketserver.ThreadingUnixStreamServer | None = None
        self._thread: threading.Thread | None = None
        self._slots = threading.BoundedSemaphore(MAX_CONNECTIONS)

    def allowed(self, uid: int, gid: int) -> bool:
        if uid in self.allowed_uids:
            return True
        if self.allowed_gid is None:
            return False
        if gid == self.allowed_gid:
            return True
        try:
            import pwd

            name = pwd.getpwuid(uid).pw_name
        except KeyError:
            return False
        return name in grp.getgrgid(self.allowed_gid).gr_mem

    def start(self) -> None:
        """Listen; only call this while holding the daemon lock (station.daemon_lock), since
        an existing socket is then known to be stale and is replaced."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if self.path.exists() or self.path.is_symlink():
            self.path.unlink()  # a stale socket left by a killed daemon
        outer = self

        class _Request(socketserver.StreamRequestHandler):
            def handle(self) -> None:
                _pid, uid, gid = peer_credentials(self.request)
                if not outer.allowed(uid, gid):
                    log.warning("refused control connection from uid %d gid %d", uid, gid)
                    self._send({"ok": False, "error": "permission denied: not the station's "
                                "user or group"})
                    return
                if not outer._slots.acquire(blocking=False):
                    self._send({"ok": False, "error": "too many console connections; retry"})
                    return
                try:
                    self.request.settimeout(IDLE_SECONDS)
                    while True:
                        # readline(limit) never buffers more than the limit, newline or not
                        line = self.rfile.readline(MAX_REQUEST + 1)
                        if not line:
                            return
                        if len(line) > MAX_REQUEST or not line.endswith(b"\n"):
                            if len(line) > MAX_REQUEST:
                                self._send({"ok": False, "error": "request longer than "
                                            f"{MAX_REQUEST} bytes refused"})
                            return
                        self._send(outer.answer(line))
                except (OSError, TimeoutError):
                    return  # the client went away or fell silent
                finally:
                    outer._slots.release()

            def _send(self, obj: dict[str, Any]) -> None:
                self.wfile.write((json.dumps(obj) + "\n").encode())
                self.wfile.flush()

        old_umask = os.umask(0o117)  # the socket is born 0660, never world-accessible
        try:
            self._server = socketserver.ThreadingUnixStreamServer(str(self.path), _Request)
        finally:
            os.umask(old_umask)
        os.chmod(self.path, 0o660)
        if self.allowed_gid is not None:
            os.chown(self.path, -1, self.allowed_gid)
        self._server.daemon_threads = True
        self._thread = threading.Thread(target=self._server.serve_forever,
                                        name="control", daemon=True)
        self._thread.start()

    def answer(self, line: bytes) -> dict[str, Any]:
        try:
            request = parse_json(decode_text(line, "request", "request"), "request")
            if not isinstance(request, dict) or not isinstance(request.get("cmd"), str):
                raise ControlError('a request is a JSON object with a "cmd" string')
            return {"ok": True, **self.handler(request)}
        except InputError as exc:
            return {"ok": False, "error": exc.fault}
        except (ControlError, ValueError, KeyError, TypeError) as exc:
            return {"ok": False, "error": str(exc).strip("'\"")}
        except Exception as exc:  # never let one request take the console down
            log.exception("control request failed")
            return {"ok": False, "error": f"internal error: {exc}"}

    def stop(self) -> None:
        if self._server is not None:
            self._server.shutdown()
            self._server.server_close()
            self._server = None
        if self.path.exists():
            self.path.unlink()


def request(path: str | Path, cmd: str, timeout: float = 5.0,
            on_wait: Callable[[float], None] | None = None, **fields: Any) -> dict[str, Any]:
    """Send one request to the daemon and return its answer (raises ControlError).

    ``on_wait(seconds)`` is called about once a second while the answer is due, so a client
    can tell its user why it waits; after ``timeout`` seconds it gives up with one line.
    """
    if len(os.fsencode(str(path))) > MAX_SOCKET_PATH_BYTES:
        raise ControlError(f"{path}: socket path longer than {MAX_SOCKET_PATH_BYTES} bytes")
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.settimeout(min(timeout, 5.0))
    try:
        sock.connect(str(path))
    except FileNotFoundError:
        raise ControlError(f"{path}: no station daemon is listening (start `station serve`)"
                           ) from None
    except PermissionError:
        raise ControlError(f"{path}: permission denied: not the station's user or group"
                           ) from None
    except ConnectionRefusedError:
        raise ControlError(f"{path}: the station daemon is not running") from None
    except OSError as exc:  # a timeout, or a path that is not a socket
        sock.close()
        raise ControlError(f"{path}: cannot reach the daemon ({exc.strerror or exc})") from None
    start = time.monotonic()
    with sock:
        try:
            sock.sendall((json.dumps({"cmd": cmd, **fields}) + "\n").encode())
            line = _answer_line(sock, start, timeout, on_wait)
        except OSError as exc:
            raise ControlError(f"{path}: the daemon did not answer ({exc.strerror or exc})"
                               ) from None
    if line is None:
        raise ControlError(f"{path}: no answer within {timeout:g} s; the daemon is busy or "
                           "stuck (see `station log`)")
    if not line:
        raise ControlError(f"{path}: the daemon closed the connection")
    try:
        answer = json.loads(line)
    except ValueError:
        raise ControlError(f"{path}: the daemon's answer is not JSON") from None
    if not isinstance(answer, dict) or not answer.get("ok"):
        raise ControlError(str(answer.get("error", "request failed")) if isinstance(answer, dict)
                           else "request failed")
    return answer


def _answer_line(sock: socket.socket, start: float, timeout: float,
                 on_wait: Callable[[float], None] | None) -> bytes | None:
    """The answer's line (b"" if the daemon hung up), or None after ``timeout`` seconds;
    ``on_wait(elapsed)`` is called about once a second meanwhile."""
    buf = bytearray()
    while True:
        left = timeout - (time.monotonic() - start)
        if left <= 0:
            return None
        sock.settimeout(min(left, 1.0))
        try:
            chunk = sock.recv(65536)
        except TimeoutError:
            if on_wait is not None:
                on_wait(time.monotonic() - start)
            continue
        if not chunk:
            return bytes(buf)
        buf += chunk
        end = buf.find(b"\n")
        if end >= 0:
            return bytes(buf[: end + 1])
        if len(buf) > MAX_ANSWER_BYTES:
            raise ControlError("the daemon's answer is too long")
