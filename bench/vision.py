"""Benchmark of the vision pipeline, per source of images.

Sources (each reported on its own; never pooled into one number):

- ``synthetic``: a random print of each of the 17 groups (``simulators.fabric``), turned
  by 0-90 degrees, 3 to 30 repeats across, photographed by the synthetic camera (lens,
  light ramp and vignetting, blur, noise, JPEG), rectified with the camera's
  calibration, then given one residual fault at a random strength: perspective error
  (frame corners moved by up to 5 %) or a fold (up to 3 px), or a strong blur, noise,
  JPEG or light ramp.
- ``tilted``: camera frames of a random print of each group, the camera tilted 3-18
  degrees and the frame not rectified (perspective left in a photo).
- ``blurred``: small prints of every group (20-34 px repeats) under blur up to 3 px,
  noise, wrinkles and JPEG, three times as many: the supergroup hunt.
- ``cloth``: random prints of the 17 groups on real-looking cloth (``simulators.cloth``):
  woven thread texture (plain or twill), stretch 3-16 % with up to 3 degrees of shear,
  wrinkles, a misregistered colour separation, noise and JPEG. Truth is the group the
  print was designed with, and the stretched lattice.
- ``fine``: fine prints (5-15 mm repeats) of every group on the same cloth, in large
  frames (3200 x 2400 px at 0.2-0.4 mm/px): hundreds of repeats, read at a third of
  the resolution, and threads near the pixel size that beat with it (moire).
- ``renderings``: a random print of every group as a drawing program writes it: a
  lattice of whole pixels (along x only when hexagonal), symmetry elements anywhere,
  500-1400 px, no anti-aliasing, no camera. Every edge is rounded to the grid the same
  way in every repeat (``vision.consistency.pixel_rounding``).
- ``waves``: smooth prints of every group as Farris's recipes draw them
  (``simulators.fabric.wave_print``): plane waves symmetrised over the group and
  domain-coloured, 40-90 px repeats, no edges anywhere (the fine detail where a missing
  symmetry shows most is absent), no camera. Evaluation only.
- ``classics``: the textile classics of ``simulators.classics`` (gingham, tartan, plaid,
  houndstooth, herringbone, polka dots, diamonds; stripes must be stripes), clean and on
  stretched, woven cloth.
- ``woven``, ``woven-twill``: yarn-dyed checks woven in plain weave or 2/2 twill
  (``simulators.classics.woven_check``), whose threads show: each crossing has the
  colour of the thread on top, so at thread scale a gingham is not p4m; the truth is
  the group it was designed with (p4m, or pmm for an uneven check), read once the yarn
  is smoothed away.
- ``lineart``: near-symmetric line prints (``simulators.lineart.layered_print``): a
  bold layer of each group, a faint layer (30-60 % contrast, thin) of a random subgroup
  of it, camera blur, noise and JPEG; the truth is measured on the drawn segments.
  Training data for the failure the npm source showed (a p1 print read as p2).
- ``sublattice``: line prints whose faint layer repeats on an index-2 sublattice of the
  bold layer's (``layered_print(faint_cell=...)``), camera blur, noise and JPEG: the bold
  layer alone shows a step the print does not repeat by, and a lattice read at that
  step invents a translation (a supergroup on half the true lattice).
- ``plain``: unprinted cloth (plain weave, twill, rib knit; threads 0.2-0.6 mm): must
  never give a 2-D lattice.
- ``npm-wallpaper-groups``: an outside reference, line drawings replicated by the npm
  package ``wallpaper-groups`` under its 16 types and drawn by OpenCV (colours, widths,
  scale, turn, blur, noise, JPEG; ``bench.npm_wallpaper``). The truth is the group and
  lattice measured on the package's own segments, not its label. Evaluation only: the
  classifier's constants are never picked on it. Skipped, saying so, without node or
  the package (``make bench`` installs it).
- ``npm-as-written``: the same package's drawings as a generator writes its PNG (tiles
  of 24-72 whole pixels, not turned, no camera, every other one without anti-aliasing).
  Evaluation only.
- ``photos-tc``, ``photos-pj``, ``photos-lyn``, ``photos-ms``: the ten hand-labelled real
  photographs of ``../shared/data/fabric_photos`` (SOURCE.md there), grouped by origin,
  read in place (never copied; skipped when absent). A group is right when it is the
  label's group or its labelled alternative.
- ``frames``: the same ten photographs whole, as taken: the garments' collars,
  pockets, folds and background around the cloth, and the line-scan frames' fine
  repeats at a quarter of the resolution. The labelled lattice holds in the region
  only, so only the group (and plain or stripes) is graded. Evaluation only, like the
  npm source: the same photographs are already among the training sources.
- ``photo-crops``: each photograph cropped, rescaled and turned eight ways (the truth
  unchanged): how stable the answers are, a stand-in for other photographs.
- ``photo-turns``: each photograph turned by three random angles off the axes (5-85
  degrees) and cropped square: threads, shading bands and print across the pixel grid.
- ``photo-views``: each photograph seen in perspective three ways (one side shrunk
  10-30 %), its central 60 % read: the repeat changes across the view.
- ``photo-degraded``: each photograph as JPEG at quality 25, with noise, under a light
  ramp, and at half size.
- ``photo-closer``: a random part of each photograph enlarged 1.5-4 times, as a closer
  camera sees it, read at pixels = mm: fewer repeats of a print, and plain cloth's yarn
  coarser than the 3 mm a print needs (no scale says it is yarn).

Reported per source: group accuracy; lattice success (found = labelled lattice up to a
unimodular change of basis, vectors within max(3 %, twice the label's uncertainty)) and
median error; subgroup (safe), supergroup (invented symmetry) and other errors; false
lattices on plain cloth and stripes; accuracy against coverage when answers below a
confidence go to the operator; seconds per image; and, measured in the same run, the
group right under the decision before issue 15 (baseline). Then a leave-one-source-out
cross-validation of the classifier's free constants (``BAND``, ``TAU``; then the
consistency test's ``OWN_ASYMMETRY``, ``SHARED_ASYMMETRY``): the constants picked on all
other sources are scored on the one left out.

    python -m bench vision                 # every source, 3 images per group and fault
    python -c "from bench.vision import run; run(per_group=1)"      # a quick subset
    python -c "from bench.vision import speed; speed()"  # seconds per 4000x3000 frame
    python -c "from bench.vision import speed; speed(fine_prints=True)"  # hundreds of repeats
    python -c "from bench.vision import yarn_effect; yarn_effect()"  # yarn on / off
    python -c "from bench.vision import option_effect; option_effect('true_repeat')"
"""

from __future__ import annotations

import csv
import itertools
import math
import platform
import time
from dataclasses import dataclass, field
from datetime import date
from pathlib import Path

import cv2
import numpy as np
from scipy import ndimage

