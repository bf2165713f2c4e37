"""The operator's screen: a web console served by the daemon (`station.web.server`)."""

from station.web.access import ConsoleRefused
from station.web.server import ConsoleServer

__all__ = ["ConsoleRefused", "ConsoleServer"]
