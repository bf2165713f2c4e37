"""A follower (`station watch`, `submit --wait`, the demo) keeps asking a daemon that is too
busy to answer in time, and gives up only after its patience: on a loaded machine one
step (the demo's reshape) may hold the daemon for longer than one request waits."""

from __future__ import annotations

import io

import pytest

import station.progress as progress
from station.control import DaemonBusy


def test_a_busy_daemon_is_asked_again_until_it_answers():
    answers = iter([DaemonBusy("busy"), DaemonBusy("busy"),
                    {"state": "done", "reason": "", "progress": {}}])

    def status(job: int):
        answer = next(answers)
        if isinstance(answer, Exception):
            raise answer
        return answer

    assert progress.follow(status, 1, stream=io.StringIO())["state"] == "done"


def test_a_daemon_busy_past_the_patience_is_an_error(monkeypatch):
    monkeypatch.setattr(progress, "BUSY_PATIENCE_S", 0.05)
    asked = []

    def status(job: int):
        asked.append(job)
        raise DaemonBusy("no answer within 5 s")

    with pytest.raises(DaemonBusy, match="no answer"):
        progress.follow(status, 1, stream=io.StringIO())
    assert len(asked) > 1  # asked again before giving up