from bench import npm_wallpaper
from simulators.camera import CameraModel, Imaging, Pose, Sheet, SyntheticCamera
from simulators.classics import CLASSICS, classic_print, woven_check
from simulators.cloth import misregister, plain_cloth, stretch, weave_texture, wrinkle
from simulators.fabric import lattice_for, random_print, render_print, wave_print
from simulators.lineart import degrade, layered_print
from solver.wallpaper import GROUP_NAMES, GROUPS, gauss_reduce
from vision.calibration import Calibration
from vision.classify import (
    BAND,
    HOLOHEDRY_TOL,
    OWN_ASYMMETRY,
    SHARED_ASYMMETRY,
    TAU,
    classify,
    holohedry,
    isometry_name,
    repeat_cells,
    symmetric_metric,
)
from vision.lattice import detect_lattice, prepare_image
from vision.pipeline import above_the_yarn, detect_fabric
from vision.rectify import rectify
from vision.subgroups import error_kind

PHOTOS = Path(__file__).resolve().parents[2] / "shared" / "data" / "fabric_photos"
FAMILIES = ("rotation-scale", "perspective", "blur", "noise", "jpeg", "light", "fold")
#: Sources for evaluation only: no constant is fitted or picked on them (an outside
#: reference, a generator family added after the constants were set, and the
#: photographs whole, which the photos-* sources already hold).
OUTSIDE = ("npm-wallpaper-groups", "npm-as-written", "waves", "photo-closer", "frames")
THRESHOLDS = (0.0, 0.5, 0.7, 0.8, 0.9, 0.95)
CV_GRID = tuple((band, tau) for band in (float("inf"), 24.0, 12.0, 6.0)
                for tau in (0.80, 0.86))
#: The consistency test's thresholds (own asymmetry, its shared part; ``inf``: off):
#: the own part over its range at the a-priori share of one half, the share around it.
CONSISTENCY_GRID = (*((own, SHARED_ASYMMETRY) for own in (0.004, 0.006, 0.008, 0.012, 0.02,
                                                          0.03, float("inf"))),
                    (OWN_ASYMMETRY, 0.3), (OWN_ASYMMETRY, 0.7))


@dataclass
class Sample:
    """One image with its truth: a group (with an accepted alternative), or "stripes"
    or "plain"; ``basis`` (2,2) columns w1, w2 in mm of the image, when known."""

    source: str
    name: str
    image: np.ndarray
    mm_per_px: float
    truth: str
    alt: str | None = None
    basis: np.ndarray | None = None
    tol: float = 0.03
    found: dict = field(default_factory=dict)


# ---------------------------------------------------------------- sources
def _params(family: str, rng: np.random.Generator) -> dict:
    """Mild defaults, the chosen family over its full range."""
    p = dict(blur=0.6, noise=2.0, jpeg=92, ramp=(0.05, -0.03), vignetting=0.1,
             persp=0.0, fold=0.0)
    if family == "perspective":
        p["persp"] = rng.uniform(0.0, 0.05)
    elif family == "blur":
        p["blur"] = rng.uniform(0.0, 3.0)
    elif family == "noise":
        p["noise"] = rng.uniform(0.0, 10.0)
    elif family == "jpeg":
        p["jpeg"] = int(rng.uniform(60, 95))
    elif family == "light":
        gain = rng.uniform(0.2, 0.4)  # a gain ramp from 1 - gain to 1 + gain (0.6..1.4)
        a = rng.uniform(0, 2 * math.pi)
        p["ramp"] = (gain * math.cos(a), gain * math.sin(a))
        p["vignetting"] = rng.uniform(0.2, 0.4)
    elif family == "fold":
        p["fold"] = rng.uniform(0.0, 3.0)
    return p


