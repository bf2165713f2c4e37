"""`station serve`: takes jobs in order and runs each through capture, planning and cutting.

One worker (the main thread) runs jobs; the control socket's threads only read the job
store and raise flags (pause, abort, stop) that the worker and the streamer act on, as
huey's consumer does with signals. Every state change goes through the job store first,
so a daemon killed at any moment restarts knowing where each job was: a job found in an
active state is marked paused ("interrupted at piece 4, 62 % cut: resume continues from
there"), its piece in progress goes back to pending with its progress kept, and the
operator's `resume` re-homes or unlocks the machine, cuts the rest of that piece from a
few millimetres before where it stopped (`station.cutting`) and then the pieces not yet
cut.

The piece in flight. A controller outlives its daemon: after a SIGKILL it runs the moves
already in its buffers, so the piece being cut may be finished with nobody listening
for its sync point. The store alone cannot know that; the machine can. The program
therefore writes a marker into the controller's EEPROM (G59 offsets) just before and
just after each piece's final move, and GRBL writes it only once every move before it
has run. At most one piece can be finished but unrecorded (the next piece's lines go out
only after this one's markers and sync line were answered and stored). Before anything
else on resume, `station.steps.cut.cut_job` waits for the machine to come to rest (sending
only the real-time ``?``), reads the marker and the head's position, and records that
piece cut exactly when the machine proves it (see `gcode.recovery` and
`station.cutting.reconcile`); then it clears the marker, homes if the position was
lost, and streams the rest. A piece the machine cannot prove finished resumes where it
stopped. tests/station/test_crash.py checks all of it against the emulator's motion trace.
"""

from __future__ import annotations

import json
import logging
import os
import signal
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from station.config import Config
from station.console_memory import AnswersFromMemory
from station.control import ControlError, ControlServer
from station.daemon_lock import lock_store
from station.fleet import Fleet, open_store, station_info
from station.fleetmember import FleetMember
from station.intake import Intake
from station.jobstore import (
    ACTIVE,
    FINAL,
    TRANSITIONS,
    Job,
    JobStore,
    JobStoreError,
    interrupted_reason,
)
from station.seams_confirm import confirm_seams
from station.storeengine import StoreUnavailable
from station.web import ConsoleServer
from vision.pipeline import confirm_fabric

log = logging.getLogger("station.daemon")


#: Reason of a job paused until the operator confirms the detected print.
CONFIRM_FABRIC = "confirm fabric"
#: Reason of a job paused until the operator confirms a CAD pattern's inferred seams.
CONFIRM_SEAMS = "confirm seams"
#: how long the console's status, jobs, pause and abort wait for the store before they
#: answer from memory; how long the other commands wait before saying it is away
MEMORY_PATIENCE_S = 0.5
CONSOLE_PATIENCE_S = 4.0


class JobInterrupted(Exception):
    """Raised inside a step when the operator paused or aborted, or the daemon stops."""

    def __init__(self, state: str, reason: str) -> None:
        super().__init__(reason)
        self.state = state
        self.reason = reason


@dataclass
class JobControl:
    """Flags the control socket raises and the running step polls (thread-safe)."""

    job_id: int
    pause: threading.Event = field(default_factory=threading.Event)
    abort: threading.Event = field(default_factory=threading.Event)
    stop: threading.Event = field(default_factory=threading.Event)
    progress: dict[str, Any] = field(default_factory=dict)

    def checkpoint(self, hold_in_place: bool = False) -> None:
        """Turn a raised flag into the matching interruption.

        While cutting, a pause is a feed hold that the streamer keeps in place
        (``hold_in_place``); between other steps it shelves the job.
        """
        if self.abort.is_set():
            raise JobInterrupted("aborted", "aborted by the operator")
        if self.stop.is_set():
            raise JobInterrupted("paused", "interrupted: the daemon stopped")
        if self.pause.is_set() and not hold_in_place:
            raise JobInterrupted("paused", "paused by the operator")

    def start_step(self, step: str, fraction: float | None = None) -> None:
        """Announce a step in the job's progress (what `station status` and `watch` show);
        ``fraction`` only where the step can measure how far it is."""
        self.progress.clear()
        self.progress.update(step=step, **({} if fraction is None else {"fraction": fraction}))


