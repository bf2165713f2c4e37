"""The web console driven in headless Chromium against `station serve --simulate`.

One job goes the whole way from the page: the pattern file is uploaded and submitted,
the station photographs the simulated table and asks to confirm the fabric, the
operator confirms on the page, and the page shows the pieces turning to cut over the
photographed fabric until the job is done.
"""

from __future__ import annotations

import http.client
import json
import socket
import urllib.error
import urllib.request
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest

from solver.garment import load_garment
from solver.seams.export import export_cad_dxf
from station.control import ControlError, request
from station.daemon import wait_until
from station.web.app import MAX_STREAMS
from tests.station.unsure_seams import without_notches

GARMENT = Path(__file__).resolve().parents[1] / "data" / "garments" / "berkeley" / \
    "tshirt-coarse.obj"
GPG_TEE = Path(__file__).resolve().parents[1] / "data" / "garments" / \
    "garment_pattern_generator" / "tee.json"  # MIT, bundled

# Records, on every change of the marker, how many of its pieces the page shows cut.
WATCH_MARKER = """() => {
  window.cutCounts = [];
  const record = () => {
    const shown = [...document.querySelectorAll('#marker polygon')];
    if (!shown.length) return;
    const cut = shown.filter((p) => p.dataset.state === 'cut').length;
    const last = window.cutCounts[window.cutCounts.length - 1];
    if (!last || last[0] !== cut || last[1] !== shown.length) {
      window.cutCounts.push([cut, shown.length]);
    }
  };
  new MutationObserver(record).observe(document.querySelector('#marker'),
    {subtree: true, childList: true, attributes: true, attributeFilter: ['data-state']});
}"""


def test_the_console_from_upload_to_cut_pieces(page, station, tmp_path_factory):
    """One job the whole way from the page, then what the page and the server show and
    refuse about it. One test, so that the simulated job runs once on whichever xdist
    worker takes it; each check below is named for what it shows."""
    silent, trickling = slow_clients(station)  # checked once the job is done
    done_job = run_job_from_the_page(page, station)
    the_station_asks_and_the_page_confirms_the_fabric(done_job, station)
    the_page_shows_the_pieces_turning_to_cut(done_job, station)
    the_page_of_a_done_job_shows_it_over_the_photographed_fabric(page, station)
    pause_without_the_token_is_refused(page, station)
    only_the_listed_pictures_of_a_job_are_served(station)
    oversized_requests_are_refused(station)
    a_broken_pattern_is_refused_and_nothing_queued(station)
    live_views_are_bounded(station)
    a_seam_struck_out_on_the_page_is_not_sewn(page, station, tmp_path_factory)
    for client in (silent, trickling):  # long closed by the console, as the socket does
        assert client.recv(1024) == b""
        client.close()


def slow_clients(station) -> tuple[socket.socket, socket.socket]:
    """A client that connects and says nothing, and one that sends half a request head:
    each would hold one of the console's connections for ever if nothing timed heads."""
    silent = socket.create_connection(("127.0.0.1", station.port))
    trickling = socket.create_connection(("127.0.0.1", station.port))
    trickling.sendall(b"GET /api/state HTTP/1.1\r\nHost: 127.0.0.1\r\n")
    for client in (silent, trickling):
        client.settimeout(2.0)
    return silent, trickling


def run_job_from_the_page(page, station) -> dict:
    """Job 1, submitted, confirmed and watched from the page until done: what the page
    showed of its pieces meanwhile, and the question it asked."""
    page.goto(station.url)
    page.fill("#token", station.token)
    page.click("#token-form button")
    page.set_input_files("#pattern", str(GARMENT))
    page.select_option("#units", "m")
    page.click("#submit-button")
    question = page.locator('.question[data-job="1"]')
    question.wait_for(timeout=60_000)
    asked = question.inner_text()
    page.evaluate(WATCH_MARKER)
    question.locator("button").click()
    try:
        page.wait_for_selector('#job[data-state="done"]', timeout=90_000)
    except Exception:
        pytest.fail(f"job 1 did not finish: {station.state()['jobs']}\n{station.log()}")
    page.wait_for_function("() => [...document.querySelectorAll('#marker polygon')]"
                           ".every((p) => p.dataset.state === 'cut')", timeout=5_000)
    seen = page.evaluate("window.cutCounts")
    return {"asked": asked, "cut_counts": seen}


def the_station_asks_and_the_page_confirms_the_fabric(done_job, station) -> None:
    assert "confirm fabric" in done_job["asked"]
    messages = [e["message"] for e in station.state()["events"] if e["job_id"] == 1]
    assert any(m.startswith("paused -> planning: fabric confirmed as") for m in messages), \
        messages
    assert messages[-1] == "cutting -> done"
    assert station.state()["questions"] == []


