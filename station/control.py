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
import pwd
import socket
import socketserver
import stat
import struct
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from station.errors import UserError
from untrusted import InputError, decode_text, parse_json
from untrusted.limits import MAX_REQUEST_BYTES, MAX_SOCKET_PATH_BYTES

log = logging.getLogger("station.control")

Handler = Callable[[dict[str, Any]], dict[str, Any]]
MAX_REQUEST = MAX_REQUEST_BYTES  # one request line, refused before it is buffered whole
MAX_CONNECTIONS = 64  # console connections at once, all users together
MAX_PER_PEER = 8  # console connections of one user (uid) at once
IDLE_SECONDS = 5.0  # between requests, and to send one whole request line
MAX_ANSWER_BYTES = 256 << 20  # what a client accepts back (job lists, logs)


class ControlError(Exception):
    """A bad request: answered with ``{"ok": false, "error": ...}``; nothing changed."""


class DaemonBusy(ControlError):
    """The daemon took the request but did not answer in time (a step holding the
    interpreter on a loaded machine): asking again later may be answered."""


def peer_credentials(sock: socket.socket) -> tuple[int, int, int]:
    """(pid, uid, gid) of the process at the other end of a Unix socket."""
    creds = sock.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED, struct.calcsize("3i"))
    return struct.unpack("3i", creds)


class RequestTooLong(Exception):
    """A request line longer than MAX_REQUEST: refused before it is buffered whole."""


class LineReader:
    """Request lines from a socket, each within a time limit from when it is awaited: a
    client trickling one byte at a time holds its connection no longer than an idle one."""

    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock
        self.buf = bytearray()

    def next(self, seconds: float) -> bytes | None:
        """The next line (with its newline), or None once the client is silent for
        ``seconds`` or gone."""
        deadline = time.monotonic() + seconds
        while True:
            end = self.buf.find(b"\n")
            if 0 <= end < MAX_REQUEST:
                line = bytes(self.buf[: end + 1])
                del self.buf[: end + 1]
                return line
            if end >= MAX_REQUEST or len(self.buf) > MAX_REQUEST:
                raise RequestTooLong
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            self.sock.settimeout(left)
            try:
                chunk = self.sock.recv(65536)
            except TimeoutError:
                return None
            if not chunk:
                return None
            self.buf += chunk


@dataclass(eq=False)
class Seat:
    """One console connection: its user, and whether a request is being answered."""

    uid: int
    sock: socket.socket
    working: bool = False
    since: float = field(default_factory=time.monotonic)


class Seats:
    """Console connections per user and in all. A newcomer over a limit takes the seat of
    the longest idle connection (closed: it was between requests, nothing is lost), so
    idle or trickling connections can never lock the operator out; only connections all
    busy answering requests make a newcomer retry."""

    def __init__(self, per_peer: int, total: int) -> None:
        self.per_peer = per_peer
        self.total = total
        self._seats: list[Seat] = []
        self._lock = threading.Lock()

    def take(self, uid: int, sock: socket.socket) -> Seat | None:
        with self._lock:
            mine = [s for s in self._seats if s.uid == uid]
            pool = mine if len(mine) >= self.per_peer else \
                self._seats if len(self._seats) >= self.total else None
            if pool is not None:
                idle = [s for s in pool if not s.working]
                if not idle:
                    return None
                victim = min(idle, key=lambda s: s.since)
                self._seats.remove(victim)
                try:
                    victim.sock.shutdown(socket.SHUT_RDWR)  # its reader sees the end at once
                except OSError:
                    pass
            seat = Seat(uid, sock)
            self._seats.append(seat)
            return seat

    def busy(self, seat: Seat, working: bool) -> bool:
        """Mark a request begun or answered; False if the seat was given away meanwhile."""
        with self._lock:
            seat.working = working
            seat.since = time.monotonic()
            return seat in self._seats

    def leave(self, seat: Seat) -> None:
        with self._lock:
            if seat in self._seats:
                self._seats.remove(seat)

    def __len__(self) -> int:
        return len(self._seats)


class ControlServer:
    """Serves ``handler`` on a Unix socket in background threads."""

    def __init__(self, path: str | Path, handler: Handler, group: str = "") -> None:
        self.path = Path(path)
        self.handler = handler
        self.allowed_uids = {os.getuid()}
        self.allowed_gid = grp.getgrnam(group).gr_gid if group else None
        self._server: socketserver.ThreadingUnixStreamServer | None = None
        self._thread: threading.Thread | None = None
        self.seats = Seats(MAX_PER_PEER, MAX_CONNECTIONS)
        stale_socket(self.path)  # refuse a wrong control.socket before anything is touched

    def allowed(self, uid: int, gid: int) -> bool:
        if uid in self.allowed_uids:
            return True
        if self.allowed_gid is None:
            return False
        if gid == self.allowed_gid:
            return True
        try:
            name = pwd.getpwuid(uid).pw_name
        except KeyError:
            return False
        return name in grp.getgrgid(self.allowed_gid).gr_mem

    def start(self) -> None:
        """Listen, replacing a stale socket left by a killed daemon; anything else at the
        path (a file, a link, a live daemon's socket) is refused and left untouched."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if stale_socket(self.path):
            self.path.unlink()  # left by a killed daemon
        outer = self

        class _Request(socketserver.StreamRequestHandler):
            def handle(self) -> None:
                _pid, uid, gid = peer_credentials(self.request)
                if not outer.allowed(uid, gid):
                    log.warning("refused control connection from uid %d gid %d", uid, gid)
                    self._send({"ok": False, "error": "permission denied: not the station's "
                                "user or group"})
                    return
                seat = outer.seats.take(uid, self.request)
                if seat is None:
                    self._send({"ok": False, "error": "too many console connections busy "
                                "at once; retry"})
                    return
                try:
                    lines = LineReader(self.request)
                    while True:
                        line = lines.next(IDLE_SECONDS)
                        if line is None or not outer.seats.busy(seat, True):
                            return  # silent, gone, or its seat was given to a newcomer
                        try:
                            self._send(outer.answer(line))
                        finally:
                            outer.seats.busy(seat, False)
                except RequestTooLong:
                    self._send({"ok": False, "error": f"request longer than {MAX_REQUEST} "
                                "bytes refused"})
                except OSError:
                    return  # the client went away, or did not read its answer
                finally:
                    outer.seats.leave(seat)

            def _send(self, obj: dict[str, Any]) -> None:
                self.request.settimeout(IDLE_SECONDS)  # a client that never reads is dropped
                self.request.sendall((json.dumps(obj) + "\n").encode())

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


class SocketInUse(UserError):
    """control.socket names something that is not a stale socket: left untouched."""


def stale_socket(path: Path) -> bool:
    """Whether ``path`` is a socket nobody listens on (False: nothing there); SocketInUse
    for anything else, which the configuration must have named by mistake."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return False
    if not stat.S_ISSOCK(st.st_mode):
        kind = "a link" if stat.S_ISLNK(st.st_mode) else "a folder" if stat.S_ISDIR(
            st.st_mode) else "a file"
        raise SocketInUse(f"{path}: control.socket names {kind}, not a socket; refusing to "
                          "replace it (choose another control.socket)")
    probe = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    probe.settimeout(1.0)
    try:
        probe.connect(str(path))
    except OSError:
        return True
    finally:
        probe.close()
    raise SocketInUse(f"{path}: another daemon listens on this control socket")


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
        raise DaemonBusy(f"{path}: no answer within {timeout:g} s; the daemon is busy or "
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