class Recorded(Protocol):
    """What a step hands on inside the process, and what the job store keeps of it (the
    paths of the job's files, and for a plan its pieces by layout id)."""

    def record(self) -> dict[str, Any]: ...


class Planned(Recorded, Protocol):
    pieces: list[str]


class Pipeline(Protocol):
    """The work of one job (`station.pipeline.StationPipeline` is the real one): each step
    takes the object the one before made in this process, or None when the job was
    captured or planned by another process; it then reads ``job.plan``, the record the
    store kept (`station.steps.capture.Captured`, `station.steps.plan.Plan`)."""

    def capture(self, job: Job, workdir: Path, control: JobControl) -> Recorded: ...

    def plan(self, job: Job, captured: Recorded | None, workdir: Path,
             control: JobControl) -> Planned: ...

    def cut(self, job: Job, plan: Planned | None, store: JobStore, control: JobControl,
            resuming: bool) -> None: ...


class _StderrHandler(logging.StreamHandler):
    """A handler on whatever ``sys.stderr`` is when a record comes, not the one it was made
    with: a command run inside another program (a test's captured stream, closed after it)
    must not leave the root logger writing to a closed file."""

    @property
    def stream(self):  # type: ignore[override]
        return sys.stderr

    @stream.setter
    def stream(self, _value) -> None:
        pass


def setup_logging(level: int = logging.INFO) -> None:
    """Log to stderr as journald keeps it: one line per record, no timestamps of our own."""
    handler = _StderrHandler()
    handler.setFormatter(logging.Formatter("<%(levelno)s>%(name)s: %(message)s"))
    root = logging.getLogger()
    root.handlers[:] = [handler]
    root.setLevel(level)