def the_page_shows_the_pieces_turning_to_cut(done_job, station) -> None:
    pieces = station.state()["pieces"]["1"]
    assert len(pieces) >= 4 and all(p["state"] == "cut" for p in pieces)
    counts = [cut for cut, shown in done_job["cut_counts"]]
    assert {shown for _, shown in done_job["cut_counts"]} == {len(pieces)}
    assert counts == sorted(counts) and counts[-1] == len(pieces), counts
    # the page followed the cut piece by piece, not only its start and its end
    assert len({c for c in counts if 0 < c < len(pieces)}) >= 3, counts


def the_page_of_a_done_job_shows_it_over_the_photographed_fabric(page, station) -> None:
    page.goto(station.url)
    page.wait_for_selector('#jobs tr[data-job="1"][data-state="done"]')
    page.wait_for_selector("#marker polygon")
    assert page.inner_text("#job-title").startswith("Job 1: done")
    layout = json.loads((station.work / "job-1" / "layout.json").read_text())
    names = page.eval_on_selector_all("#marker text", "ts => ts.map((t) => t.textContent)")
    assert sorted(names) == sorted(p["name"] for p in layout["pieces"])
    shown = page.eval_on_selector_all("#marker polygon", "ps => ps.map((p) => p.dataset.state)")
    assert shown == ["cut"] * len(layout["pieces"])
    assert page.locator("#marker line.grain").count() == len(names)
    assert "at confidence" in page.inner_text("#fabric-group")
    links = page.eval_on_selector_all("#file-links a", "as => as.map((a) => a.textContent)")
    assert {"frame.png", "detection.png", "marker.png", "toolpath.png"} <= set(links), links
    page.wait_for_function("() => document.querySelector('#fit').naturalWidth > 0")
    page.wait_for_selector("#photo .lattice line")
    page.wait_for_timeout(300)  # the marker's background picture, once decoded
    shot = cv2.imdecode(np.frombuffer(page.locator("#marker").screenshot(), np.uint8),
                        cv2.IMREAD_COLOR)
    assert shot.std() > 20, "the marker is drawn on a blank background"
    # that background is the photograph of the table, not a picture drawn for the group
    with urllib.request.urlopen(station.url + "api/jobs/1/cloth.png") as answer:
        cloth = cv2.imdecode(np.frombuffer(answer.read(), np.uint8), cv2.IMREAD_COLOR)
    rectified = cv2.imread(str(station.work / "job-1" / "rectified.png"))
    mm_per_px = json.loads((station.work / "job-1" / "camera.json").read_text())["mm_per_px"]
    h, w = cloth.shape[:2]
    crop = rectified[:round(layout["width"] / mm_per_px), :round(layout["length"] / mm_per_px)]
    photo = cv2.resize(crop, (w, h), interpolation=cv2.INTER_AREA).astype(float)
    r = np.corrcoef(photo.ravel(), cloth.astype(float).ravel())[0, 1]
    assert r > 0.9, r


def pause_without_the_token_is_refused(page, station) -> None:
    page.goto(station.url)

    def post(path: str, token: str | None) -> tuple[int, dict]:
        return tuple(page.evaluate("""async ([path, token]) => {
            const headers = token === null ? {} : {'X-Station-Token': token};
            const r = await fetch(path, {method: 'POST', headers});
            return [r.status, await r.json()];
        }""", [path, token]))

    assert post("/api/jobs/1/pause", None)[0] == 401
    assert post("/api/jobs/1/pause", "not-the-token")[0] == 403
    assert post("/api/jobs/1/abort", None)[0] == 401
    # with the token the daemon answers, as `station pause 1` is answered on the socket
    status, answer = post("/api/jobs/1/pause", station.token)
    with pytest.raises(ControlError) as refused:
        request(station.socket, "pause", job=1)
    assert status == 409 and answer == {"ok": False, "error": str(refused.value)}
    status, answer = post("/api/jobs/1/retry", station.token)
    assert status == 409 and "only failed or aborted jobs can be retried" in answer["error"]
    assert station.state()["jobs"][0]["state"] == "done"


def _get(station, path: str, host: str | None = None) -> int:
    conn = http.client.HTTPConnection("127.0.0.1", station.port, timeout=5)
    conn.request("GET", path, headers={"Host": host} if host else {})
    status = conn.getresponse().status
    conn.close()
    return status


def only_the_listed_pictures_of_a_job_are_served(station) -> None:
    assert _get(station, "/api/jobs/1/files/rectified.png") == 200
    assert _get(station, "/api/jobs/1/files/marker.png") == 200
    for path in ("/api/jobs/1/files/layout.json", "/api/jobs/1/files/..%2F..%2Fjobs.db",
                 "/api/jobs/1/files/%2Fetc%2Fpasswd", "/api/jobs/2/files/rectified.png",
                 "/static/../../jobs.db", "/static/..%2F..%2Fconfig.py"):
        assert _get(station, path) == 404, path
    # a page elsewhere reaching the console through DNS rebinding: refused by its name
    assert _get(station, "/api/state", host=f"attacker.example:{station.port}") == 421