def _residual_warp(img: np.ndarray, p: dict, rng: np.random.Generator
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Apply perspective and fold; return the image and the 2x2 Jacobian at the centre."""
    h, w = img.shape[:2]
    jac = np.eye(2)
    if p["persp"] > 0:
        src = np.float32([[0, 0], [w, 0], [w, h], [0, h]])
        dst = (src + rng.uniform(-1, 1, (4, 2)) * p["persp"] * np.array([w, h])).astype(
            np.float32)
        hom = cv2.getPerspectiveTransform(src, dst)
        img = cv2.warpPerspective(img, hom, (w, h), borderMode=cv2.BORDER_REFLECT)
        c = np.array([w / 2, h / 2, 1.0])
        q = hom @ c
        # d(H c / (h3 c)) / dc
        jac = (hom[:2, :2] * q[2] - np.outer(q[:2], hom[2, :2])) / q[2] ** 2
    if p["fold"] > 0:
        yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
        ang = rng.uniform(0, math.pi)
        k = 2 * math.pi / max(w, h) * rng.uniform(0.5, 1.0)
        phase = rng.uniform(0, 2 * math.pi)
        s = np.sin(k * (xx * math.cos(ang) + yy * math.sin(ang)) + phase).astype(np.float32)
        img = cv2.remap(img, xx + p["fold"] * s * math.cos(ang + 1.2),
                        yy + p["fold"] * s * math.sin(ang + 1.2), cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_REFLECT)
    return img, jac


def synthetic(per_group: int, size: tuple[int, int] = (1600, 1200), seed: int = 0):
    """Camera frames of random prints, one fault family each (see the module text)."""
    cam = CameraModel.default(size)
    height = 1000.0
    field_mm = size[0] * height / cam.K[0, 0]
    for gi, group in enumerate(GROUP_NAMES):
        for k in range(per_group):
            rng = np.random.default_rng(seed + 1000 * gi + k)
            family = FAMILIES[k % len(FAMILIES)]
            p = _params(family, rng)
            repeats = math.exp(rng.uniform(math.log(3), math.log(30)))
            pr = random_print(group, field_mm / repeats, rotation=rng.uniform(0, 90),
                              seed=int(rng.integers(1 << 30)))
            imaging = Imaging(light_ramp=p["ramp"], vignetting=p["vignetting"],
                              blur=p["blur"], noise=p["noise"], jpeg_quality=p["jpeg"])
            big = 3.0 * field_mm  # a sheet larger than the view
            sim = SyntheticCamera(Sheet(pr, size=(big, big), shift=(-big / 2, -big / 2)),
                                  camera=cam, imaging=imaging,
                                  poses=[Pose.overhead((0.0, 0.0), height)],
                                  seed=int(rng.integers(1 << 30)))
            frame = sim.read()
            hom = np.linalg.inv(sim.truth.homography)
            cal = Calibration(cam.K, cam.dist, cam.resolution, homography=hom / hom[2, 2])
            img, _region, s = rectify(frame, cal)
            img, jac = _residual_warp(img, p, rng)
            yield Sample("synthetic", f"{group}/{family}/{repeats:.1f}", img, s, group,
                         basis=jac @ sim.truth.wallpaper.basis)


def _on_cloth(img: np.ndarray, mm_per_px: float, rng: np.random.Generator
              ) -> tuple[np.ndarray, np.ndarray]:
    """Thread texture, stretch and shear, wrinkles, misregistration, noise and JPEG."""
    thread_px = rng.uniform(0.2, 0.5) / mm_per_px
    gain = weave_texture(img.shape[:2], thread_px, weave=str(rng.choice(["plain", "twill"])),
                         contrast=rng.uniform(0.05, 0.2), angle_deg=rng.uniform(-2, 2),
                         rng=rng)
    img = np.clip(img * gain[..., None], 0, 255).astype(np.uint8)
    img, jac = stretch(img, rng.uniform(1.03, 1.16), shear_deg=rng.uniform(-3, 3),
                       angle_deg=rng.uniform(0, 180))
    img = wrinkle(img, rng.uniform(1, 5), rng.uniform(0.03, 0.1) * max(img.shape), rng=rng)
    img = misregister(img, tuple(rng.uniform(-1.5, 1.5, 2)), channel=int(rng.integers(3)))
    img = cv2.GaussianBlur(img, (0, 0), rng.uniform(0.4, 1.2))
    img = np.clip(img + rng.normal(0, rng.uniform(1, 6), img.shape), 0, 255).astype(np.uint8)
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, int(rng.uniform(70, 95))])
    return cv2.imdecode(buf, cv2.IMREAD_COLOR), jac


def _print_on_cloth(group: str, period_mm: float, mm_per_px: float, size: tuple[int, int],
                    rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A random print of ``group`` filling a ``size`` frame, on cloth (``_on_cloth``),
    and its stretched lattice (columns, mm)."""
    pr = random_print(group, period_mm, rotation=rng.uniform(0, 90),
                      seed=int(rng.integers(1 << 30)))
    img = render_print(pr, (size[0] * mm_per_px, size[1] * mm_per_px), mm_per_px)
    img, jac = _on_cloth(img, mm_per_px, rng)
    return img, jac @ pr.wallpaper.basis


def cloth(per_group: int, size: tuple[int, int] = (1200, 900), seed: int = 0):
    """Random prints of every group on stretched, wrinkled, woven cloth."""
    for gi, group in enumerate(GROUP_NAMES):
        for k in range(per_group):
            rng = np.random.default_rng(seed + 7919 * gi + k + 1)
            mm = rng.uniform(0.1, 0.3)
            repeats = math.exp(rng.uniform(math.log(4), math.log(20)))
            img, basis = _print_on_cloth(group, size[0] * mm / repeats, mm, size, rng)
            yield Sample("cloth", f"{group}/{repeats:.1f}", img, mm, group, basis=basis)


def fine(per_group: int, size: tuple[int, int] = (3200, 2400), seed: int = 0):
    """Fine prints of every group on stretched, wrinkled, woven cloth in large frames."""
    for gi, group in enumerate(GROUP_NAMES):
        for k in range(per_group):
            rng = np.random.default_rng(seed + 104729 * gi + k + 7)
            mm = rng.uniform(0.2, 0.4)
            period = math.exp(rng.uniform(math.log(5), math.log(15)))
            img, basis = _print_on_cloth(group, period, mm, size, rng)
            yield Sample("fine", f"{group}/{period:.1f}mm", img, mm, group, basis=basis)


def classics(per_name: int = 2, seed: int = 0):
    """Each textile classic clean, then on stretched woven cloth."""
    for ni, name in enumerate(CLASSICS):
        for k in range(per_name):
            rng = np.random.default_rng(seed + 31 * ni + k)
            mm = 0.25
            pr = classic_print(name, rng.uniform(15, 45), rotation=rng.uniform(0, 90))
            img = render_print(pr, (300, 225), mm)
            jac = np.eye(2)
            if k % 2:
                img, jac = _on_cloth(img, mm, rng)
            truth = "stripes" if name == "stripes" else pr.truth.group
            basis = None if name == "stripes" else jac @ pr.wallpaper.basis
            yield Sample("classics", f"{name}/{'cloth' if k % 2 else 'clean'}", img, mm,
                         truth, basis=basis)


def woven(per_kind: int = 4, seed: int = 0, weave: str = "plain"):
    """Yarn-dyed woven checks (``simulators.classics.woven_check``), each crossing the
    colour of the thread on top: ginghams (designed p4m) and, one in three, uneven
    checks (pmm, whose quarter turn the yarn must not invent), 6-24 threads per band,
    5-15 mm repeats at 0.06-0.15 mm per pixel, alternately clean and on cloth."""
    for k in range(3 * per_kind):
        rng = np.random.default_rng(seed + 4099 * k + 17)
        threads = int(rng.integers(6, 25))
        weft = threads
        if k % 3 == 2:
            weft = int(np.clip(round(threads * rng.choice([rng.uniform(0.4, 0.7),
                                                          rng.uniform(1.3, 1.6)])),
                               1, 2 * threads - 1))
        mm = rng.uniform(0.06, 0.15)
        pr = woven_check(rng.uniform(5, 15), threads, weft_threads=weft, weave=weave,
                         rotation=rng.uniform(0, 90), shade=rng.uniform(0, 0.08))
        img = render_print(pr, (640 * mm, 480 * mm), mm)
        jac = np.eye(2)
        if k % 2:
            img, jac = _on_cloth(img, mm, rng)
        yield Sample("woven" if weave == "plain" else f"woven-{weave}",
                     f"{pr.truth.group}/{threads}:{weft}", img, mm,
                     pr.truth.group, basis=jac @ pr.wallpaper.basis)


def tilted_frame(group: str, tilt: float, seed: int, size: tuple[int, int] = (480, 360),
                 height: float = 600.0) -> tuple[np.ndarray, float, np.ndarray]:
    """A frame straight from a camera looking ``tilt`` degrees off the vertical (in a
    random direction) at a random print, never rectified; the mm per pixel at its
    centre and the print's lattice there (the view's Jacobian at the centre)."""
    cam = CameraModel.default(size, dist=(0, 0, 0, 0, 0))
    mm_per_px = height / cam.K[0, 0]
    rng = np.random.default_rng(seed)
    pr = random_print(group, size[0] * mm_per_px / rng.uniform(6, 10),
                      rotation=rng.uniform(0, 90), seed=seed)
    sim = SyntheticCamera(Sheet(pr, size=(3000, 3000), shift=(-1500, -1500)), camera=cam,
                          imaging=Imaging(blur=0.6, noise=2.0, jpeg_quality=92,
                                          light_ramp=(0.05, -0.03), vignetting=0.1),
                          poses=[Pose.overhead((0, 0), height, tilt_deg=tilt,
                                               tilt_azimuth_deg=rng.uniform(0, 360))],
                          seed=seed)
    frame = sim.read()
    # Table -> image homography; its Jacobian at the frame centre carries the lattice.
    hom = sim.truth.homography / sim.truth.homography[2, 2]
    centre = np.array([(size[0] - 1) / 2, (size[1] - 1) / 2, 1.0])
    inv = np.linalg.inv(hom)
    t = inv @ centre
    q = hom @ (t / t[2])
    jac = (hom[:2, :2] * q[2] - np.outer(q[:2], hom[2, :2])) / q[2] ** 2
    return frame, mm_per_px, jac * mm_per_px @ pr.wallpaper.basis


def tilted(per_group: int, seed: int = 0):
    """Camera frames tilted 3-18 degrees, not rectified (perspective left in a photo)."""
    for gi, group in enumerate(GROUP_NAMES):
        for k in range(per_group):
            rng = np.random.default_rng(seed + 613 * gi + k)
            tilt = float(rng.uniform(3, 18))
            frame, mm, basis = tilted_frame(group, tilt, int(rng.integers(1 << 30)))
            yield Sample("tilted", f"{group}/{tilt:.0f}deg", frame, mm, group, basis=basis,
                         tol=0.05)


def blurred(per_group: int, seed: int = 0):
    """Small prints (20-34 px repeats) under heavy blur (up to 3 px), noise, wrinkles and
    JPEG: where blur can make a print look more symmetric than it is (supergroups)."""
    for gi, group in enumerate(GROUP_NAMES):
        for k in range(per_group):
            rng = np.random.default_rng(seed + 389 * gi + k + 7)
            period = rng.uniform(20, 34)
            pr = random_print(group, period, rotation=rng.uniform(0, 90),
                              seed=int(rng.integers(1 << 30)))
            img = render_print(pr, (220.0, 170.0), 1.0)
            img = wrinkle(img, rng.uniform(0, 1), rng.uniform(40, 90), rng=rng)
            img = cv2.GaussianBlur(img, (0, 0), rng.uniform(0.01, 3.0))
            img = np.clip(img + rng.normal(0, rng.uniform(0, 8), img.shape), 0, 255)
            ok, buf = cv2.imencode(".jpg", img.astype(np.uint8),
                                   [cv2.IMWRITE_JPEG_QUALITY, int(rng.uniform(60, 95))])
            yield Sample("blurred", f"{group}/{period:.0f}px", cv2.imdecode(buf, 1), 1.0,
                         group, basis=pr.wallpaper.basis)


def lineart(per_group: int, seed: int = 0):
    """Near-symmetric line prints of every group (see the module text)."""
    for gi, group in enumerate(GROUP_NAMES):
        for k in range(per_group):
            rng = np.random.default_rng(seed + 100 * gi + k + 7)
            img, truth, basis = layered_print(group, rng.uniform(30, 70),
                                              seed=seed + 100 * gi + k)
            yield Sample("lineart", f"{group}/{truth}/{k}", degrade(img, rng), 0.25, truth,
                         basis=basis)


#: The index-2 sublattices a faint layer of ``sublattice`` repeats on (columns over the
#: bold layer's basis).
FAINT_CELLS = (np.array([[2, 0], [0, 1]]), np.array([[1, 1], [1, -1]]))


def sublattice(per_group: int, seed: int = 0):
    """Line prints whose faint layer repeats on a sublattice (see the module text)."""
    for gi, group in enumerate(GROUP_NAMES):
        for k in range(per_group):
            rng = np.random.default_rng(seed + 100 * gi + k + 11)
            img, truth, basis = layered_print(group, rng.uniform(25, 45),
                                              seed=seed + 100 * gi + k + 50,
                                              faint_cell=FAINT_CELLS[k % 2])
            yield Sample("sublattice", f"{group}/{truth}/{k}", degrade(img, rng), 0.25,
                         truth, basis=basis)


def plain(per_weave: int = 3, seed: int = 0):
    """Unprinted cloth close up: the weave is all there is."""
    for wi, weave in enumerate(("plain", "twill", "rib")):
        for k in range(per_weave):
            rng = np.random.default_rng(seed + 101 * wi + k)
            mm = rng.uniform(0.04, 0.12)
            thread = rng.uniform(0.2, 0.6)
            img = plain_cloth((1200, 900), thread / mm, weave=weave,
                              seed=int(rng.integers(1 << 30)))
            yield Sample("plain", f"{weave}/{thread:.2f}mm", img, mm, "plain")


def npm(per_type: int, seed: int = 0):
    """The npm package's line drawings (see ``bench.npm_wallpaper``); none, saying
    why, when node or the package is missing."""
    why = npm_wallpaper.unavailable()
    if why:
        print(f"source npm-wallpaper-groups skipped: {why}", flush=True)
        return
    for kind, group, img, basis in npm_wallpaper.patterns(per_type, seed=seed):
        yield Sample("npm-wallpaper-groups", f"{kind}->{group}", img,
                     npm_wallpaper.MM_PER_PX, group, basis=basis)


def npm_as_written(per_type: int, seed: int = 0):
    """The npm package's line drawings as a generator writes them (tiles of whole
    pixels, no camera, half without anti-aliasing); none, saying why, when node or
    the package is missing."""
    why = npm_wallpaper.unavailable()
    if why:
        print(f"source npm-as-written skipped: {why}", flush=True)
        return
    for kind, group, img, basis in npm_wallpaper.patterns(per_type, seed=seed,
                                                          as_written=True):
        yield Sample("npm-as-written", f"{kind}->{group}", img, npm_wallpaper.MM_PER_PX,
                     group, basis=basis)


def renderings(per_group: int, seed: int = 0):
    """Random prints as a drawing program writes them (see the module text)."""
    for gi, group in enumerate(GROUP_NAMES):
        for k in range(per_group):
            rng = np.random.default_rng(seed + 100 * gi + k + 13)
            repeat = int(rng.integers(24, 80))
            kind = GROUPS[group].lattice
            # Whole pixels (along x only on a hexagonal lattice: sqrt 3 is not whole).
            if kind == "hexagonal":
                w1 = np.array([2.0 * (repeat // 2), 0.0])
                w2 = np.array([w1[0] / 2, w1[0] / 2 * math.sqrt(3.0)])
            elif kind == "rhombic":
                half = math.radians(rng.uniform(68.0, 78.0)) / 2
                w1 = np.rint(repeat * np.array([math.cos(half), math.sin(half)]))
                w2 = w1 * [1.0, -1.0]
            else:
                w1, w2 = (np.rint(v) for v in lattice_for(group, repeat, rng=rng))
            side = int(rng.integers(500, 1400))
            pr = random_print(group, w1=w1, w2=w2, seed=int(rng.integers(1 << 30)),
                              origin=tuple(rng.uniform(0, 1, 2)))
            img = render_print(pr, (side, side * 3 // 4), 1.0, anti_alias=False)
            yield Sample("renderings", f"{group}/{repeat}px/{side}", img, 1.0, group,
                         basis=pr.wallpaper.basis)


def waves(per_group: int, seed: int = 0):
    """Smooth domain-coloured prints of every group (see the module text)."""
    for gi, group in enumerate(GROUP_NAMES):
        for k in range(per_group):
            rng = np.random.default_rng(seed + 211 * gi + k + 5)
            repeat = rng.uniform(40, 90)
            pr = wave_print(group, repeat, rotation=rng.uniform(0, 90),
                            seed=int(rng.integers(1 << 30)))
            yield Sample("waves", f"{group}/{repeat:.0f}px", render_print(pr, (640, 480), 1.0),
                         1.0, group, basis=pr.wallpaper.basis)


def photos(root: Path = PHOTOS, whole: bool = False):
    """The hand-labelled photographs, cropped to their labelled region (pixels = mm);
    or ``whole``, as taken, without the labelled lattice (which holds in the region
    only): the photos of garments show collars, pockets and drape around the cloth."""
    labels = root / "labels.csv"
    if not labels.is_file():
        return
    with open(labels, newline="") as fh:
        for r in csv.DictReader(fh):
            img = cv2.imread(str(root / r["file"]), cv2.IMREAD_COLOR)
            if img is None:
                continue
            if r["roi"] and not whole:
                x0, y0, x1, y1 = (int(v) for v in r["roi"].split())
                img = img[y0:y1, x0:x1]
            basis = None
            if r["w1_x"] and r["w2_x"] and not (whole and r["roi"]):
                basis = np.array([[float(r["w1_x"]), float(r["w2_x"])],
                                  [float(r["w1_y"]), float(r["w2_y"])]])
            truth = r["group"] if r["group"] != "none" else "plain"
            tol = max(0.03, 2 * float(r["lattice_unc_pct"] or 0) / 100)
            source = "frames" if whole else "photos-" + r["file"].split("_")[0]
            yield Sample(source, r["file"], img, 1.0, truth,
                         alt=r["alt_group"] or None, basis=basis, tol=tol)


def photo_crops(per_photo: int = 8, seed: int = 0, root: Path = PHOTOS):
    """Each labelled photograph cropped to 60-90 % of its region each way at a random
    place, rescaled 0.6-1.4 times and turned by a random number of quarter turns: the
    group does not change and the labelled lattice turns and scales with the image. A
    stand-in for other photographs of the same cloths: how stable each answer is."""
    rng = np.random.default_rng(seed)
    turns = (np.eye(2), np.array([[0, 1], [-1, 0]]), -np.eye(2), np.array([[0, -1], [1, 0]]))
    for s in photos(root):
        for k in range(per_photo):
            h, w = s.image.shape[:2]
            f = rng.uniform(0.6, 0.9)
            ch, cw = int(h * f), int(w * f)
            y0, x0 = int(rng.integers(0, h - ch + 1)), int(rng.integers(0, w - cw + 1))
            zoom = rng.uniform(0.6, 1.4)
            img = cv2.resize(s.image[y0:y0 + ch, x0:x0 + cw], None, fx=zoom, fy=zoom,
                             interpolation=cv2.INTER_AREA)
            turn = int(rng.integers(0, 4))  # np.rot90: counter-clockwise as displayed
            img = np.ascontiguousarray(np.rot90(img, turn))
            basis = None if s.basis is None else turns[turn] @ s.basis * zoom
            yield Sample("photo-crops", f"{s.name}#{k}", img, 1.0, s.truth, alt=s.alt,
                         basis=basis, tol=s.tol)


def photo_turns(per_photo: int = 3, seed: int = 0, root: Path = PHOTOS):
    """Each labelled photograph turned by random angles (5-85 degrees, resampled) and
    cropped to the largest centred square the turned region fills: cloth photographed
    off the axes, whose threads, shading bands and print run across the pixel grid.
    The group does not change; the labelled lattice turns with the image."""
    rng = np.random.default_rng(seed)
    for s in photos(root):
        h, w = s.image.shape[:2]
        for _ in range(per_photo):
            angle = float(rng.uniform(5.0, 85.0))
            turn = cv2.getRotationMatrix2D(((w - 1) / 2, (h - 1) / 2), angle, 1.0)
            img = cv2.warpAffine(s.image, turn, (w, h), flags=cv2.INTER_LINEAR)
            t = math.radians(angle)
            side = int(min(h, w) / (math.cos(t) + math.sin(t)))
            y0, x0 = (h - side) // 2, (w - side) // 2
            basis = None if s.basis is None else turn[:, :2] @ s.basis
            yield Sample("photo-turns", f"{s.name}@{angle:.0f}",
                         np.ascontiguousarray(img[y0:y0 + side, x0:x0 + side]), 1.0,
                         s.truth, alt=s.alt, basis=basis, tol=s.tol)


def photo_views(per_photo: int = 3, seed: int = 0, root: Path = PHOTOS):
    """Each labelled photograph seen in perspective: one side of the frame shrunk by
    10-30 % (a camera tilted towards it), the central 60 % kept. The group does not
    change; the labelled lattice maps through the view's derivative at the centre,
    where it is graded (within 6 %: the repeat changes across the view)."""
    rng = np.random.default_rng(seed)
    for s in photos(root):
        h, w = s.image.shape[:2]
        corners = np.float32([[0, 0], [w, 0], [w, h], [0, h]])
        for _ in range(per_photo):
            shrink, edge = float(rng.uniform(0.1, 0.3)), int(rng.integers(0, 4))
            moved = corners.copy()
            for k in (edge, (edge + 1) % 4):  # the edge's ends move towards its middle
                moved[k] += (corners[edge] + corners[(edge + 1) % 4] - 2 * corners[k]) \
                    * shrink / 2
            view = cv2.getPerspectiveTransform(corners, moved)
            img = cv2.warpPerspective(s.image, view, (w, h), flags=cv2.INTER_LINEAR)
            basis = None
            if s.basis is not None:
                p = view @ np.array([w / 2, h / 2, 1.0])
                jac = (view[:2, :2] * p[2] - np.outer(p[:2], view[2, :2])) / p[2] ** 2
                basis = jac @ s.basis
            yield Sample("photo-views", f"{s.name}/{edge}/{shrink:.2f}",
                         np.ascontiguousarray(img[int(0.2 * h):int(0.8 * h),
                                                  int(0.2 * w):int(0.8 * w)]), 1.0,
                         s.truth, alt=s.alt, basis=basis, tol=max(s.tol, 0.06))


def photo_closer(per_photo: int = 4, seed: int = 0, root: Path = PHOTOS):
    """Each labelled photograph as a camera 1.5-4 times closer would take it: a random
    part of its region enlarged (cubic) back to the region's size, read at pixels = mm
    as the photographs are. Fewer repeats of a print; the yarn of plain cloth several
    times coarser, above the 3 mm a print needs (a close-up of cloth whose scale
    nobody gave)."""
    rng = np.random.default_rng(seed)
    for s in photos(root):
        h, w = s.image.shape[:2]
        for _ in range(per_photo):
            zoom = float(rng.uniform(1.5, 4.0))
            ch, cw = int(h / zoom), int(w / zoom)
            y0, x0 = int(rng.integers(0, h - ch + 1)), int(rng.integers(0, w - cw + 1))
            img = cv2.resize(s.image[y0:y0 + ch, x0:x0 + cw], (w, h),
                             interpolation=cv2.INTER_CUBIC)
            basis = None if s.basis is None else s.basis * np.array([[w / cw], [h / ch]])
            yield Sample("photo-closer", f"{s.name}x{zoom:.1f}", img, 1.0, s.truth,
                         alt=s.alt, basis=basis, tol=s.tol)


def photo_degraded(seed: int = 0, root: Path = PHOTOS):
    """Each labelled photograph four ways worse than taken: JPEG at quality 25, noise of
    10 grey levels, light falling to a third across the frame, and half the size."""
    rng = np.random.default_rng(seed)
    for s in photos(root):
        h, w = s.image.shape[:2]
        yy, xx = np.mgrid[0:h, 0:w]
        light = 0.5 + 0.8 * (xx / w) * (0.6 + 0.4 * yy / h)
        worse = {
            "jpeg25": cv2.imdecode(cv2.imencode(".jpg", s.image,
                                                [cv2.IMWRITE_JPEG_QUALITY, 25])[1],
                                   cv2.IMREAD_COLOR),
            "noise10": np.clip(s.image + rng.normal(0, 10, s.image.shape), 0, 255),
            "ramp": np.clip(s.image * light[..., None], 0, 255),
            "half": cv2.resize(s.image, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)}
        for kind, img in worse.items():
            zoom = 0.5 if kind == "half" else 1.0
            yield Sample("photo-degraded", f"{s.name}/{kind}", img.astype(np.uint8), 1.0,
                         s.truth, alt=s.alt,
                         basis=None if s.basis is None else s.basis * zoom, tol=s.tol)


# ---------------------------------------------------------------- a print's distortion
def motif_stretch(name: str = "ms_checker_perspective.jpg",
                  stretches: tuple[float, ...] = (0.0, 0.05, 0.1, 0.15, 0.2),
                  tol: float = 2 * HOLOHEDRY_TOL, root: Path = PHOTOS) -> str:
    """:func:`stretch_scores` of the labelled photograph ``name`` on its labelled
    lattice, as a table: whether a symmetry the label names is in the image, or only
    in the design the label assumes (issue 15's last photograph)."""
    s = next((x for x in photos(root) if x.name == name), None)
    if s is None or s.basis is None:
        return f"{name}: no labelled lattice here ({root})"
    rows = [f"| {kind} {a.ravel().tolist()} | " + " | ".join(f"{v:.2f}" for v in scores)
            + " |" for a, kind, scores in stretch_scores(s, stretches, tol)]
    text = (f"{name} ({s.truth}), mean cell on the labelled lattice:\n\n"
            "| isometry (fractional matrix) | "
            + " | ".join(f"stretch {100 * e:.0f} %" for e in stretches) + " |\n|---|"
            + "---|" * len(stretches) + "\n" + "\n".join(rows))
    print(text)
    return text


def stretch_scores(s: Sample, stretches: tuple[float, ...], tol: float = 2 * HOLOHEDRY_TOL
                   ) -> list[tuple[np.ndarray, str, list[float]]]:
    """How far the print of ``s`` must be stretched for each isometry of its lattice
    (``s.basis``) to map it onto itself: per isometry of finite order within ``tol``
    (relative metric tolerance; twice the classifier's by default, so that a lattice
    seen steeply still shows the quarter turn its design would have), its integer
    matrix, its kind and its score at each stretch.

    The mean cell (no whitening) is sampled on the basis. In the frame where the
    lattice is undistorted (its metric averaged over the isometries tested, as
    ``vision.classify`` tests them), each isometry's image is stretched by ``1 + e``
    along the lattice's principal strain axis and shrunk as much across, and correlated
    with the cell over a Gaussian window of 0.35 repeats about the best centre (the
    best of 24 x 24, refined eightfold). A symmetry of the print scores near 1 at
    e = 0."""
    flat, scale = prepare_image(s.image)
    basis = s.basis / s.mm_per_px * scale
    _, (motif, *_) = repeat_cells(flat, basis)
    motif = motif - motif.mean()
    n = motif.shape[0]
    holo = holohedry(basis, tol=tol)
    ev, vec = np.linalg.eigh(symmetric_metric(basis, holo))
    to_frame = vec @ np.diag(np.sqrt(ev)) @ vec.T  # undistorted frame, from fractions
    to_frame /= math.sqrt(np.linalg.det(to_frame))
    frame_inv = np.linalg.inv(to_frame)
    strain = frame_inv.T @ (basis.T @ basis) @ frame_inv  # measured metric in that frame
    axis = np.linalg.eigh(strain)[1]
    u, v = axis[:, 1], axis[:, 0]
    g = np.linspace(-0.5, 0.5, 48, endpoint=False)
    pts = np.stack([a.ravel() for a in np.meshgrid(g, g, indexing="ij")])  # (2, P)
    weight = np.exp(-0.5 * ((to_frame @ pts) ** 2).sum(0) / 0.35**2)
    c = np.arange(24) / 24
    coarse = np.stack([a.ravel() for a in np.meshgrid(c, c, indexing="ij")])  # (2, C)
    f = np.linspace(-1.0, 1.0, 9) / 24
    fine = np.stack([a.ravel() for a in np.meshgrid(f, f, indexing="ij")])

    def window(points: np.ndarray, centres: np.ndarray) -> np.ndarray:
        at = (points[:, None, :] + centres[:, :, None]) * n  # (2, C, P) grid units
        vals = ndimage.map_coordinates(motif, at.reshape(2, -1), order=3, mode="grid-wrap")
        vals = vals.reshape(at.shape[1:])
        return vals - (vals * weight).sum(1, keepdims=True) / weight.sum()

    def best(op: np.ndarray) -> float:
        """The windowed correlation at the best centre: 24 x 24, then refined."""
        score, centres = None, coarse
        for _ in range(2):
            here, there = window(pts, centres), window(op @ pts, centres)
            corr = (weight * here * there).sum(1) / np.sqrt(
                (weight * here**2).sum(1) * (weight * there**2).sum(1))
            k = int(np.argmax(corr))
            score, centres = float(corr[k]), centres[:, k, None] + fine
        return score

    out = []
    for a in holo:
        if not any(np.array_equal(np.linalg.matrix_power(a, k), np.eye(2)) for k in (2, 3, 4, 6)):
            continue  # of infinite order (a shear): an isometry of no lattice
        kind = isometry_name(a)
        scores = [best(frame_inv @ ((1 + e) * np.outer(u, u) + np.outer(v, v) / (1 + e))
                       @ to_frame @ a) for e in stretches]
        out.append((a, kind, scores))
    return out


# ---------------------------------------------------------------- scoring
def lattice_match(found: np.ndarray, truth: np.ndarray) -> tuple[bool, float]:
    """(same lattice up to a unimodular change of basis, largest relative error)."""
    t1, t2, _ = gauss_reduce(truth[:, 0], truth[:, 1])
    t = np.column_stack([t1, t2])
    u = np.linalg.solve(t, found)
    ur = np.round(u)
    if abs(abs(np.linalg.det(ur)) - 1) > 1e-9 or np.abs(u - ur).max() > 0.3:
        return False, float("inf")
    err = float(np.max(np.linalg.norm(found - t @ ur, axis=0) / np.linalg.norm(found, axis=0)))
    return True, err


def baseline(s: Sample) -> str:
    """The outcome under the decision before issue 15, measured in the same run: no
    weave test, weak repeats accepted (0.2), the lattice's isometries only within 20 %
    of exact, whitening over every harmonic, no consistency test (the per-repeat check
    and the single-repeat rule cannot be switched off, so the baseline has them)."""
    flat, scale = prepare_image(s.image)
    lat = detect_lattice(s.image, mm_per_px=s.mm_per_px, prepared=(flat, scale),
                         min_strength=0.2, min_repeat_mm=0.0)
    if s.truth in ("plain", "stripes"):
        return "false lattice" if lat.found else "right"
    c = classify(s.image, lat, flat=flat, scale=scale, band=float("inf"), holohedry_tol=0.2,
                 strain_sigma=1e9, consistency=False)
    return error_kind(c.group, s.truth, s.alt)


def evaluate(s: Sample, *, with_baseline: bool = True, **options: bool) -> dict:
    """``detect_fabric`` on one sample (with ``options``, its switches), graded against
    its truth."""
    t0 = time.perf_counter()
    det = detect_fabric(s.image, mm_per_px=s.mm_per_px, **options)
    sec = time.perf_counter() - t0
    group = det.classification.group
    out = dict(group=group, kind=det.lattice.kind, conf=float(det.classification.confidence),
               scores=dict(det.classification.scores),
               strength=float(det.lattice.strength),
               sec=sec, lattice_ok=None, err=float("nan"))
    if s.basis is not None:
        ok, err = (lattice_match(det.lattice.basis, s.basis) if det.lattice.found
                   else (False, float("inf")))
        out.update(lattice_ok=bool(ok and err < s.tol), err=err)
    if s.truth in ("plain", "stripes"):
        out["outcome"] = "false lattice" if det.lattice.found else (
            "right" if det.lattice.kind == s.truth or s.alt == det.lattice.kind else "other")
    else:
        out["outcome"] = error_kind(group, s.truth, s.alt)
    out["baseline"] = baseline(s) if with_baseline else None
    return out


def _pct(a, b) -> str:
    return f"{100 * a / b:.0f} % ({a}/{b})" if b else "-"


def report(samples: list[Sample]) -> str:
    sources = list(dict.fromkeys(s.source for s in samples))
    lines = ["| source | images | group right | before issue 15 | lattice ok | "
             "median lattice err % | subgroup | supergroup | other | missed | "
             "false lattice | s/image |", "|---" * 12 + "|"]
    cover = ["| source | " + " | ".join(f"conf >= {t:g}" for t in THRESHOLDS) + " |",
             "|---" * (len(THRESHOLDS) + 1) + "|"]
    for src in sources:
        rows = [s.found for s in samples if s.source == src]
        n = len(rows)
        count = {k: sum(r["outcome"] == k for r in rows)
                 for k in ("right", "subgroup", "supergroup", "other", "missed",
                           "false lattice")}
        lat = [r for r in rows if r["lattice_ok"] is not None]
        errs = [r["err"] for r in lat if np.isfinite(r["err"])]
        med = f"{np.median(errs) * 100:.2f}" if errs else "-"
        lines.append(" | ".join([
            f"| {src}", str(n), _pct(count["right"], n),
            _pct(sum(r["baseline"] == "right" for r in rows), n),
            _pct(sum(r["lattice_ok"] for r in lat), len(lat)), med,
            *(str(count[k]) for k in ("subgroup", "supergroup", "other", "missed",
                                      "false lattice")),
            f"{np.median([r['sec'] for r in rows]):.2f} |"]))
        graded = [r for r in rows if r["group"] is not None]
        cells = []
        for t in THRESHOLDS:
            kept = [r for r in graded if r["conf"] >= t]
            right = sum(r["outcome"] == "right" for r in kept)
            cells.append(f"{_pct(len(kept), len(graded)).split(' ')[0]} kept, "
                         f"{100 * right / len(kept):.0f} % right" if kept else "none kept")
        cover.append(f"| {src} | " + " | ".join(cells) + " |")
    return "\n".join(lines + ["", "Accuracy against coverage (answers with a lattice; "
                                      "the rest go to the operator):", ""] + cover)


def cross_validate(samples: list[Sample], grid=CV_GRID, params=("band", "tau"),
                   shipped=(BAND, TAU), safer=lambda cfg: (cfg[1], cfg[0])) -> str:
    """Leave one source out: pick the classifier's constants ``params`` (one tuple of
    ``grid`` each) on the other sources (mean accuracy over sources; a supergroup costs
    ten right answers), score them on the one left out. Ties go to ``safer`` (by
    default a higher tau, a wider band: fewer symmetries claimed)."""
    cached = []
    for s in samples:
        if s.truth in ("plain", "stripes"):
            continue
        flat, scale = prepare_image(s.image)
        _, smooth, read = above_the_yarn(flat, scale, s.mm_per_px)  # as detect_fabric
        lat = detect_lattice(s.image, mm_per_px=s.mm_per_px, prepared=(flat, scale),
                             smooth_px=smooth)
        cached.append((s, lat, read, scale))
    outcome = {}
    for cfg in dict.fromkeys((*grid, shipped)):
        for i, (s, lat, flat, scale) in enumerate(cached):
            c = classify(s.image, lat, flat=flat, scale=scale, **dict(zip(params, cfg,
                                                                          strict=True)))
            outcome[cfg, i] = error_kind(c.group, s.truth, s.alt)
    sources = list(dict.fromkeys(s.source for s, *_ in cached))

    def counts(cfg, srcs) -> tuple[int, int, int]:
        ks = [outcome[cfg, i] for i, (s, *_) in enumerate(cached) if s.source in srcs]
        return sum(k == "right" for k in ks), sum(k == "supergroup" for k in ks), len(ks)

    def merit(cfg, srcs) -> tuple:
        per = []
        for src in srcs:
            right, sup, n = counts(cfg, [src])
            per.append((right - 10 * sup) / n)
        return float(np.mean(per)), *safer(cfg)

    names = ", ".join(params)
    lines = [f"| held-out source | picked on the others ({names}) | held-out right | "
             "held-out supergroups | shipped constants: right, supergroups |",
             "|---|---|---|---|---|"]
    for src in sources:
        best = max(grid, key=lambda cfg: merit(cfg, [x for x in sources if x != src]))
        right, sup, n = counts(best, [src])
        right0, sup0, _ = counts(shipped, [src])
        lines.append(f"| {src} | {', '.join(f'{v:g}' for v in best)} | {_pct(right, n)} | "
                     f"{sup} | {_pct(right0, n)}, {sup0} |")
    return "\n".join(lines)


def fit_temperature(samples: list[Sample], grid=(0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0)
                    ) -> str:
    """The posterior's temperature under which the winner's probability best predicts
    whether the answer is right (Bernoulli log-loss, mean over sources), and how the
    confidence compares with the share of right answers at that temperature."""
    rows = [(s, s.found) for s in samples if s.found.get("scores")]
    right = np.array([f["outcome"] == "right" for _, f in rows])

    def conf(t: float) -> np.ndarray:
        out = []
        for _, f in rows:
            ll = np.array(list(f["scores"].values())) / t
            p = np.exp(ll - ll.max())
            out.append(p.max() / p.sum())
        return np.clip(np.array(out), 1e-6, 1 - 1e-6)

    def loss(t: float) -> float:
        c = conf(t)
        per = {}
        for (s, _), y, ci in zip(rows, right, c, strict=True):
            per.setdefault(s.source, []).append(-math.log(ci if y else 1 - ci))
        return float(np.mean([np.mean(v) for v in per.values()]))

    best = min(grid, key=loss)
    c = conf(best)
    bins = [(0.0, 0.7), (0.7, 0.9), (0.9, 0.99), (0.99, 1.01)]
    cells = [f"confidence in [{a:g}, {min(b, 1):g}{']' if b > 1 else ')'}: "
             f"{int(sel.sum())} answers, mean confidence {c[sel].mean():.2f}, "
             f"share right {right[sel].mean():.2f}"
             for a, b in bins if (sel := (c >= a) & (c < b)).any()]
    return (f"best temperature {best:g} (mean log-loss per source "
            f"{', '.join(f'T={t:g}: {loss(t):.3f}' for t in grid)})\n\n- "
            + "\n- ".join(cells))


def _sources(per_group: int, seed: int) -> dict:
    """Every source by name, as a function that yields its samples."""
    return {"synthetic": lambda: synthetic(per_group, seed=seed),
            "tilted": lambda: tilted(per_group, seed=seed),
            "blurred": lambda: blurred(3 * per_group, seed=seed),
            "cloth": lambda: cloth(per_group, seed=seed),
            "fine": lambda: fine(per_group, seed=seed),
            "classics": lambda: classics(max(2, per_group), seed=seed),
            "woven": lambda: woven(2 * per_group, seed=seed),
            "twill": lambda: woven(2 * per_group, seed=seed, weave="twill"),
            "lineart": lambda: lineart(per_group, seed=seed),
            "sublattice": lambda: sublattice(per_group, seed=seed),
            "plain": lambda: plain(max(2, per_group), seed=seed),
            "photos": photos,
            "frames": lambda: photos(whole=True),
            "crops": photo_crops,
            "turns": photo_turns,
            "views": photo_views,
            "degraded": photo_degraded,
            "closer": photo_closer,
            "renderings": lambda: renderings(per_group, seed=seed),
            "waves": lambda: waves(per_group, seed=seed),
            "npm": lambda: npm(per_group, seed=seed),
            "npm-as-written": lambda: npm_as_written(per_group, seed=seed)}


def run(per_group: int = 3, *, seed: int = 0, verbose: bool = True, cv: bool = True,
        sources: tuple[str, ...] = ("synthetic", "tilted", "blurred", "cloth", "fine",
                                    "classics", "woven", "twill", "lineart", "sublattice",
                                    "renderings", "waves", "plain", "photos", "frames",
                                    "crops", "turns", "views", "degraded", "closer",
                                    "npm", "npm-as-written")
        ) -> dict:
    makers = _sources(per_group, seed)
    samples = []
    for name in sources:
        for s in makers[name]():
            s.found = evaluate(s)
            samples.append(s)
            if verbose:
                f = s.found
                print(f"{s.source:11s} {s.name:28s} truth {s.truth:8s} -> "
                      f"{f['group'] or f['kind']!s:8s} {f['outcome']:13s} conf {f['conf']:.2f}"
                      f" lattice {f['lattice_ok']!s:5s} strength {f['strength']:.2f}"
                      f" {f['sec']:.2f} s",
                      flush=True)
    text = (f"## Vision (`python -m bench vision`, {date.today().isoformat()}, "
            f"{platform.machine()}, {per_group} per group)\n\n" + report(samples))
    # Outside references are evaluation only: no constant is fitted or picked on them.
    own = [s for s in samples if s.source not in OUTSIDE]
    if own:
        text += "\n\nConfidence calibration: " + fit_temperature(own)
    if cv and own:
        text += "\n\nLeave-one-source-out cross-validation:\n\n" + cross_validate(own)
        # Ties go to the stricter test (a lower own asymmetry, then share, refused).
        text += ("\n\nLeave-one-source-out cross-validation of the consistency test:\n\n"
                 + cross_validate(own, CONSISTENCY_GRID,
                                  ("own_asymmetry", "shared_asymmetry"),
                                  (OWN_ASYMMETRY, SHARED_ASYMMETRY),
                                  safer=lambda cfg: (-cfg[0], -cfg[1])))
    print(text)
    return {"samples": samples, "markdown": text}


def option_effect(option: str = "above_yarn", per_group: int = 2, seed: int = 0,
                  sources: tuple[str, ...] = ("woven", "plain", "cloth", "classics",
                                              "synthetic", "photos")) -> str:
    """Each sample read twice in one process, with ``detect_fabric``'s switch
    ``option`` off and on (``above_yarn``: the yarn smoothed away; ``true_repeat``: the
    lattice's step checked against the repeats): outcomes and lattices per source, and
    every image whose answer changed."""
    makers = _sources(per_group, seed)
    rows, changed = [], []
    for name in sources:
        counts, images = {False: {}, True: {}}, 0
        for s in makers[name]():
            got, images = {}, images + 1
            for on in (False, True):
                f = evaluate(s, with_baseline=False, **{option: on})
                for key in (f["outcome"], f"lattice {f['lattice_ok']}"):
                    counts[on][key] = counts[on].get(key, 0) + 1
                got[on] = (f"{f['group'] or f['kind']} ({f['outcome']}, {f['conf']:.2f}, "
                           f"lattice {f['lattice_ok']})")
            if got[False] != got[True]:
                changed.append(f"- {s.source} {s.name} (truth {s.truth}): {got[False]} -> "
                               f"{got[True]}")
        rows.append(f"| {name} | {images} | "
                    + " | ".join(", ".join(f"{k} {v}" for k, v in sorted(counts[on].items()))
                                 for on in (False, True)) + " |")
    text = (f"| source | images | {option} off | {option} on |\n|---|---|---|---|\n"
            + "\n".join(rows) + "\n\nChanged:\n\n" + ("\n".join(changed) or "none"))
    print(text)
    return text


def yarn_effect(per_group: int = 2, seed: int = 0,
                sources: tuple[str, ...] = ("woven", "plain", "cloth", "classics",
                                            "synthetic", "photos")) -> str:
    """:func:`option_effect` of the yarn smoothing (the command BENCHMARKS.md records)."""
    return option_effect("above_yarn", per_group, seed, sources)


def speed(frames: int = 3, seed: int = 0, fine_prints: bool = False,
          **options: bool) -> list[float]:
    """Seconds of ``detect_fabric`` (with ``options``) on 4000x3000 camera frames (one
    core's work): the ``synthetic`` source's, or the ``fine`` source's (hundreds of
    repeats) with ``fine_prints``."""
    frames_of = fine(1, size=(4000, 3000), seed=seed) if fine_prints else synthetic(
        1, size=(4000, 3000), seed=seed)
    secs, cpu = [], []
    for s in itertools.islice(frames_of, frames):
        t0, c0 = time.perf_counter(), time.process_time()
        detect_fabric(s.image, mm_per_px=s.mm_per_px, **options)
        secs.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    print(f"detect_fabric on {frames} 4000x3000 frames: wall "
          f"{', '.join(f'{v:.2f}' for v in secs)} s; CPU (all threads) "
          f"{', '.join(f'{v:.2f}' for v in cpu)} s")
    return secs


def main() -> None:
    run()
    speed()