class Daemon(AnswersFromMemory):
    """The station's job loop and its control endpoints."""

    def __init__(self, config: Config, pipeline: Pipeline) -> None:
        self.config = config
        self.pipeline = pipeline
        self.console = ConsoleServer(self, {CONFIRM_FABRIC: "confirm",  # refuses unsafe
                                            CONFIRM_SEAMS: "confirm"})
        # first of all: a second daemon on this store (by any path or name) must leave
        # everything untouched
        self.lock = lock_store(config)
        try:
            self.control = ControlServer(config.resolve(config["control"]["socket"]),
                                         self.handle, config["control"]["group"])
            self.store = open_store(config)
        except BaseException:
            self.lock.release()
            raise
        self.fleet: FleetMember | None = None
        if config["station"]["name"]:
            self.fleet = FleetMember(
                Fleet(self.store, config["station"]["lost_after_s"]),
                station_info(config, getattr(pipeline, "machine", None)),
                self._doing, self.handle, config["station"]["heartbeat_s"],
                wake=lambda: self._wake.set())
        self.store.engine.on_outage = self._on_outage  # a server store; SQLite never calls
        self.work_dir = config.resolve(config["store"]["work_dir"])
        self.running: JobControl | None = None
        # what the console last read from the store, to answer from while it is away
        self._memory: dict[int, dict[str, Any]] = {}
        self._owed_pause: int | None = None  # paused while the store was away: record it
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._lock = threading.Lock()
        self.intake = Intake(self.work_dir / "inputs", getattr(pipeline, "check", None),
                             seconds=config["control"]["check_seconds"],
                             memory_bytes=config["control"]["check_memory_mb"] << 20,
                             allowed=[config.resolve(f)
                                      for f in config["control"]["submit_folders"]])

    # ------------------------------------------------------------------ lifecycle
    def serve(self, once: bool = False) -> int:
        """Run until SIGTERM/SIGINT (or, with ``once``, until no job is left)."""
        for sig in (signal.SIGTERM, signal.SIGINT):
            signal.signal(sig, self._on_signal)
        try:
            self.recover()
            self.control.start()
            self.console.start()
            log.info("serving on %s, job store %s%s", self.control.path, self.store.location,
                     f", station {self.fleet.info.name}" if self.fleet else "")
            self.run_loop(once)
        finally:
            self.intake.stop()
            self.console.stop()
            self.control.stop()
            if self.fleet is not None:
                self.fleet.stop()
            self.store.close()  # before the lock: its release closes a descriptor of the file
            self.lock.release()
            log.info("stopped")
        return 0

    def run_loop(self, once: bool = False) -> None:
        """Take jobs in order until stopped (or, with ``once``, until the queue is empty).

        A lone station takes the store's next job; a fleet station claims one it may run.
        """
        try:
            while not self._stop.is_set():
                if not self.lock.still_held():
                    log.error("another daemon took this station's name while the store was "
                              "away; stopping")
                    self.shutdown()
                    break
                job = self.fleet.claim() if self.fleet else self.store.next_job()
                if job is None:
                    if once:
                        return
                    self._wake.wait(0.5)
                    self._wake.clear()
                    continue
                try:
                    self.run_job(job)
                except Exception:  # the loop outlives any one job, even a broken failure path
                    log.exception("job %d: the job loop caught an error; the job is set aside",
                                  job.id)
                    self._set_aside(job.id)
        finally:
            if self.fleet is not None:
                self.fleet.stop()

    def _set_aside(self, job_id: int) -> None:
        """Fail a job whose own failure handling broke, so next_job() moves on."""
        try:
            if self.store.job(job_id).state not in FINAL:
                self.store.transition(job_id, "failed", "internal error while handling a "
                                      "failure (see the daemon's log)")
        except Exception:
            log.exception("job %d could not be set aside; stopping the job loop", job_id)
            self.shutdown()

    def shutdown(self) -> None:
        """Ask the loop to stop safely, as SIGTERM does."""
        self._stop.set()
        self._wake.set()
        if self.running is not None:
            self.running.stop.set()

    def _on_signal(self, signum: int, _frame: Any) -> None:
        """Only raise flags: the worker stops the machine safely and saves the state."""
        log.warning("signal %d: stopping safely", signum)
        self.shutdown()

    def recover(self) -> None:
        """After a crash, a job found active was interrupted: pause it, say so.

        In a fleet only this station's own jobs are touched: they become "interrupted"
        and this station resumes them itself (the claim takes them first).
        """
        if self.fleet is not None:
            self.fleet.join()
            for job in self.fleet.interrupt_own():
                log.warning("job %d was interrupted; station %s resumes it", job.id,
                            self.fleet.info.name)
            self.fleet.start()
            return
        for job in self.store.jobs(ACTIVE):
            reset = self.store.reset_unfinished_pieces(job.id)
            where = interrupted_reason(self.store.pieces(job.id))
            self.store.transition(job.id, "paused", "interrupted: the daemon was not running"
                                  + (f"; {where}" if where else
                                     f"; {reset} piece in progress not cut" if reset else ""))
            log.warning("job %d was interrupted while %s; paused for the operator",
                        job.id, job.state)

    # ------------------------------------------------------------------ one job
    def run_job(self, job: Job) -> None:
        control = JobControl(job.id)
        with self._lock:
            self.running = control
        workdir = self.work_dir / f"job-{job.id}"
        workdir.mkdir(parents=True, exist_ok=True)
        try:
            resuming = job.state == "cutting"
            # Each step hands the next what it made (objects, inside this process); the
            # store keeps the paths of the files, from which another process resumes.
            captured, plan = None, None
            if job.state == "submitted" and not self._admitted(job):
                job = self._admit_from_store(job)
            if job.state in ("submitted", "capturing"):
                job = self.store.transition(job.id, "capturing")
                captured = self.pipeline.capture(job, workdir, control)
                control.checkpoint()
                self.store.set_plan(job.id, captured.record())
                job = self.store.transition(job.id, "planning")
            if job.state == "planning":
                plan = self.pipeline.plan(job, captured, workdir, control)
                self.store.set_plan(job.id, plan.record())
                self.store.set_pieces(job.id, plan.pieces)
                control.checkpoint()
                job = self.store.transition(job.id, "ready")
            if job.state == "ready":
                job = self.store.transition(job.id, "cutting")
            if job.state == "cutting":
                self.pipeline.cut(job, plan, self.store, control, resuming)
                control.checkpoint()
                self.store.transition(job.id, "done")
                log.info("job %d done", job.id)
        except JobInterrupted as exc:
            self._interrupt(job.id, exc.state, exc.reason)
        except Exception as exc:
            log.exception("job %d failed", job.id)
            self._fail(job.id, f"{type(exc).__name__}: {exc}")
        finally:
            with self._lock:
                self.running = None

    def _admitted(self, job: Job) -> bool:
        """Whether the job's inputs are this station's checked copies."""
        folder = self.intake.folder.resolve()
        return all(Path(p).resolve().is_relative_to(folder)
                   for p in (job.garment, job.fabric) if p is not None)

    def _admit_from_store(self, job: Job) -> Job:
        """A job queued straight into a shared store (`station submit --fleet`, or anyone
        who reaches the database) is taken in as the socket takes one, before this
        station reads a byte of it with its own rights: the files copied within limits
        (and from the allowed folders only), checked in a bounded child."""
        garment, fabric, _ = self.intake.admit({"garment": job.garment, "fabric": job.fabric,
                                                "options": job.options})
        self.store.set_inputs(job.id, garment, fabric)
        return self.store.job(job.id)

    def _fail(self, job_id: int, reason: str) -> None:
        """Record a failure; a fault while recording it (say the job is already failed) is
        logged, never allowed out of the job loop."""
        try:
            self.store.reset_unfinished_pieces(job_id)
            current = self.store.job(job_id).state
            if "failed" in TRANSITIONS[current]:
                self.store.transition(job_id, "failed", reason)
            else:
                log.error("job %d is %s; not marked failed (%s)", job_id, current, reason)
        except Exception:
            log.exception("job %d: recording its failure failed", job_id)

    def _interrupt(self, job_id: int, state: str, reason: str) -> None:
        if self.fleet is not None and state == "paused" and self._stop.is_set():
            state = "interrupted"  # the station stopped: it takes its job up again itself
        self.store.reset_unfinished_pieces(job_id)
        current = self.store.job(job_id).state
        if current != state and state in TRANSITIONS[current]:
            self.store.transition(job_id, state, reason)
        log.info("job %d %s: %s", job_id, state, reason)

    # ------------------------------------------------------------------ fleet
    def _doing(self) -> tuple[int | None, dict[str, Any]]:
        """The running job and its progress, for the fleet's heartbeat."""
        running = self.running
        return (None, {}) if running is None else (running.job_id, dict(running.progress))

    def _on_outage(self, down: bool) -> None:
        """The shared store went away (or came back): hold the cut in place meanwhile.

        Nothing can be recorded while the server is down, so the machine must not run
        ahead of the store: a feed hold now, released when the store answers again. (A
        piece's sync point cannot pass either: recording it waits for the store.)
        """
        running = self.running
        if running is None or running.progress.get("step") != "cutting":
            return
        if down and not running.pause.is_set():
            log.warning("job store unreachable: feed hold until it is back")
            running.progress["held_for_store"] = True
            running.pause.set()
        elif not down and running.progress.pop("held_for_store", False):
            log.warning("job store back: resuming the cut")
            running.pause.clear()
        if not down and self._owed_pause is not None:
            # not from inside the store's call that is telling us: a thread of its own
            threading.Thread(target=self._record_owed_pause, daemon=True).start()

    def _record_owed_pause(self) -> None:
        job_id, self._owed_pause = self._owed_pause, None
        try:
            if job_id is not None and self.store.job(job_id).state == "cutting":
                self.store.transition(job_id, "paused", "paused by the operator (feed hold) "
                                      "while the job store was away")
        except Exception:
            log.exception("job %s: recording the operator's pause failed", job_id)

    # ------------------------------------------------------------------ control
    def handle(self, request: dict[str, Any]) -> dict[str, Any]:
        """Run a console command; status, jobs, pause and abort never wait for a store that
        is away (they answer from memory), the others wait a few seconds at most."""
        cmd = request["cmd"]
        handler = getattr(self, f"cmd_{cmd}", None)
        if handler is None:
            raise ControlError(f"unknown command {cmd!r}")
        remembered = getattr(self, f"memory_{cmd}", None)
        try:
            with self.store.engine.impatient(MEMORY_PATIENCE_S if remembered
                                             else CONSOLE_PATIENCE_S):
                return handler(request)
        except JobStoreError as exc:
            raise ControlError(str(exc)) from None
        except StoreUnavailable:
            if remembered is None:
                raise ControlError(f"the job store is unreachable; {cmd} waits until it is "
                                   "back (status, jobs, pause and abort answer meanwhile)"
                                   ) from None
            return {**remembered(request), "store": "unreachable: answered from memory"}

    def cmd_ping(self, _req: dict[str, Any]) -> dict[str, Any]:
        return {"pid": os.getpid(), "running": self.running.job_id if self.running else None}

    def cmd_submit(self, req: dict[str, Any]) -> dict[str, Any]:
        """Copy the inputs, check them in a bounded child process, then queue the job.

        This connection's thread only waits for the child; other requests are answered
        meanwhile. The job runs from the copies, so a file changed later changes nothing.
        """
        garment, fabric, options = self.intake.admit(req)
        job = self.store.submit(garment, fabric, options)
        self._wake.set()
        return {"job": job.to_dict()}

    def cmd_jobs(self, _req: dict[str, Any]) -> dict[str, Any]:
        jobs = [self._summary(j) for j in self.store.jobs()]
        self._memory = {j["id"]: {k: v for k, v in j.items() if k != "progress"} for j in jobs}
        return {"jobs": jobs}

    def cmd_status(self, req: dict[str, Any]) -> dict[str, Any]:
        job_id = req.get("job")
        if job_id is None:
            running = self.running
            jobs = self.store.jobs()
            job_id = running.job_id if running else (jobs[-1].id if jobs else None)
            if job_id is None:
                return {"job": None}
        return {"job": self._summary(self.store.job(int(job_id)))}

    def cmd_pause(self, req: dict[str, Any]) -> dict[str, Any]:
        """Cutting: feed hold in place. Earlier steps: shelve the job at the next step."""
        control = self._target(req)
        if control.pause.is_set() and not control.progress.pop("held_for_store", False):
            raise ControlError(f"job {control.job_id} is already paused")
        control.pause.set()
        if self.store.job(control.job_id).state == "cutting":
            self.store.transition(control.job_id, "paused", "paused by the operator "
                                  "(feed hold)")
            return {"job": control.job_id, "message": "paused (feed hold)"}
        return {"job": control.job_id, "message": "pausing after the current step"}

    def cmd_resume(self, req: dict[str, Any]) -> dict[str, Any]:
        job_id = req.get("job")
        running = self.running
        if running is not None and running.pause.is_set() and (
                job_id is None or int(job_id) == running.job_id):
            job = self.store.job(running.job_id)
            if job.state == "paused":
                self.store.transition(job.id, job.resume_state or "cutting",
                                      "resumed by the operator")
            running.pause.clear()
            return {"job": running.job_id, "message": "resumed"}
        paused = [j for j in self.store.jobs(("paused",))
                  if job_id is None or j.id == int(job_id)]
        if not paused:
            raise ControlError("no paused job to resume")
        job = paused[0]
        self.store.transition(job.id, job.resume_state or "submitted", "resumed by the operator")
        self._wake.set()
        return {"job": job.id, "message": f"resumed at {job.resume_state}"}

    def cmd_abort(self, req: dict[str, Any]) -> dict[str, Any]:
        job_id = req.get("job")
        running = self.running
        if running is not None and (job_id is None or int(job_id) == running.job_id):
            running.abort.set()
            return {"job": running.job_id, "message": "aborting (safe stop)"}
        if job_id is None:
            raise ControlError("no job is running; name the job to abort")
        job = self.store.job(int(job_id))
        if job.state in FINAL:
            raise ControlError(f"job {job.id} is already {job.state}")
        self.store.transition(job.id, "aborted", "aborted by the operator")
        return {"job": job.id, "message": "aborted"}

    def cmd_retry(self, req: dict[str, Any]) -> dict[str, Any]:
        if req.get("job") is None:
            raise ControlError("retry needs a job number")
        job = self.store.job(int(req["job"]))
        if job.state not in ("failed", "aborted"):
            raise ControlError(f"job {job.id} is {job.state}; only failed or aborted jobs "
                               "can be retried")
        self.store.transition(job.id, "submitted", "retried by the operator")
        self._wake.set()
        return {"job": job.id, "message": "queued again; pieces already cut stay cut"}

    def cmd_confirm(self, req: dict[str, Any]) -> dict[str, Any]:
        """Accept (or, with ``group``, correct) the print of a job waiting at "confirm
        fabric", or (with ``seams``, a --seams document) the seams of one waiting at
        "confirm seams"; the job goes on to planning with what was confirmed."""
        if req.get("job") is None:
            raise ControlError("confirm needs a job number")
        job = self.store.job(int(req["job"]))
        if job.state != "paused" or not job.reason.startswith((CONFIRM_FABRIC, CONFIRM_SEAMS)):
            raise ControlError(f"job {job.id} is {job.state}, not waiting at "
                               f"'{CONFIRM_FABRIC}' or '{CONFIRM_SEAMS}'")
        if job.reason.startswith(CONFIRM_SEAMS):
            try:
                said = confirm_seams(self.work_dir / f"job-{job.id}", req.get("seams"))
            except (OSError, ValueError) as exc:
                raise ControlError(str(exc)) from None
            self.store.transition(job.id, "planning", said)
            self._wake.set()
            return {"job": job.id, "message": f"{said}; planning"}
        path = self.work_dir / f"job-{job.id}" / "fabric.json"
        try:
            doc = confirm_fabric(json.loads(path.read_text()), req.get("group"))
        except (OSError, ValueError) as exc:
            raise ControlError(f"{path}: {exc}") from None
        path.write_text(json.dumps(doc, indent=2))
        self.store.set_plan(job.id, {"fabric": str(path)})
        self.store.transition(job.id, "planning", f"fabric confirmed as {doc['group']}")
        self._wake.set()
        warning = (doc.get("distortion") or {}).get("warning")
        return {"job": job.id, "group": doc["group"],
                "message": f"fabric confirmed as {doc['group']}; planning"
                           + (f" (warning: {warning})" if warning else "")}

    def cmd_plan(self, req: dict[str, Any]) -> dict[str, Any]:
        """The files a job's planning wrote (for `station preview`); read-only."""
        if req.get("job") is None:
            raise ControlError("plan needs a job number")
        job = self.store.job(int(req["job"]))
        return {"job": job.id, "state": job.state, "plan": job.plan}

    def cmd_log(self, req: dict[str, Any]) -> dict[str, Any]:
        job_id = req.get("job")
        events = self.store.events(None if job_id is None else int(job_id),
                                   after=int(req.get("after", 0)))
        return {"events": events[-int(req.get("limit", 200)):]}

    def _target(self, req: dict[str, Any]) -> JobControl:
        running = self.running
        job_id = req.get("job")
        if running is None or (job_id is not None and int(job_id) != running.job_id):
            raise ControlError("that job is not running" if job_id is not None
                               else "no job is running")
        return running

    def _summary(self, job: Job) -> dict[str, Any]:
        out = self.store.summary(job)
        self._memory[job.id] = dict(out)
        return self._with_progress(out)


def wait_until(predicate, timeout: float, interval: float = 0.05) -> bool:
    """Poll ``predicate`` until true or ``timeout`` seconds pass (for tests and tools)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(interval)
    return bool(predicate())