def oversized_requests_are_refused(station) -> None:
    big = json.dumps({"group": "p4m", "pad": "x" * (70 << 10)}).encode()
    req = urllib.request.Request(station.url + "api/jobs/1/confirm", data=big, method="POST",
                                 headers={"X-Station-Token": station.token})
    with pytest.raises(urllib.error.HTTPError) as refused:
        urllib.request.urlopen(req, timeout=5)
    assert refused.value.code == 413


def a_broken_pattern_is_refused_and_nothing_queued(station) -> None:
    """The page's upload goes through the same intake as `station submit`: a pattern that
    cannot be read is refused by name, nothing is queued and the upload is removed."""

    def post(path: str, data: bytes) -> tuple[int, dict]:
        req = urllib.request.Request(station.url + path, data=data, method="POST",
                                     headers={"X-Station-Token": station.token})
        try:
            with urllib.request.urlopen(req, timeout=60) as answer:
                return answer.status, json.load(answer)
        except urllib.error.HTTPError as refused:
            return refused.code, json.load(refused)

    jobs_before = len(station.state()["jobs"])
    status, sent = post("api/uploads?name=broken.obj", b"v 0 0 0\nf 1 2 3\n")
    assert status == 200 and sent["upload"].endswith("/broken.obj"), sent
    status, answer = post("api/submit", json.dumps({"garment": sent["upload"]}).encode())
    assert status == 409 and "broken.obj" in answer["error"], answer
    assert len(station.state()["jobs"]) == jobs_before
    assert not (station.work / "uploads" / sent["upload"]).parent.exists()
    assert post("api/uploads?name=../x.obj", b"v 0 0 0\n")[0] == 400


def live_views_are_bounded(station) -> None:
    """Each open page holds one event stream; past MAX_STREAMS a newcomer is told to come
    back (503), and a stream closed gives its seat back."""

    def open_stream() -> tuple[http.client.HTTPResponse, http.client.HTTPConnection]:
        conn = http.client.HTTPConnection("127.0.0.1", station.port, timeout=5)
        conn.request("GET", "/api/events")
        return conn.getresponse(), conn

    opened = [open_stream() for _ in range(MAX_STREAMS + 1)]
    statuses = [answer.status for answer, _ in opened]
    assert statuses.count(200) <= MAX_STREAMS and statuses[-1] == 503, statuses
    assert opened[0][0].read1(65536).startswith(b"id: ")  # a live view, sent at once
    for _, conn in opened:
        conn.close()

    def seat_free() -> bool:
        answer, conn = open_stream()
        conn.close()
        return answer.status == 200

    assert wait_until(seat_free, 5)


def a_seam_struck_out_on_the_page_is_not_sewn(page, station, tmp_path_factory) -> None:
    """A CAD pattern whose seams are unsure: the page lists them with tick boxes; the
    operator strikes out one unsure seam and confirms, and the job is planned with the
    others only (the answer is the whole list, nothing inferred again)."""
    dxf = tmp_path_factory.mktemp("cad") / "tee.dxf"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        export_cad_dxf(load_garment(GPG_TEE), dxf, allowance_mm=10.0, seed=3)
    without_notches(dxf, "sleeve")
    job = request(station.socket, "submit", garment=str(dxf), fabric=None)["job"]["id"]
    folder = station.work / f"job-{job}"

    def asks(question: str) -> bool:
        return any(q["job"] == job and q["question"] == question
                   for q in station.state()["questions"])

    assert wait_until(lambda: asks("confirm fabric"), 60), station.log()
    request(station.socket, "confirm", job=job)
    assert wait_until(lambda: asks("confirm seams"), 60), station.log()
    found = json.loads((folder / "seams.json").read_text())
    page.goto(station.url)
    box = page.locator(f'.question[data-job="{job}"]')
    box.locator("input[data-seam]").first.wait_for(timeout=10_000)
    assert box.locator("input[data-seam]").count() == len(found["seams"])
    unsure = box.locator('li[data-unsure="yes"] input[data-seam]')
    struck = int(unsure.first.get_attribute("data-seam"))
    marked = [int(t.get_attribute("data-seam")) for t in unsure.all()]
    assert marked == [s["number"] for s in found["seams"] if s["confidence"] < 0.9]
    unsure.first.uncheck()
    box.locator("button").click()
    page.wait_for_selector("#message.good", timeout=10_000)
    assert "no others" in page.inner_text("#message")
    confirmed = json.loads((folder / "seams-confirmed.json").read_text())
    assert confirmed["infer"] is False
    assert len(confirmed["seams"]) == len(found["seams"]) - 1
    # planning reads the answer: the seams listed again are the kept ones, none added
    assert wait_until(lambda: not asks("confirm seams") and json.loads(
        (folder / "seams.json").read_text())["seams"] != found["seams"], 30), station.log()
    again = json.loads((folder / "seams.json").read_text())["seams"]
    kept = [(s["a"], s["b"], s["length_mm"]) for s in found["seams"] if s["number"] != struck]
    assert sorted((s["a"], s["b"], s["length_mm"]) for s in again) == sorted(kept)
    request(station.socket, "abort", job=job)
