"""Step 1 of a job: the print on the table, as `Captured` hands it to planning.

The operator's FABRIC.json when the job names one; otherwise a photograph from the
station's camera (whatever ``open_camera`` the caller gave: the daemon's caller picks the
real camera, a simulation entry point the synthetic one), rectified to the fabric's own
millimetres and read by `vision`. The FABRIC.json, the photo and camera.json are written
into the job's folder for the operator and for a job planned by another process
(`Captured.read`); inside this process the objects go on.
"""

from __future__ import annotations

import json
import logging
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from solver.jsonfile import read_json
from solver.wallpaper import Wallpaper
from station.config import Config
from station.daemon import CONFIRM_FABRIC, JobControl, JobInterrupted
from station.jobstore import Job
from vision.calibration import Calibration
from vision.camera import Camera
from vision.camera import open_camera as open_video_camera
from vision.rectify import rectify

log = logging.getLogger("station.capture")

#: builds the station's camera from its configuration (the daemon's caller chooses it)
CameraOpener = Callable[[Config], Camera]
#: (frame, rectified fabric area, mm per pixel, the simulated camera's truth or None)
Photo = tuple[np.ndarray, np.ndarray, float, Any]


@dataclass
class Captured:
    """What capture hands to planning: the FABRIC.json document (written at ``path``),
    its print as an object when capture made one, and the rectified photo, if taken."""

    path: str
    fabric: dict[str, Any]
    wallpaper: Wallpaper | None = None
    photo: np.ndarray | None = None
    mm_per_px: float = 1.0

    def record(self) -> dict[str, str]:
        """What the job store keeps of it: where its FABRIC.json is."""
        return {"fabric": self.path}

    @classmethod
    def read(cls, path: str | Path, workdir: Path) -> Captured:
        """The capture of a job planned in another process than the one that captured it
        (or after the operator confirmed its print): from the job's files."""
        camera = workdir / "camera.json"
        photo = cv2.imread(str(workdir / "rectified.png")) if camera.is_file() else None
        mm_per_px = float(read_json(camera)["mm_per_px"]) if photo is not None else 1.0
        return cls(str(path), read_json(path), None, photo, mm_per_px)


def real_camera(config: Config) -> Camera:
    """The configured camera (an OpenCV source). A simulated one comes only from a
    simulation entry point (`station serve --simulate`, `station demo`)."""
    c = config["camera"]
    if c["source"] == "simulated":
        raise ValueError("camera.source = \"simulated\" is a dry run: start the station "
                         "with `station serve --simulate`")
    return open_video_camera(c["source"], average=c["frames"])


def capture_fabric(job: Job, workdir: Path, config: Config, take_photo: Callable[[], Photo],
                   control: JobControl) -> Captured:
    """FABRIC.json of the job: the operator's file, or detected from a photograph
    (``take_photo``: `photograph` with the station's camera)."""
    target = workdir / "fabric.json"
    if job.fabric is not None:
        shutil.copyfile(job.fabric, target)
        return Captured(str(target), read_json(job.fabric))
    control.start_step("photographing")
    frame, rectified, mm_per_px, truth = take_photo()
    cv2.imwrite(str(workdir / "frame.png"), frame)
    cv2.imwrite(str(workdir / "rectified.png"), rectified)
    camera = {"mm_per_px": mm_per_px, "frame": str(workdir / "frame.png"),
              "rectified": str(workdir / "rectified.png"),
              "truth": (truth.wallpaper.to_dict()
                        if truth is not None and truth.wallpaper is not None else None)}
    control.checkpoint()
    control.start_step("detecting")
    fabric, wallpaper = _detect(rectified, mm_per_px, truth, config, workdir, camera)
    (workdir / "camera.json").write_text(json.dumps(camera, indent=2, default=float))
    target.write_text(json.dumps(fabric, indent=2, default=float))
    below = float(config["camera"]["confirm_below"])
    if (fabric.get("source") == "detected" and fabric["group"] is not None
            and fabric["confidence"] < below):
        raise JobInterrupted("paused", f"{CONFIRM_FABRIC}: {fabric['group']} at "
                             f"confidence {fabric['confidence']:.2f} (below {below:g}); "
                             f"see detection.png, then `station confirm {job.id} "
                             "[--group G]`")
    return Captured(str(target), fabric, wallpaper, rectified, float(mm_per_px))


def _detect(rectified: np.ndarray, mm_per_px: float, truth: Any, config: Config,
            workdir: Path, camera: dict[str, Any]) -> tuple[dict[str, Any], Wallpaper | None]:
    """(FABRIC.json document, its print) read from the photo; ``camera`` gains the
    detection's summary. Without `vision.pipeline` only a simulated camera's known
    print can stand in, and the log says so loudly."""
    try:
        # Here, not at the top: vision.pipeline is the one part of vision a station may
        # lack (tests remove it); the known print of a simulated camera then stands in.
        from vision.pipeline import detect_fabric, draw_overlay
    except ImportError as exc:
        if truth is None or truth.wallpaper is None:
            raise
        log.error("VISION UNAVAILABLE (%s): using the simulated camera's known print", exc)
        fabric = {**truth.wallpaper.to_dict(), "source": "simulator truth: vision unavailable"}
        return fabric, _plain(truth.wallpaper)
    detection = detect_fabric(rectified, mm_per_px=mm_per_px,
                              min_repeat_mm=config["camera"]["min_repeat_mm"])
    cv2.imwrite(str(workdir / "detection.png"), draw_overlay(rectified, detection))
    fabric = {**detection.fabric_json(), "source": "detected"}
    camera["detection"] = detection.summary()
    if fabric["group"] is None and fabric.get("kind") not in ("plain", "stripes"):
        raise ValueError("no periodic print found on the table "
                         f"({detection.lattice.message or detection.lattice.kind}): "
                         "give the job a FABRIC.json")
    wallpaper = detection.wallpaper
    return fabric, None if wallpaper is None else _plain(wallpaper)


def _plain(wallpaper: Wallpaper) -> Wallpaper:
    """The print as FABRIC.json describes it (lattice, group, origin; the station's
    tolerance, no motif image), so the plan is the same as one made from the file."""
    return Wallpaper(wallpaper.group, wallpaper.w1, wallpaper.w2, wallpaper.origin)


def photograph(config: Config, open_camera: CameraOpener) -> Photo:
    """(frame, rectified fabric area, mm per pixel, truth or None).

    The rectified image covers the usable fabric (nest length x width) from the
    fabric's corner on the table, so its pixel (c, r) is fabric point (c, r) * mm/px:
    what is detected there is in the fabric's own millimetres, as nesting wants.
    """
    c, n = config["camera"], config["nest"]
    ox, oy = (float(v) for v in config["machine"]["fabric_origin"])
    region = (ox, oy, ox + n["length_mm"], oy + n["width_mm"])
    with open_camera(config) as camera:
        frame = camera.read()
        truth = getattr(camera, "truth", None)  # a simulated camera knows its print
    if c["calibration"]:
        rectified, _region, mm_per_px = rectify(
            frame, Calibration.load(config.resolve(c["calibration"])), region=region)
    elif truth is not None:
        mm_per_px = float(truth.mm_per_px)
        rectified = truth.rectify(frame, region, mm_per_px)
    else:
        raise ValueError("camera.calibration is empty: calibrate the camera "
                         "(station calibrate) or use the simulated camera")
    if truth is not None and (ox, oy) != (0.0, 0.0):
        truth = None  # its print is in table mm; the station speaks fabric mm
    return frame, rectified, mm_per_px, truth
