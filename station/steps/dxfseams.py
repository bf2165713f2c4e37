"""A CAD pattern's seams as the operator confirmed them, before any work is done on it.

A DXF carries no seams: they are inferred (:mod:`solver.seams`), drawn numbered
(seams.png) and listed as a ``--seams`` file (seams.json). A pattern with an unsure seam
(under ``seams.confirm_below``) holds its job at "confirm seams" until the operator
confirms them as found or sends a correction (`station.seams_confirm`), which becomes the
job's seams-confirmed.json; seams sent with the job are the operator's word from the
start.

An order may hold several DXF styles and sizes, each its own pattern with its own seams.
They are checked one after the other, before any garment is aligned: the job waits at the
first unsure one, with its picture and list in the job's seams.png and seams.json (what
`station confirm` and the console show), named in the reason. What the operator confirms
then belongs to that style and size and is kept under its own name, so the next one can
be asked about in turn and none is asked twice.
"""

from __future__ import annotations

import json
import logging
import shutil
import warnings
from collections.abc import Callable
from pathlib import Path

from solver.garment import Garment
from station.allowance import rules_for_job
from station.config import Config
from station.daemon import CONFIRM_SEAMS, JobInterrupted
from station.jobstore import Job
from station.order import Order, OrderGarment
from station.seams_confirm import SEAMS_CONFIRMED, SEAMS_FOUND, SEAMS_PICTURE
from station.seams_view import DxfInspection, draw_seams, read_dxf, seams_document

__all__ = ["StyleKey", "dxf_job_garment", "order_dxf_garments"]

log = logging.getLogger("station.garment")

StyleKey = tuple[Path, str | None, str | None]  # (pattern, size, units): one pattern to sew
ReadDxf = Callable[[Path | None], DxfInspection]  # the pattern read with these seams


def dxf_job_garment(job: Job, workdir: Path, config: Config) -> Garment:
    """A job's DXF pattern with its seams as the operator confirmed them, else inferred;
    every seam drawn numbered (seams.png) and listed as a ``--seams`` file (seams.json).
    Unsure seams not yet confirmed (nor sent with the job: option ``seams``) hold the
    job at "confirm seams"; a sew line the file lacks is its cut line inset by the job's
    seam allowance (station.toml's unless it gives one)."""
    confirmed = workdir / SEAMS_CONFIRMED
    if job.options.get("seams") is not None and not confirmed.is_file():
        confirmed.write_text(json.dumps(job.options["seams"]))  # sent with the job

    def read(seams: Path | None) -> DxfInspection:
        return _read_job_dxf(job, config, Path(job.garment), seams,
                             size=job.options.get("size"), units=job.options.get("units"))

    found = _confirmed(read, job, workdir, confirmed, config, what="")
    _show(found, workdir, config)
    return found.garment


def order_dxf_garments(job: Job, order: Order, workdir: Path, config: Config
                       ) -> dict[StyleKey, Garment]:
    """Every DXF style and size of ``order`` with its seams confirmed, checked in the
    order's order before any garment is aligned; the job waits at "confirm seams" at
    the first unsure one. Each one's seams are drawn and listed as
    ``seams-STYLE-SIZE.png`` and ``.json``."""
    out: dict[StyleKey, Garment] = {}
    below = float(config["seams"]["confirm_below"])
    for item in order.garments:
        key = (item.pattern, item.size, item.units)
        if key in out or item.pattern.suffix.lower() != ".dxf":
            continue
        tag = "-".join([item.style, *([item.size] if item.size else [])])
        own = workdir / f"seams-confirmed-{tag}.json"

        def read(seams: Path | None, item: OrderGarment = item) -> DxfInspection:
            return _read_job_dxf(job, config, item.pattern, seams, size=item.size,
                                 units=item.units)

        asked = workdir / SEAMS_CONFIRMED  # the operator's answer to the question asked
        if not own.is_file() and asked.is_file() and read(None).unsure(below):
            asked.replace(own)  # it answered this style: the first unsure one unanswered
        what = f"{item.pattern.name}" + (f" size {item.size}" if item.size else "") + ": "
        found = _confirmed(read, job, workdir, own, config, what=what)
        _show(found, workdir, config, tag)
        out[key] = found.garment
    return out


def _confirmed(read: ReadDxf, job: Job, workdir: Path, confirmed: Path, config: Config, *,
               what: str) -> DxfInspection:
    """The pattern read with the operator's ``confirmed`` seams when there are some; a job
    waits at "confirm seams" (its picture and list written for the operator) when seams
    are unsure and unconfirmed, or when the operator's file does not fit the pattern."""
    below = float(config["seams"]["confirm_below"])
    again = f"see {SEAMS_PICTURE} and {SEAMS_FOUND}, then `station confirm {job.id}` " \
            "[--seams S.json]"
    try:
        found = read(confirmed if confirmed.is_file() else None)
    except ValueError as exc:
        if not confirmed.is_file() or str(confirmed) not in str(exc):
            raise
        confirmed.unlink()  # the operator's file does not fit the pattern: ask again
        _show(read(None), workdir, config)
        raise JobInterrupted("paused", f"{CONFIRM_SEAMS}: {what}the seams sent were refused "
                             f"({exc}); {again}") from None
    unsure = found.unsure(below)
    if unsure and not confirmed.is_file():
        _show(found, workdir, config)
        raise JobInterrupted("paused", f"{CONFIRM_SEAMS}: {what}seam(s) "
                             f"{', '.join(map(str, unsure))} of {len(found.seams)} under "
                             f"confidence {below:g}; {again}")
    return found


def _show(found: DxfInspection, workdir: Path, config: Config, tag: str | None = None) -> None:
    """Draw and list ``found``'s seams: the job's seams.png and seams.json, or, for one
    style of an order (``tag``), its own pair of files."""
    suffix = "" if tag is None else f"-{tag}"
    picture = workdir / SEAMS_PICTURE.replace(".png", f"{suffix}.png")
    draw_seams(found.pieces, found.seams, picture,
               unsure_below=float(config["seams"]["confirm_below"]), folds=found.folds())
    listed = workdir / SEAMS_FOUND.replace(".json", f"{suffix}.json")
    listed.write_text(json.dumps(seams_document(found), indent=2))
    if tag is None:
        return
    if not (workdir / SEAMS_PICTURE).is_file():  # the console's seams picture: the first
        shutil.copyfile(picture, workdir / SEAMS_PICTURE)


def _read_job_dxf(job: Job, config: Config, path: Path, seams: Path | None, *,
                  size: str | None, units: str | None) -> DxfInspection:
    """A DXF of the job read with its seam allowance; the reader's warnings (a piece too
    narrow for the allowance, say) go to the log."""
    given = job.options.get("seam_allowance") is not None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        found = read_dxf(path, size=size, units=units,
                         allowance_mm=rules_for_job(config, job.options).seam_mm,
                         allowance_from="the job's seam_allowance" if given
                         else "station.toml allowance.seam_mm", seams=seams)
    for w in caught:
        log.warning("job %d: %s", job.id, w.message)
    return found
