"""The console's settings: loopback unless told, a token for the network, the token file."""

from __future__ import annotations

import os
import stat

import pytest

from station.cli import main
from station.config import load_config
from station.web.access import ConsoleRefused, console_settings, parse_listen, token_matches


def _config(tmp_path, **console):
    return load_config(None, {"console": {"token_file": str(tmp_path / "console.token"),
                                          **console}})


def test_the_default_console_is_loopback_with_a_private_token(tmp_path):
    settings = console_settings(_config(tmp_path))
    assert (settings.host, settings.port, settings.loopback) == ("127.0.0.1", 8410, True)
    token_file = tmp_path / "console.token"
    assert stat.S_IMODE(os.stat(token_file).st_mode) == 0o640
    assert settings.token == token_file.read_text().strip() and len(settings.token) >= 32
    # the next start reads the same token; an empty listen means no console at all
    assert console_settings(_config(tmp_path)).token == settings.token
    assert console_settings(_config(tmp_path, listen="")) is None


def test_a_network_console_without_a_token_is_refused_at_start(tmp_path, capsys):
    with pytest.raises(ConsoleRefused, match="not a loopback address"):
        console_settings(_config(tmp_path, listen="0.0.0.0:8410", token_file=""))
    # a loopback console without a token is read-only (no change can match no token)
    read_only = console_settings(_config(tmp_path, listen="[::1]:8410", token_file=""))
    assert read_only.token is None and read_only.loopback
    assert not token_matches("anything", None) and not token_matches("", "x" * 32)
    # `station serve` stops at once with one line naming the keys; nothing was left running
    config = tmp_path / "station.toml"
    config.write_text('[store]\npath = "jobs.db"\nwork_dir = "work"\n'
                      '[control]\nsocket = "station.sock"\n'
                      '[console]\nlisten = "0.0.0.0:18999"\ntoken_file = ""\n')
    assert main(["serve", "--simulate", "--config", str(config)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "console.listen = 0.0.0.0:18999" in err, err
    assert not (tmp_path / "station.sock").exists()


def test_a_token_file_others_can_read_is_refused(tmp_path):
    token_file = tmp_path / "console.token"
    token_file.write_text("a-token-long-enough-to-count\n")
    token_file.chmod(0o644)
    with pytest.raises(ConsoleRefused, match="readable by others"):
        console_settings(_config(tmp_path))
    token_file.chmod(0o600)
    token_file.write_text("short\n")
    with pytest.raises(ConsoleRefused, match="at least 16"):
        console_settings(_config(tmp_path))


@pytest.mark.parametrize("listen", ["8410", "localhost:", ":8410", "host:99999", "h:x"])
def test_a_listen_address_must_be_host_and_port(listen):
    with pytest.raises(ConsoleRefused, match="HOST:PORT"):
        parse_listen(listen)
