"""One call from a photo to the fabric description: lattice, group, origin, distortion.

``detect_fabric`` works on an image whose pixels are square table millimetres (a
rectified frame, or a flat scan with a known pixel size); ``offset`` is the machine
position of pixel (0, 0)'s centre, so the answer is in machine millimetres.
"""

from __future__ import annotations

import time

import cv2
import numpy as np

from solver.wallpaper import GROUPS
from vision.basis import nested
from vision.classify import Classification, classify, moved_origin
from vision.distortion import Distortion, angle_between, local_lattices, measure_distortion
from vision.evidence import missing_evidence, without_lattice
from vision.fabric import STRETCH_TOL, FabricDetection, confirm_fabric
from vision.lattice import LatticeResult, detect_lattice, yarn_repeat
from vision.overlay import draw_overlay
from vision.perspective import View, fit_view
from vision.prepare import WORK_SIDE, prepare_image
from vision.repeat import true_lattice

# FabricDetection, confirm_fabric (vision.fabric) and draw_overlay (vision.overlay) are read
# here by the station and the tests: one import for the whole of detection.
__all__ = ["CONFIRM_BELOW", "FabricDetection", "above_the_yarn", "confirm_fabric",
           "detect_fabric", "draw_overlay"]

#: Below this confidence a detected group goes to the operator ("confirm fabric").
CONFIRM_BELOW = 0.9

#: Most confidence in a group read on the frame's central part only, where the whole
#: frame shows no lattice (other cloth, a pocket or drape at the edges): the operator
#: confirms that the print covers the fabric.
PART_OF_FRAME_CONFIDENCE = 0.5

#: Working pixels a repeat needs for its detail to be read; a finer one is read again at
#: full resolution (:func:`_closer_look`). The classifier compares up to 12 harmonics
#: per repeat; at 7 px a basketweave keeps its second direction 0.04 deep in the
#: autocorrelation (it reads as stripes), at 14 px 0.5.
RESOLVE_PX = 16.0

#: Repeats (of the longest step the working image saw) across the centre read closer,
#: in 512-1024 px: enough for the per-repeat checks, while the whole 1024 px centre put
#: fine 4000 x 3000 frames over 1.5 s (BENCHMARKS.md).
CLOSER_REPEATS = 16

#: Side (input px) of the frame's centre given a first look at full resolution when the
#: working image shows no repeat too fine for it: a repeat finer still may be lost there.
PEEK_SIDE = 512

#: Gaussian smoothing, in units of the yarn's repeat (:func:`yarn_repeat`), that takes
#: the yarn out of the image before the print is read: it leaves exp(-9 pi^2 / 8) ~ 1e-5
#: of the weave's fundamental, and the band edges' thread steps with it, and keeps print
#: detail a few threads wide.
YARN_SMOOTHING = 0.75

#: Share of the image's contrast that must remain above the yarn for the cloth to
#: carry a print there; less, and its only structure is the yarn (plain cloth keeps
#: 3-11 % after the smoothing, woven checks 37-78 %: ``bench.vision`` sources plain
#: and woven).
PRINT_ABOVE_YARN = 0.2

_IDEAL_ANGLE = {"rectangular": 90.0, "square": 90.0, "hexagonal": 120.0}


def _ideal_angle(group: str, lat: LatticeResult) -> float | None:
    """The w1-w2 angle the print should have. A check spread skewed by a few degrees
    loses its mirrors and reads as an oblique print (p1, p2); its skew is still
    measured against the right angle it is close to."""
    ideal = _IDEAL_ANGLE.get(GROUPS[group].lattice)
    if ideal is None and GROUPS[group].lattice == "oblique":
        if abs(angle_between(lat.w1, lat.w2) - 90.0) < 5.0:
            ideal = 90.0
    return ideal


