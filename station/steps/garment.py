"""Step 2 of a job: the garment as it will be cut, loaded once.

The submitted pattern in mm, its left/right pairs (found, or as the job declares them),
made one pattern each when the job asks (``symmetrise``), with the job's grain lines and
bias pieces. The console commands call the same functions with their own pairs.

A CAD pattern (DXF) carries no seams: a job with an unsure one waits at "confirm seams"
(`station.steps.dxfseams`), as a job waits at "confirm fabric" for its print.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

# the module, not its loader: tests count the loads (tests/station/job_io.py)
import solver.garment as garment_files
from solver.garment import Garment, save_obj
from solver.garment.symmetrise import Symmetrised, symmetrise
from solver.garment.symmetry import MirrorPair, mirror_pairs, pairs_from_dict
from station.config import Config
from station.jobstore import Job
from station.render import garment_credit
from station.steps.dxfseams import dxf_job_garment

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
