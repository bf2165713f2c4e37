"""The console's answers while the job store is away: status, jobs, pause and abort.

The daemon remembers every job summary the console last read (`Daemon._summary`); while
the store does not answer, `Daemon.handle` calls the ``memory_<cmd>`` method here instead
of ``cmd_<cmd>``. A pause given meanwhile holds the machine at once and is recorded when
the store is back; an abort only raises the running job's flag, as it always does.
"""

from __future__ import annotations

from typing import Any

from station.control import ControlError


class AnswersFromMemory:
    """Mixed into `station.daemon.Daemon` (its ``running``, ``_memory``, ``_owed_pause``
    and ``_target``)."""

    running: Any
    _memory: dict[int, dict[str, Any]]
    _owed_pause: int | None

    def _target(self, req: dict[str, Any]) -> Any:
        raise NotImplementedError  # the daemon's: the running job's JobControl

    def memory_jobs(self, _req: dict[str, Any]) -> dict[str, Any]:
        return {"jobs": [self._with_progress(dict(j)) for _, j in sorted(self._memory.items())]}

    def memory_status(self, req: dict[str, Any]) -> dict[str, Any]:
        running = self.running
        job_id = req.get("job")
        if job_id is None:
            job_id = running.job_id if running else max(self._memory, default=None)
        if job_id is None:
            return {"job": None}
        known = self._memory.get(int(job_id))
        if known is None and running is not None and int(job_id) == running.job_id:
            known = {"id": running.job_id, "state": "unknown while the job store is away"}
        if known is None:
            raise ControlError(f"the job store is unreachable and job {job_id} is not in "
                               "memory")
        return {"job": self._with_progress(dict(known))}

    def memory_pause(self, req: dict[str, Any]) -> dict[str, Any]:
        control = self._target(req)
        control.pause.set()
        control.progress.pop("held_for_store", None)  # the operator's now: stays paused
        self._owed_pause = control.job_id
        return {"job": control.job_id, "message": "paused (feed hold); recorded in the job "
                "store when it is back"}

    def memory_abort(self, req: dict[str, Any]) -> dict[str, Any]:
        running = self.running
        job_id = req.get("job")
        if running is None or (job_id is not None and int(job_id) != running.job_id):
            raise ControlError("the job store is unreachable: only the running job can be "
                               "aborted meanwhile")
        running.abort.set()
        return {"job": running.job_id, "message": "aborting (safe stop)"}

    def _with_progress(self, summary: dict[str, Any]) -> dict[str, Any]:
        running = self.running
        if running is not None and running.job_id == summary.get("id"):
            summary["progress"] = dict(running.progress)
        return summary
