"""What the console pages are sent: the fleet's stations, the jobs and their pieces, the
questions the station asks, the event log; read from a real job store."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from station.config import load_config
from station.daemon import CONFIRM_FABRIC, Daemon, wait_until
from station.web.feed import Feed

_spec = importlib.util.spec_from_file_location(
    "daemon_tests", Path(__file__).parents[1] / "station" / "test_daemon.py")
_daemon_tests = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_daemon_tests)


@pytest.fixture
def daemon(tmp_path):
    config = load_config(None, {
        "store": {"path": str(tmp_path / "jobs.db"), "work_dir": str(tmp_path / "work")},
        "control": {"socket": str(tmp_path / "station.sock")},
        "station": {"name": "left-table"},
    })
    daemon = Daemon(config, _daemon_tests.TickingPipeline())
    daemon.fleet.join()
    yield daemon
    daemon.fleet.stop()
    daemon.store.close()
    daemon.lock.release()


def test_the_view_holds_the_fleet_the_jobs_their_pieces_and_the_questions(daemon, tmp_path):
    feed = Feed(daemon, {CONFIRM_FABRIC: "confirm"})
    store = daemon.store
    waiting = store.submit(str(tmp_path / "shirt.obj"), None, {})
    store.transition(waiting.id, "capturing")
    store.transition(waiting.id, "paused", f"{CONFIRM_FABRIC}: pmm at confidence 0.55")
    cutting = store.submit(str(tmp_path / "skirt.obj"), None, {})
    for state in ("capturing", "planning"):
        store.transition(cutting.id, state)
    store.set_pieces(cutting.id, ["front#1", "back#1"])
    store.set_piece_state(cutting.id, 0, "cut")

    feed.refresh()
    view, version = feed.view, feed.version
    assert [s["name"] for s in view["stations"]] == ["left-table"]
    assert view["stations"][0]["state"] == "idle"
    assert [(j["id"], j["state"]) for j in view["jobs"]] == [(waiting.id, "paused"),
                                                               (cutting.id, "planning")]
    assert view["pieces"][str(cutting.id)] == [
        {"piece": 0, "name": "front#1", "state": "cut"},
        {"piece": 1, "name": "back#1", "state": "pending"}]
    assert view["questions"] == [{"job": waiting.id, "question": CONFIRM_FABRIC,
                                  "answer": "confirm",
                                  "reason": f"{CONFIRM_FABRIC}: pmm at confidence 0.55"}]
    assert any(e["message"].startswith("capturing -> paused") for e in view["events"])

    feed.refresh()  # nothing changed: the pages are sent nothing new
    assert feed.version == version
    store.set_piece_state(cutting.id, 1, "cutting")
    feed.refresh()
    assert feed.version == version + 1
    assert feed.view["pieces"][str(cutting.id)][1]["state"] == "cutting"
    # the log is read on from where it stopped: each event once
    ids = [e["id"] for e in feed.view["events"]]
    assert ids == sorted(set(ids)) and len(ids) == len(store.events())


def test_nobody_watching_means_no_reading(daemon, tmp_path):
    """The streamer shares the interpreter with the feed: with no page open, the feed reads
    nothing; the first page makes it read, within one interval."""
    feed = Feed(daemon, {}, interval=0.05)
    feed.start()
    try:
        daemon.store.submit(str(tmp_path / "shirt.obj"), None, {})
        assert not wait_until(lambda: feed.version > 0, 0.5)
        feed.watch()
        assert wait_until(lambda: feed.version > 0, 2)
        assert [j["state"] for j in feed.view["jobs"]] == ["submitted"]
        feed.unwatch()
        seen = feed.version
        daemon.store.submit(str(tmp_path / "skirt.obj"), None, {})
        assert not wait_until(lambda: feed.version > seen, 0.5)
    finally:
        feed.stop()
