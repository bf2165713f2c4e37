"""Step 2 of a job: the garment as it will be cut, loaded once.

The submitted pattern in mm, its left/right pairs (found, or as the job declares them),
made one pattern each when the job asks (``symmetrise``), with the job's grain lines and
bias pieces. The console commands call the same functions with their own pairs.

A CAD pattern (DXF) carries no seams: they are inferred, drawn (seams.png) and listed
(seams.json), and a job with an unsure seam waits at "confirm seams" until the operator
confirms them or sends a correction (`station.seams_confirm`), as a job waits at "confirm
fabric" for its print.
"""

from __future__ import annotations

import json
import logging
import shutil
import warnings
from pathlib import Path
from typing import Any

# the module, not its loader: tests count the loads (tests/station/job_io.py)
import solver.garment as garment_files
from solver.garment import Garment, save_obj
from solver.garment.symmetrise import Symmetrised, symmetrise
from solver.garment.symmetry import MirrorPair, mirror_pairs, pairs_from_dict
from station.allowance import rules_for_job
from station.config import Config
from station.daemon import CONFIRM_SEAMS, JobInterrupted
from station.jobstore import Job
from station.render import garment_credit
from station.seams_confirm import SEAMS_CONFIRMED, SEAMS_FOUND, SEAMS_PICTURE
from station.seams_view import DxfInspection, draw_seams, read_dxf, seams_document

log = logging.getLogger("station.garment")

Pairs = tuple[list[tuple[int, int]], list[tuple[int, int]]]  # (declared, vetoed)


def found_pairs(garment: Garment, declared: Pairs = ([], [])) -> list[MirrorPair]:
    """The garment's left/right pairs: those found, with ``declared`` (declared, vetoed)."""
    return mirror_pairs(garment, declared=declared[0], vetoed=declared[1])


def job_pairs(garment: Garment, options: dict[str, Any]) -> list[MirrorPair]:
    """The pairs of a job: found, with its ``pairs`` option heard."""
    return found_pairs(garment, pairs_from_dict(options.get("pairs", {}), garment,
                                                "job option pairs"))


def symmetrised(garment: Garment, pairs: list[MirrorPair]) -> tuple[Garment, Symmetrised]:
    """The garment with each pair made one pattern cut twice, and the record of it."""
    sym = symmetrise(garment, pairs)
    return sym.garment, sym


def symmetrise_job(garment: Garment, options: dict[str, Any]
                   ) -> tuple[Garment, Symmetrised | None]:
    """The job's garment with its left/right pairs made one pattern each when the job
    asks (``symmetrise``), and the record of it (or None)."""
    if not options.get("symmetrise", False):
        return garment, None
    return symmetrised(garment, job_pairs(garment, options))


def grained(garment: Garment, config: Config, options: dict[str, Any]) -> Garment:
    """``garment`` with the job's grain lines and bias pieces and the station's up axis."""
    up = config["align"]["up"]
    return garment.with_grain(lines=options.get("grain_lines"), bias=options.get("bias", ()),
                              up=None if up == "auto" else up)


def job_garment(job: Job, workdir: Path, config: Config
                ) -> tuple[Garment, Path, Symmetrised | None]:
    """(garment, path of the job's copy, symmetrise record or None): the submitted
    pattern loaded once, in mm (a DXF's seams confirmed: `dxf_job_garment`), symmetrised
    if the job asks, and copied beside the job's files (with its licence note) for the
    operator and for a job resumed elsewhere."""
    if Path(job.garment).suffix.lower() == ".dxf":
        garment = dxf_job_garment(job, workdir, config)
    else:
        garment = garment_files.load_garment(job.garment, units=job.options.get("units"),
                                             size=job.options.get("size"))
    garment, record = symmetrise_job(garment, job.options)
    garment_path = workdir / "garment.obj"
    save_obj(garment, garment_path)
    keep_licence_note(Path(job.garment), workdir)
    return garment, garment_path, record


def dxf_job_garment(job: Job, workdir: Path, config: Config) -> Garment:
    """A job's DXF pattern with its seams as the operator confirmed them, else inferred;
    every seam drawn numbered (seams.png) and listed as a ``--seams`` file (seams.json).
    Unsure seams (under ``seams.confirm_below``) not yet confirmed (nor sent with the
    job: option ``seams``) hold the job at "confirm seams"; a sew line the file lacks is
    its cut line inset by the job's seam allowance (station.toml's unless it gives one)."""
    confirmed = workdir / SEAMS_CONFIRMED
    if job.options.get("seams") is not None and not confirmed.is_file():
        confirmed.write_text(json.dumps(job.options["seams"]))  # sent with the job
    below = float(config["seams"]["confirm_below"])
    again = f"see {SEAMS_PICTURE} and {SEAMS_FOUND}, then `station confirm {job.id}` " \
            "[--seams S.json]"
    try:
        found = _read_job_dxf(job, config, confirmed if confirmed.is_file() else None)
    except ValueError as exc:
        if not confirmed.is_file() or str(confirmed) not in str(exc):
            raise
        confirmed.unlink()  # the operator's file does not fit the pattern: ask again
        raise JobInterrupted("paused", f"{CONFIRM_SEAMS}: the seams sent were refused "
                             f"({exc}); {again}") from None
    draw_seams(found.pieces, found.seams, workdir / SEAMS_PICTURE, unsure_below=below,
               folds=found.folds())
    (workdir / SEAMS_FOUND).write_text(json.dumps(seams_document(found), indent=2))
    unsure = found.unsure(below)
    if unsure and not confirmed.is_file():
        raise JobInterrupted("paused", f"{CONFIRM_SEAMS}: seam(s) "
                             f"{', '.join(map(str, unsure))} of {len(found.seams)} under "
                             f"confidence {below:g}; {again}")
    return found.garment


def _read_job_dxf(job: Job, config: Config, seams: Path | None) -> DxfInspection:
    """The job's DXF read with its options and seam allowance; the reader's warnings
    (a piece too narrow for the allowance, say) go to the log."""
    given = job.options.get("seam_allowance") is not None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        found = read_dxf(job.garment, size=job.options.get("size"),
                         units=job.options.get("units"),
                         allowance_mm=rules_for_job(config, job.options).seam_mm,
                         allowance_from="the job's seam_allowance" if given
                         else "station.toml allowance.seam_mm", seams=seams)
    for w in caught:
        log.warning("job %d: %s", job.id, w.message)
    return found


def keep_licence_note(garment: Path, workdir: Path) -> None:
    """Copy the garment library's README beside the job's copy of the pattern, so every
    picture drawn from the copy still carries the acknowledgement its licence asks for."""
    if garment_credit(garment) is None:
        return
    for name in ("README.txt", "BERKELEY-README.txt"):
        note = garment.resolve().parent / name
        if note.is_file():
            shutil.copyfile(note, workdir / "BERKELEY-README.txt")
            return