def detect_fabric(image: np.ndarray, *, mm_per_px: float, offset=(0.0, 0.0),
                  skew_tol_deg: float = 1.0, bow_tol_mm: float = 3.0,
                  distortion: bool = True, min_repeat_mm: float = 3.0,
                  stretch_tol: float = STRETCH_TOL, above_yarn: bool = True,
                  true_repeat: bool = True, closer_look: bool = True) -> FabricDetection:
    """Lattice, group with origin, and distortion of the print in ``image``; a repeat
    finer than ``min_repeat_mm`` is the weave (``kind: "plain"``). Skew, bow and a
    stretch of the lattice off its group's (``stretch_tol``, relative) beyond their
    tolerances are named in ``distortion.warning``. Perspective left in the image
    (:mod:`vision.perspective`) is undone before the group is read, and reported; yarn
    the image resolves (:func:`vision.lattice.yarn_repeat`) is smoothed away first
    (``above_yarn``), and a lattice whose step is not a repeat of the print is halved
    (:func:`vision.repeat.true_lattice`, ``true_repeat``); both off only to measure what
    they change. A repeat too fine for the shrunk working image is read at full
    resolution on the frame's centre (``closer_look``, :func:`_closer_look`); a frame
    that shows a print over its centre only is read there. An answer read on a part
    that the whole frame does not bear out goes to the operator."""
    t0 = time.perf_counter()
    flat, scale, yarn_mm, sigma, read, lat = _first_reading(image, mm_per_px, min_repeat_mm,
                                                            above_yarn)
    if closer_look and scale < 1.0:
        # A repeat finer than the working image resolves: the centre read at full scale.
        closer = _closer_look(image, lat, scale, mm_per_px, offset=offset,
                              skew_tol_deg=skew_tol_deg, bow_tol_mm=bow_tol_mm,
                              distortion=distortion, min_repeat_mm=min_repeat_mm,
                              stretch_tol=stretch_tol, above_yarn=above_yarn,
                              true_repeat=true_repeat)
        if closer is not None:
            closer.seconds = time.perf_counter() - t0
            return closer
    if true_repeat:
        lat = true_lattice(image, lat, prepared=(flat, scale), smooth_px=sigma, read=read)
    lat, cls, local, view = _read_print(image, read, lat, scale, mm_per_px, min_repeat_mm,
                                        true_repeat, distortion)
    candidate, why = None, missing_evidence(lat, cls)
    if why:
        candidate, (lat, cls) = cls.wallpaper, without_lattice(lat, why)
    dist = Distortion()
    if distortion and lat.found and cls.group is not None:
        dist = measure_distortion(image, lat, skew_tol_deg=skew_tol_deg,
                                  bow_tol_mm=bow_tol_mm,
                                  ideal_angle=_ideal_angle(cls.group, lat),
                                  prepared=(read, scale), local=local)
        _warn_of_strain_and_view(dist, cls, view, stretch_tol)
    return FabricDetection(lat, cls, dist, np.asarray(offset, float), float(mm_per_px),
                           time.perf_counter() - t0, yarn_mm, candidate)


def _read_print(image: np.ndarray, flat: np.ndarray, lat: LatticeResult, scale: float,
                mm_per_px: float, min_repeat_mm: float, true_repeat: bool, distortion: bool
                ) -> tuple[LatticeResult, Classification, tuple[np.ndarray, np.ndarray] | None,
                           View | None]:
    """Lattice and group of the print in the working image ``flat`` (the yarn taken
    away), whose whole-frame lattice is ``lat``; with the local lattices and the
    perspective they show (None where not measured or not used). With ``distortion``,
    a perspective is undone before the group is read, and where no one lattice holds
    over the whole frame (a steep view, or more than the cloth in the photo) the
    frame's central part is read, and the operator confirms that the print covers it."""
    local, view, cls = None, None, None
    seed, part = lat, None
    if distortion and lat.kind == "plain":
        seed, *part = _central_part(flat, scale, mm_per_px, min_repeat_mm)
    if distortion and seed.found:
        local = local_lattices(flat, seed.basis / mm_per_px * scale)
        view = fit_view(*local, flat.shape, scale)
    if view is not None:
        found = _decide_part(*view.rectify(flat), scale, mm_per_px, min_repeat_mm,
                             true_repeat, allowance=view.change)
        if found is not None:
            lat, cls = found
    elif part and seed.found:
        found = _decide_part(*part, scale, mm_per_px, min_repeat_mm, true_repeat)
        if found is not None:
            lat, cls = found
            # Read on a part only: whether the print covers the cloth, the operator says.
            _read_on_part(cls, f"the print repeats over the frame's central "
                               f"{100 * part[0].size / flat.size:.0f} % only")
    if cls is None:
        view, local = None, local if lat.found else None
        cls = classify(image, lat, flat=flat, scale=scale)
    return lat, cls, local, view


