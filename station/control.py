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
from collections.abc import Callable
from pathlib import Path
from typing import Any

log = logging.getLogger("station.control")

Handler = Callable[[dict[str, Any]], dict[str, Any]]
MAX_REQUEST = 1 << 20


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
                for line in self.rfile:
                    if len(line) > MAX_REQUEST:
                        self._send({"ok": False, "error": "request too long"})
                        return
                    self._send(outer.answer(line))

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
            request = json.loads(line)
            if not isinstance(request, dict) or not isinstance(request.get("cmd"), str):
                raise ControlError('a request is a JSON object with a "cmd" string')
            return {"ok": True, **self.handler(request)}
        except json.JSONDecodeError as exc:
            return {"ok": False, "error": f"not JSON: {exc.msg}"}
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


def request(path: str | Path, cmd: str, timeout: float = 5.0, **fields: Any) -> dict[str, Any]:
    """Send one request to the daemon and return its answer (raises ControlError)."""
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.settimeout(timeout)
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
    with sock, sock.makefile("rwb") as stream:
        stream.write((json.dumps({"cmd": cmd, **fields}) + "\n").encode())
        stream.flush()
        line = stream.readline()
    if not line:
        raise ControlError(f"{path}: the daemon closed the connection")
    answer = json.loads(line)
    if not answer.get("ok"):
        raise ControlError(answer.get("error", "request failed"))
    return answer
