"""Who may use the web console: where it listens, and the token that any change needs.

Reading is open to whoever reaches the address (loopback by default); every request that
changes state (submit, confirm, pause, resume, abort, retry) carries the station's console
token in the ``X-Station-Token`` header. The token lives in a file the station writes
once, readable by its user and the control group (mode 0640), as the control socket is
usable by them: whoever may run `station pause` may read the token and pause from the
page. A header, never a cookie (no cross-site request can forge it) nor the URL (which
ends up in logs and browser history).
"""

from __future__ import annotations

import grp
import hmac
import ipaddress
import os
import secrets
import stat
from dataclasses import dataclass
from pathlib import Path

from station.config import Config
from station.errors import UserError

TOKEN_HEADER = "X-Station-Token"
LOOPBACK_NAMES = ("localhost",)


class ConsoleRefused(UserError):
    """The console's settings are unsafe or unusable: the daemon does not start."""


@dataclass(frozen=True)
class ConsoleSettings:
    """Where the console listens and the token that changes need (None: read-only)."""

    host: str
    port: int
    token: str | None

    @property
    def loopback(self) -> bool:
        return is_loopback(self.host)


def is_loopback(host: str) -> bool:
    if host in LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def parse_listen(text: str, where: str = "console.listen") -> tuple[str, int]:
    """'HOST:PORT' (IPv6 as '[::1]:PORT') -> (host, port); one line naming the key if not."""
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ConsoleRefused(f"{where} must be HOST:PORT (e.g. 127.0.0.1:8410), got {text!r}")
    return host.strip("[]"), int(port)


def console_listen(config: Config) -> tuple[str, int] | None:
    """(host, port) of the console (None when ``console.listen`` is empty: no console),
    checked without touching any file, so a daemon refuses before it takes anything.

    Listening beyond loopback without a token is refused: anyone on the network could
    otherwise pause or abort the machine.
    """
    section = config["console"]
    if not section["listen"]:
        return None
    host, port = parse_listen(section["listen"])
    if not section["token_file"] and not is_loopback(host):
        raise ConsoleRefused(f"console.listen = {section['listen']} is not a loopback "
                             "address and console.token_file is empty: refusing to serve "
                             "the console to the network without a token")
    return host, port


def console_settings(config: Config) -> ConsoleSettings | None:
    """The console's address and token (the token file is written if missing)."""
    listen = console_listen(config)
    if listen is None:
        return None
    token_file = config["console"]["token_file"]
    token = load_token(config.resolve(token_file), config["control"]["group"]) \
        if token_file else None
    return ConsoleSettings(*listen, token)


def load_token(path: Path, group: str = "") -> str:
    """The console token from ``path``, written first if there is none (0640, the control
    group's). A token file others can read is refused: it would open the machine to them."""
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o640)
        with os.fdopen(fd, "w") as out:
            out.write(secrets.token_urlsafe(32) + "\n")
        if group:
            os.chown(path, -1, grp.getgrnam(group).gr_gid)
    mode = os.stat(path).st_mode
    if not stat.S_ISREG(mode):
        raise ConsoleRefused(f"{path}: console.token_file is not a regular file")
    if mode & 0o007:
        raise ConsoleRefused(f"{path}: the console token is readable by others (mode "
                             f"{stat.S_IMODE(mode):04o}); chmod o-rwx it")
    token = path.read_text(errors="replace").strip()
    if len(token) < 16 or not token.isprintable():
        raise ConsoleRefused(f"{path}: the console token must be one line of at least 16 "
                             "printable characters")
    return token


def token_matches(given: str | None, expected: str | None) -> bool:
    """Constant-time comparison; no token configured means no change is allowed."""
    if not given or expected is None:
        return False
    return hmac.compare_digest(given.encode(), expected.encode())