def _warn_of_strain_and_view(dist: Distortion, cls: Classification, view: View | None,
                             stretch_tol: float) -> None:
    """Name in ``dist.warning`` a stretch of the lattice off the group's beyond
    ``stretch_tol`` and a perspective undone, and record the perspective."""
    dist.perspective = None if view is None else view.to_dict()
    if cls.strain > stretch_tol:
        # The print was designed on the group's lattice; the cloth (or the camera)
        # stretches it: pieces cut now come out of the print by this much.
        fault = (f"stretched {100 * cls.strain:.1f} % off the {cls.group} lattice "
                 f"(tolerance {100 * stretch_tol:g} %)")
        dist.warning = (f"{dist.warning}; {fault}" if dist.warning
                        else f"fabric lies distorted: {fault} (straighten the cloth)")
    if view is not None:
        fault = (f"seen in perspective (the lattice changes {100 * view.change:.0f} % "
                 "across the view; the group was read on the rectified image)")
        dist.warning = (f"{dist.warning}; {fault}" if dist.warning
                        else f"fabric lies distorted: {fault}")


def _read_on_part(cls: Classification, why: str) -> None:
    """A group read on a part of the frame: whether the print covers the fabric, the
    operator confirms (confidence at most ``PART_OF_FRAME_CONFIDENCE``, and why)."""
    cls.confidence = min(cls.confidence, PART_OF_FRAME_CONFIDENCE)
    cls.message = "; ".join(filter(None, (cls.message,
                                          f"{why}: confirm that it covers the fabric")))


def _first_reading(image: np.ndarray, mm_per_px: float, min_repeat_mm: float,
                   above_yarn: bool) -> tuple[np.ndarray, float, float, float, np.ndarray,
                                              LatticeResult]:
    """The working image and its scale, the yarn's repeat (mm), the smoothing that takes
    it away (working px), the image read with it taken away, and the lattice found."""
    flat, scale = prepare_image(image)
    yarn_mm, sigma, read = (above_the_yarn(flat, scale, mm_per_px, min_repeat_mm)
                            if above_yarn else (np.nan, 1.0, flat))
    lat = detect_lattice(image, mm_per_px=mm_per_px, prepared=(flat, scale),
                         min_repeat_mm=min_repeat_mm, smooth_px=sigma)
    return flat, scale, yarn_mm, sigma, read, lat


def _steps(lat: LatticeResult) -> tuple[float, float]:
    """The shortest and the longest step (mm) of a repeat found: the stripes' period,
    or a lattice's two vectors; NaN without one."""
    if lat.kind == "stripes":
        return lat.period, lat.period
    if lat.found:
        n1, n2 = np.hypot(*lat.w1), np.hypot(*lat.w2)
        return float(min(n1, n2)), float(max(n1, n2))
    return float("nan"), float("nan")


def _unresolved(lat: LatticeResult, mm_per_px: float, scale: float) -> bool:
    """Whether a repeat was found whose shortest step spans fewer than ``RESOLVE_PX``
    pixels of a working image at ``scale``."""
    return bool(_steps(lat)[0] / mm_per_px * scale < RESOLVE_PX)


def _centre(image: np.ndarray, side: int) -> tuple[np.ndarray, np.ndarray]:
    """The central ``side`` x ``side`` pixels of ``image`` (less where it is smaller),
    and their top-left corner (x, y)."""
    h, w = image.shape[:2]
    ch, cw = min(h, side), min(w, side)
    y0, x0 = (h - ch) // 2, (w - cw) // 2
    return image[y0:y0 + ch, x0:x0 + cw], np.array([x0, y0], float)


def _closer_look(image: np.ndarray, seen: LatticeResult, scale: float, mm_per_px: float,
                 **options) -> FabricDetection | None:
    """The frame's centre (``CLOSER_REPEATS`` repeats across) read at full resolution,
    when the print's repeat spans fewer than ``RESOLVE_PX`` pixels of the working image
    (at ``scale``): there its detail is lost, and what is left can beat with the pixels
    into a wrong lattice, or leave a 2-D print one direction only (a basketweave's 7 px
    repeat under shading bands reads as stripes). The repeat is the one the working
    image showed (``seen``), or, when that is coarser or none, the one a first look at
    the central ``PEEK_SIDE`` px shows (a fine herringbone's twill step, lost in the
    shrink, leaves a coarse beat). None when neither is that fine, or when the closer
    look shows no lattice.

    The answer goes to the operator when it disagrees with the whole frame's (stripes,
    or a lattice that is not a multiple of the one read closer)."""
    found = seen
    if not _unresolved(seen, mm_per_px, scale):
        found = _first_reading(_centre(image, PEEK_SIDE)[0], mm_per_px,
                               options["min_repeat_mm"], options["above_yarn"])[-1]
        if not _unresolved(found, mm_per_px, scale):
            return None
    side = int(np.clip(CLOSER_REPEATS * _steps(found)[1] / mm_per_px, PEEK_SIDE, WORK_SIDE))
    crop, corner = _centre(image, side)
    det = detect_fabric(crop, mm_per_px=mm_per_px, closer_look=False, **options)
    if not det.lattice.found or det.classification.wallpaper is None:
        return None
    shift = corner * mm_per_px
    det.classification.wallpaper = moved_origin(det.classification.wallpaper, shift)
    det.distortion.centres = det.distortion.centres + shift
    if not (seen.found and nested(det.lattice.basis, seen.basis)):
        whole = {"stripes": f"stripes {seen.period:.1f} mm apart",
                 "lattice": f"a repeat of {_steps(seen)[0]:.1f} mm"}.get(seen.kind, "no print")
        _read_on_part(det.classification, f"the whole frame, shrunk to {WORK_SIDE} px, "
                      f"shows {whole}; its central {crop.shape[1]} x {crop.shape[0]} px at "
                      "full resolution a lattice")
    return det


