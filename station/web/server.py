"""The web console inside the daemon's process: uvicorn in one thread, on its own loop.

Starlette and uvicorn (see pyproject.toml) serve it: the daemon's threads stay as they are,
the console only reads the store and calls the control handler, and a stop closes it in a
second. Connections are bounded like the control socket's: 64 at once, 5 s to send each
request head (from the connection or the last answer, `TimedHeads`), heads of 64 KiB. A
request whose Host is not the station's own name is refused when listening on loopback,
so a web page elsewhere cannot reach the console through DNS rebinding.
"""

from __future__ import annotations

import asyncio
import logging
import socket
import threading
import time
from typing import Any
from urllib.parse import urlsplit

import uvicorn
from uvicorn.protocols.http.h11_impl import H11Protocol

from station.control import IDLE_SECONDS, MAX_CONNECTIONS
from station.web.access import ConsoleSettings, console_listen, console_settings
from station.web.app import ConsoleApp
from station.web.feed import Feed
from untrusted.limits import MAX_REQUEST_BYTES

log = logging.getLogger("station.web")

LOOPBACK_HOSTS = {"127.0.0.1", "localhost", "::1"}
SECURITY_HEADERS = [
    (b"content-security-policy", b"default-src 'self'; img-src 'self' data:; "
     b"frame-ancestors 'none'; base-uri 'none'; form-action 'none'"),
    (b"x-content-type-options", b"nosniff"),
    (b"referrer-policy", b"no-referrer"),
]


class Guard:
    """ASGI wrapper: refuse foreign Host names on loopback, add the security headers."""

    def __init__(self, app: Any, hosts: set[str] | None) -> None:
        self.app = app
        self.hosts = hosts  # None: any name (a network console, reached by its address)

    async def __call__(self, scope: dict, receive: Any, send: Any) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        host = dict(scope["headers"]).get(b"host", b"").decode("latin-1")
        if self.hosts is not None and (urlsplit("//" + host).hostname or "") not in self.hosts:
            await send({"type": "http.response.start", "status": 421,
                        "headers": [(b"content-type", b"text/plain")]})
            await send({"type": "http.response.body", "body": b"unknown host name\n"})
            return

        async def guarded_send(message: dict) -> None:
            if message["type"] == "http.response.start":
                message["headers"] = list(message.get("headers", [])) + SECURITY_HEADERS
            await send(message)

        await self.app(scope, receive, guarded_send)


class TimedHeads(H11Protocol):
    """HTTP/1.1 (h11) whose every request head must arrive within IDLE_SECONDS of the
    connection, or of the last answer, as on the control socket. uvicorn times out only an
    idle keep-alive connection, and not once its first byte came: without this, 64 clients
    connecting and sending nothing (or a byte at a time) would keep the console away."""

    head_timer: asyncio.TimerHandle | None = None
    waited_after: Any = None  # the request-response cycle after which a head is awaited

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        super().connection_made(transport)
        self._await_head()

    def data_received(self, data: bytes) -> None:
        super().data_received(data)
        if self.cycle is not self.waited_after and self.head_timer is not None:
            self.head_timer.cancel()  # a whole request head came: it is being answered
            self.head_timer = None

    def on_response_complete(self) -> None:
        super().on_response_complete()
        self._await_head()

    def connection_lost(self, exc: Exception | None) -> None:
        if self.head_timer is not None:
            self.head_timer.cancel()
        super().connection_lost(exc)

    def _await_head(self) -> None:
        if self.head_timer is not None:
            self.head_timer.cancel()
        self.waited_after = self.cycle
        self.head_timer = self.loop.call_later(IDLE_SECONDS, self._too_slow)

    def _too_slow(self) -> None:
        self.head_timer = None
        if self.cycle is self.waited_after and not self.transport.is_closing():
            self.transport.close()


class ConsoleServer:
    """Started by the daemon's ``serve`` and stopped with it; nothing when
    ``console.listen`` is empty."""

    def __init__(self, daemon: Any, questions: dict[str, str]) -> None:
        console_listen(daemon.config)  # an unsafe address is refused before anything starts
        self.daemon = daemon
        self.questions = questions  # reason prefix -> the command that answers it
        self.settings: ConsoleSettings | None = None
        self.feed: Feed | None = None
        self._server: uvicorn.Server | None = None
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str | None:
        if self.settings is None or self._server is None:
            return None
        host = self.settings.host
        return f"http://{'[' + host + ']' if ':' in host else host}:{self.settings.port}/"

    def start(self) -> None:
        """Read the token (ConsoleRefused, one line, for a bad token file) and listen. An
        address already in use is logged and the station runs on without its screen."""
        self.settings = console_settings(self.daemon.config)
        if self.settings is None:
            return
        try:
            sock = bind(self.settings.host, self.settings.port)
        except OSError as exc:
            log.error("console: cannot listen on %s:%d (%s); serving without the web console",
                      self.settings.host, self.settings.port, exc.strerror or exc)
            return
        self.feed = Feed(self.daemon, self.questions)
        self.feed.start()
        app = ConsoleApp(self.daemon, self.feed, self.settings.token,
                         self.daemon.config.resolve(self.daemon.config["store"]["work_dir"]))
        hosts = (LOOPBACK_HOSTS | {self.settings.host}) if self.settings.loopback else None
        config = uvicorn.Config(Guard(app.starlette(), hosts), http=TimedHeads,
                                log_level="warning", access_log=False, lifespan="off",
                                limit_concurrency=MAX_CONNECTIONS,
                                timeout_keep_alive=int(IDLE_SECONDS),
                                timeout_graceful_shutdown=1,
                                h11_max_incomplete_event_size=MAX_REQUEST_BYTES)
        self._server = uvicorn.Server(config)
        self._thread = threading.Thread(target=self._server.run, kwargs={"sockets": [sock]},
                                        name="console", daemon=True)
        self._thread.start()
        deadline = time.monotonic() + 10
        while not self._server.started and self._thread.is_alive() and \
                time.monotonic() < deadline:
            time.sleep(0.02)
        log.info("console on %s%s", self.url, "" if self.settings.token else " (read-only)")

    def stop(self) -> None:
        if self.feed is not None:
            self.feed.stop()  # ends the live views, so the server stops at once
        if self._server is not None:
            self._server.should_exit = True
        if self._thread is not None:
            self._thread.join(5)
        self._server = self._thread = None


def bind(host: str, port: int) -> socket.socket:
    """A listening socket, made here so that a taken port is known before the thread runs."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((host, port))
        sock.listen(MAX_CONNECTIONS)
    except OSError:
        sock.close()
        raise
    return sock
