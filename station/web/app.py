"""The console's HTTP side: the page, its live view, a job's pictures, and the console
commands behind the station's token.

Every command goes through ``ControlServer.answer``, the very entry the Unix socket's
lines go through (`station pause 3` and the page's Pause button run the same handler
with the same rules); the page adds only the upload of a pattern file, which it hands to
``submit`` as a path, so intake copies and checks it in a bounded child like any other.
"""

from __future__ import annotations

import asyncio
import json
import re
import secrets
import shutil
import time
from pathlib import Path
from typing import Any

from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response, StreamingResponse
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from station.web.access import TOKEN_HEADER, token_matches
from station.web.feed import Feed
from station.web.jobview import JobFiles
from untrusted.limits import MAX_REQUEST_BYTES

STATIC = Path(__file__).with_name("static")
ACTIONS = ("confirm", "pause", "resume", "abort", "retry")
#: a pattern or FABRIC.json sent from the browser; bigger patterns go by `station submit`
MAX_UPLOAD_BYTES = 64 << 20
MAX_STREAMS = 16  # open live views at once (each page holds one)
UPLOAD_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,99}$")
UPLOADS_KEPT_S = 3600.0  # an upload never submitted is removed after an hour


class ConsoleApp:
    """The routes of one station's console."""

    def __init__(self, daemon: Any, feed: Feed, token: str | None, work_dir: Path) -> None:
        self.daemon = daemon
        self.feed = feed
        self.token = token
        self.jobs = JobFiles(work_dir)
        self.uploads = work_dir.resolve() / "uploads"
        self.streams = 0
        allowed = daemon.intake.allowed
        if allowed and self.uploads not in allowed:
            allowed.append(self.uploads)  # the page's uploads are this station's own folder

    def starlette(self) -> Starlette:
        return Starlette(routes=[
            Route("/", self.index),
            Route("/api/state", self.state),
            Route("/api/events", self.events),
            Route("/api/jobs/{job:int}", self.job),
            Route("/api/jobs/{job:int}/cloth.png", self.cloth),
            Route("/api/jobs/{job:int}/files/{name}", self.picture),
            Route("/api/uploads", self.upload, methods=["POST"]),
            Route("/api/submit", self.submit, methods=["POST"]),
            Route("/api/jobs/{job:int}/{action}", self.action, methods=["POST"]),
            Mount("/static", StaticFiles(directory=STATIC), name="static"),
        ])

    # ------------------------------------------------------------------ reading
    async def index(self, _request: Request) -> Response:
        return FileResponse(STATIC / "index.html")

    def state(self, _request: Request) -> Response:
        """The view once (read now), for a script or a page before its stream opens."""
        try:
            self.feed.refresh()
        except Exception as exc:  # the store away: the last view, and why it is old
            return JSONResponse({"version": self.feed.version, **self.feed.view,
                                 "stale": str(exc)})
        return JSONResponse({"version": self.feed.version, **self.feed.view})

    async def events(self, request: Request) -> Response:
        """Server-sent events: the whole view each time it changes, a comment every 15 s
        to keep proxies from closing a quiet stream."""
        if self.streams >= MAX_STREAMS:
            return JSONResponse({"ok": False, "error": "too many console pages open"}, 503)

        async def stream():
            # counted from inside: a client gone before its stream began never holds a seat
            self.streams += 1
            self.feed.watch()
            sent, quiet = -1, 0.0
            try:
                while not self.feed.stopped and not await request.is_disconnected():
                    if self.feed.version not in (sent, 0):  # 0: nothing read yet
                        sent = self.feed.version
                        yield f"id: {sent}\ndata: {json.dumps(self.feed.view)}\n\n"
                        quiet = 0.0
                    elif quiet > 15.0:
                        yield ": still here\n\n"
                        quiet = 0.0
                    await asyncio.sleep(0.1)
                    quiet += 0.1
            finally:
                self.streams -= 1
                self.feed.unwatch()

        return StreamingResponse(stream(), media_type="text/event-stream",
                                 headers={"Cache-Control": "no-store"})

    def job(self, request: Request) -> Response:
        job_id = request.path_params["job"]
        answer = self.command({"cmd": "status", "job": job_id})
        if not answer["ok"]:
            return JSONResponse(answer, 404)
        return JSONResponse({"ok": True, "job": answer["job"], **self.jobs.detail(job_id)})

    def cloth(self, request: Request) -> Response:
        png = self.jobs.cloth_png(request.path_params["job"])
        if png is None:
            return JSONResponse({"ok": False, "error": "the job has no marker yet"}, 404)
        return Response(png, media_type="image/png", headers={"Cache-Control": "no-store"})

    def picture(self, request: Request) -> Response:
        path = self.jobs.file(request.path_params["job"], request.path_params["name"])
        if path is None:
            return JSONResponse({"ok": False, "error": "no such picture"}, 404)
        return FileResponse(path, headers={"Cache-Control": "no-store"})

    # ------------------------------------------------------------------ changing
    def refused(self, request: Request) -> Response | None:
        """401 without the token, 403 with a wrong one; None when the request may go on."""
        given = request.headers.get(TOKEN_HEADER)
        if not given:
            return JSONResponse({"ok": False, "error": f"the console token is needed "
                                 f"(header {TOKEN_HEADER})"}, 401)
        if not token_matches(given, self.token):
            return JSONResponse({"ok": False, "error": "wrong console token"}, 403)
        return None

    async def action(self, request: Request) -> Response:
        """confirm, pause, resume, abort or retry job N, as `station ACTION N` does."""
        if (refusal := self.refused(request)) is not None:
            return refusal
        action = request.path_params["action"]
        if action not in ACTIONS:
            return JSONResponse({"ok": False, "error": f"unknown action {action!r}"}, 404)
        body = await self.json_body(request)
        if isinstance(body, Response):
            return body
        req: dict[str, Any] = {"cmd": action, "job": request.path_params["job"]}
        if action == "confirm" and body.get("group"):
            req["group"] = body["group"]
        if action == "confirm" and body.get("seams") is not None:
            req["seams"] = body["seams"]  # checked by the daemon as `station confirm --seams`
        return self.answered(await asyncio.to_thread(self.command, req))

    async def upload(self, request: Request) -> Response:
        """One file of a submission, kept until ``submit`` names it (by the id answered)."""
        if (refusal := self.refused(request)) is not None:
            return refusal
        name = request.query_params.get("name", "")
        if not UPLOAD_NAME.match(name):
            return JSONResponse({"ok": False, "error": "name the file with letters, digits, "
                                 "'.', '_' or '-' (at most 100)"}, 400)
        self.forget_old_uploads()
        folder = self.uploads / secrets.token_hex(8)
        folder.mkdir(parents=True, mode=0o700)
        size = 0
        with open(folder / name, "wb") as out:
            async for chunk in request.stream():
                size += len(chunk)
                if size > MAX_UPLOAD_BYTES:
                    out.close()
                    shutil.rmtree(folder, ignore_errors=True)
                    return JSONResponse({"ok": False, "error": "a file sent from the page is "
                                         f"at most {MAX_UPLOAD_BYTES >> 20} MiB; submit a "
                                         "bigger one with `station submit`"}, 413)
                out.write(chunk)
        return JSONResponse({"ok": True, "upload": f"{folder.name}/{name}"})

    async def submit(self, request: Request) -> Response:
        """Queue a job from uploaded files: ``{"garment": id, "fabric": id or null,
        "options": {...}}``; without a fabric the station photographs the table."""
        if (refusal := self.refused(request)) is not None:
            return refusal
        body = await self.json_body(request)
        if isinstance(body, Response):
            return body
        files = {k: self.uploaded(body.get(k)) for k in ("garment", "fabric")}
        if files["garment"] is None or (body.get("fabric") and files["fabric"] is None):
            return JSONResponse({"ok": False, "error": "upload the pattern file first"}, 400)
        req = {"cmd": "submit", "garment": str(files["garment"]),
               "fabric": None if files["fabric"] is None else str(files["fabric"]),
               "options": body.get("options") or {}}
        try:
            answer = await asyncio.to_thread(self.command, req)
        finally:  # intake took its own copies (or refused): the uploads are done with
            for path in files.values():
                if path is not None:
                    shutil.rmtree(path.parent, ignore_errors=True)
        return self.answered(answer)

    # ------------------------------------------------------------------ helpers
    def command(self, req: dict[str, Any]) -> dict[str, Any]:
        """The control socket's answer to ``req`` (same parsing, handler and errors)."""
        return self.daemon.control.answer(json.dumps(req).encode())

    @staticmethod
    def answered(answer: dict[str, Any]) -> Response:
        return JSONResponse(answer, 200 if answer.get("ok") else 409)

    @staticmethod
    async def json_body(request: Request) -> dict[str, Any] | Response:
        """The request's JSON object (empty body: {}), bounded like a control socket line."""
        data = b""
        async for chunk in request.stream():
            data += chunk
            if len(data) > MAX_REQUEST_BYTES:
                return JSONResponse({"ok": False, "error": f"request longer than "
                                     f"{MAX_REQUEST_BYTES} bytes refused"}, 413)
        try:
            body = json.loads(data) if data.strip() else {}
        except ValueError:
            body = None
        if not isinstance(body, dict):
            return JSONResponse({"ok": False, "error": "the body must be a JSON object"}, 400)
        return body

    def uploaded(self, upload: Any) -> Path | None:
        """The file of an upload id ('hex/name'), None if there is no such upload."""
        if not isinstance(upload, str) or not re.fullmatch(r"[0-9a-f]{16}/[^/]{1,100}", upload):
            return None
        path = self.uploads / upload
        return path if UPLOAD_NAME.match(path.name) and path.is_file() else None

    def forget_old_uploads(self) -> None:
        if not self.uploads.is_dir():
            return
        limit = time.time() - UPLOADS_KEPT_S
        for folder in self.uploads.iterdir():
            if folder.is_dir() and folder.stat().st_mtime < limit:
                shutil.rmtree(folder, ignore_errors=True)