def above_the_yarn(flat: np.ndarray, scale: float, mm_per_px: float,
                   min_repeat_mm: float = 3.0) -> tuple[float, float, np.ndarray]:
    """The yarn's repeat in mm (:func:`vision.lattice.yarn_repeat`; NaN where the image
    does not show it), the smoothing in working pixels that takes it away (1 px, the
    lattice search's own, otherwise) and the working image ``flat`` with it taken away:
    the print was designed above the yarn. Where less than ``PRINT_ABOVE_YARN`` of the
    contrast would remain, the yarn is all there is (plain cloth): ``flat`` as it is."""
    yarn_mm = yarn_repeat(flat, mm_per_px / scale, min_repeat_mm)
    if np.isfinite(yarn_mm):
        yarn_px = YARN_SMOOTHING * yarn_mm / mm_per_px * scale
        above = cv2.GaussianBlur(flat, (0, 0), yarn_px)
        if above.var() >= PRINT_ABOVE_YARN * flat.var():
            return yarn_mm, yarn_px, above
    return yarn_mm, 1.0, flat


def _central_part(flat: np.ndarray, scale: float, mm_per_px: float, min_repeat_mm: float
                  ) -> tuple[LatticeResult, np.ndarray, tuple[int, int]]:
    """The lattice of the central half (each way) of the working image, else of its
    central quarter: a steep view changes the repeat less over a smaller part, and a
    photo's edges may show other things than the cloth. Returns the lattice, the part
    read (mean removed) and its top-left corner (working px)."""
    h, w = flat.shape
    lat, part, corner = LatticeResult("plain"), flat, (0, 0)
    for frac in (0.5, 0.25):
        ch, cw = int(h * frac), int(w * frac)
        y0, x0 = (h - ch) // 2, (w - cw) // 2
        crop = flat[y0:y0 + ch, x0:x0 + cw]
        if min(crop.shape) < 32:
            break
        part, corner = crop - np.float32(crop.mean()), (x0, y0)
        lat = detect_lattice(_frame_of(part, scale), mm_per_px=mm_per_px,
                             prepared=(part, scale), min_repeat_mm=min_repeat_mm)
        if lat.found:
            break
    return lat, part, corner


def _frame_of(part: np.ndarray, scale: float) -> np.ndarray:
    """An input-sized frame for a working-image part (calloc: no memory is touched);
    the readers only take its shape."""
    return np.zeros((max(16, round(part.shape[0] / scale)),
                     max(16, round(part.shape[1] / scale))), np.uint8)


def _decide_part(part: np.ndarray, corner: tuple[int, int], scale: float,
                 mm_per_px: float, min_repeat_mm: float, true_repeat: bool = True,
                 allowance: float = 0.0) -> tuple[LatticeResult, Classification] | None:
    """Lattice and group of a part of the working image (the perspective undone, or
    the frame's centre) whose top-left corner lies at ``corner`` (working px), in the
    input image's millimetres; None when the part shows no lattice. ``allowance``:
    the lattice change across the part that the decision tolerates."""
    frame = _frame_of(part, scale)
    lat = detect_lattice(frame, mm_per_px=mm_per_px, prepared=(part, scale),
                         min_repeat_mm=min_repeat_mm)
    if true_repeat:
        lat = true_lattice(frame, lat, prepared=(part, scale))
    if not lat.found:
        return None
    cls = classify(frame, lat, flat=part, scale=scale, allowance=allowance)
    if cls.wallpaper is not None:
        cls.wallpaper = moved_origin(cls.wallpaper, np.array(corner, float) / scale * mm_per_px)
    return lat, cls
