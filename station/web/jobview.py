"""A job as the console page draws it, from the files its planning wrote.

Only files of the job's own folder under the work folder are ever read or served, by
names from a fixed list: a request cannot name a path. The page draws the marker itself
(an SVG over :func:`station.render.cloth_image`, the photographed fabric) so that each
piece can change colour as the machine cuts it; the pictures the pipeline drew
(detection, a CAD pattern's seams, seam fit, toolpath) are served as they are.
"""

from __future__ import annotations

import json
import threading
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from solver.nest.layout import Layout
from station.render import cloth_image
from station.seams_confirm import SEAMS_FOUND

#: the pictures a job's folder may hold, in the order the page offers them
PICTURES = ("rectified.png", "detection.png", "seams.png", "frame.png", "marker.png",
            "fit-reshaped.png", "fit-aligned.png", "fit-before.png", "toolpath.png")
CLOTH_WIDTH_PX = 1400  # the marker's background, drawn once per job and kept
FABRIC_KEYS = ("group", "confidence", "w1", "w2", "origin", "source", "kind", "units")


class JobFiles:
    """Reads one station's job folders: ``work_dir/job-N``."""

    def __init__(self, work_dir: Path) -> None:
        self.work_dir = work_dir.resolve()
        self._cloth: dict[tuple[int, float], bytes] = {}
        self._lock = threading.Lock()

    def folder(self, job_id: int) -> Path:
        return self.work_dir / f"job-{int(job_id)}"

    def file(self, job_id: int, name: str) -> Path | None:
        """A listed picture of the job, None if not listed or not there; a link that leads
        out of the work folder is refused like a missing file."""
        if name not in PICTURES:
            return None
        path = (self.folder(job_id) / name).resolve()
        if not path.is_relative_to(self.work_dir) or not path.is_file():
            return None
        return path

    def _json(self, job_id: int, name: str) -> dict[str, Any] | None:
        path = (self.folder(job_id) / name).resolve()
        if not path.is_relative_to(self.work_dir) or not path.is_file():
            return None
        try:
            doc = json.loads(path.read_text())
        except (OSError, ValueError):
            return None
        return doc if isinstance(doc, dict) else None

    def detail(self, job_id: int) -> dict[str, Any]:
        """What the page needs to draw the job: the print, the camera's scale, the marker's
        pieces (fabric mm), which pictures exist, and a CAD pattern's seams as found."""
        fabric = self._json(job_id, "fabric.json") or {}
        camera = self._json(job_id, "camera.json") or {}
        layout = self._json(job_id, "layout.json")
        return {
            "fabric": {k: fabric[k] for k in FABRIC_KEYS if k in fabric} or None,
            "photo_mm_per_px": camera.get("mm_per_px") if self.file(job_id, "rectified.png")
            else None,
            "marker": None if layout is None else marker_outline(layout),
            "pictures": [n for n in PICTURES if self.file(job_id, n) is not None],
            "seams": self._json(job_id, SEAMS_FOUND),  # a CAD pattern's, as inferred
        }

    def cloth_png(self, job_id: int) -> bytes | None:
        """The fabric under the job's marker (PNG): its photograph, or its lattice on plain
        cloth when it was given as a FABRIC.json; None before the job is nested."""
        layout_path = self.folder(job_id) / "layout.json"
        layout = self._json(job_id, "layout.json")
        if layout is None:
            return None
        key = (job_id, layout_path.stat().st_mtime)
        with self._lock:
            if key in self._cloth:
                return self._cloth[key]
        photo_path = self.file(job_id, "rectified.png")
        photo = None if photo_path is None else cv2.imread(str(photo_path))
        mm_per_px = float((self._json(job_id, "camera.json") or {}).get("mm_per_px", 1.0))
        image = cloth_image(Layout.from_dict(layout), CLOTH_WIDTH_PX, photo=photo,
                            photo_mm_per_px=mm_per_px)
        ok, png = cv2.imencode(".png", image)
        if not ok:
            return None
        with self._lock:
            self._cloth = {k: v for k, v in self._cloth.items() if k[0] != job_id}
            self._cloth[key] = png.tobytes()
            while len(self._cloth) > 8:
                self._cloth.pop(next(iter(self._cloth)))
        return png.tobytes()


def marker_outline(layout: dict[str, Any]) -> dict[str, Any]:
    """The marker's pieces for the page: name, cut line (0.1 mm) and grain arrow."""

    def mm(points: Any) -> list[list[float]]:
        return np.round(np.asarray(points, float).reshape(-1, 2), 1).tolist()

    return {"length": float(layout["length"]), "width": float(layout["width"]),
            "pieces": [{"id": p["id"], "name": p.get("name", p["id"]),
                        "outline": mm(p["outline"]),
                        "grainline": None if p.get("grainline") is None else mm(p["grainline"])}
                       for p in layout.get("pieces", [])]}
