"""One headless Chromium (Debian's package, driven by Playwright) and one `station serve
--simulate` for the console's tests: the daemon photographs the simulated table, asks to
confirm the fabric (confirm_below = 1), plans quickly and cuts on a fast emulator.

Without Chromium or Playwright the browser tests skip, saying why; under CI (CI=true) they
fail instead: `make test` installs both, and a silent skip would hide that it did not.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import urllib.request
from pathlib import Path

import pytest

from station.config import EMULATOR_PORT
from station.daemon import wait_until

try:
    from playwright.sync_api import sync_playwright
except ImportError:  # the dev extra is not installed
    sync_playwright = None

CHROMIUM = Path("/usr/bin/chromium")
# Chromium as the machine notes start it: no sandbox (root in CI), and none of its
# background connections, which a closed network refuses by the dozen.
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]
EMULATOR_SPEED = 200  # simulated seconds per wall second: six pieces cut in a few seconds


def _unavailable(reason: str) -> None:
    if os.environ.get("CI"):
        pytest.fail(f"CI needs the console's browser tests and {reason} (run `make test`, "
                    "which installs Debian's chromium and the dev extra)")
    pytest.skip(f"{reason}: the console's browser tests are skipped (`make test` installs it)")


@pytest.fixture(scope="module")
def browser():
    if sync_playwright is None:
        _unavailable("Playwright is not installed")
    if not CHROMIUM.exists():
        _unavailable(f"{CHROMIUM} is missing")
    with sync_playwright() as pw:
        chromium = pw.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        yield chromium
        chromium.close()


@pytest.fixture
def page(browser):
    context = browser.new_context(viewport={"width": 1400, "height": 1000})
    tab = context.new_page()
    errors: list[str] = []
    tab.on("pageerror", lambda exc: errors.append(str(exc)))
    yield tab
    context.close()
    assert not errors, f"the page raised: {errors}"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Station:
    """The served station: its folder, console URL, token and control socket."""

    def __init__(self, folder: Path, port: int, proc: subprocess.Popen) -> None:
        self.folder = folder
        self.url = f"http://127.0.0.1:{port}/"
        self.port = port
        self.proc = proc
        self.socket = folder / "station.sock"
        self.work = folder / "work"

    @property
    def token(self) -> str:
        return (self.folder / "console.token").read_text().strip()

    def state(self) -> dict:
        with urllib.request.urlopen(self.url + "api/state", timeout=5) as answer:
            return json.load(answer)

    def log(self) -> str:
        return (self.folder / "daemon.log").read_text()[-4000:]


@pytest.fixture(scope="module")
def station(tmp_path_factory):
    folder = tmp_path_factory.mktemp("console")
    port = free_port()
    serial = EMULATOR_PORT.replace("speed=50", f"speed={EMULATOR_SPEED}")
    (folder / "station.toml").write_text(
        f'[serial]\nport = "{serial}"\n'
        '[store]\npath = "jobs.db"\nwork_dir = "work"\n'
        '[control]\nsocket = "station.sock"\n'
        f'[console]\nlisten = "127.0.0.1:{port}"\ntoken_file = "console.token"\n'
        "[camera]\nconfirm_below = 1.0\n[seams]\nconfirm_below = 0.9\n"
        "[align]\nrestarts = 1\n[nest]\nseconds = 1.0\n")
    with open(folder / "daemon.log", "wb") as log:
        proc = subprocess.Popen([sys.executable, "-m", "station.cli", "serve", "--simulate",
                                 "--config", str(folder / "station.toml")],
                                stdout=log, stderr=log, cwd=folder)
    served = Station(folder, port, proc)

    def up() -> bool:
        try:
            return "jobs" in served.state()
        except OSError:
            return proc.poll() is not None  # died: stop waiting, the assert below says so

    assert wait_until(up, 60, 0.2) and proc.poll() is None, served.log()
    yield served
    proc.terminate()
    proc.wait(30)
