"""Benchmark of the vision pipeline on synthetic 4000x3000 camera frames.

Every image: a random print of one of the 17 groups (``simulators.fabric``), turned by
0-90 degrees, with a repeat that shows 3 to 30 repeats across the frame, photographed
by the synthetic camera (``simulators.camera``: lens, light ramp and vignetting, blur,
noise, JPEG), rectified onto the table with the camera's calibration, and then given
the residual geometric faults a real set-up leaves: a perspective error (frame corners
moved by up to 5 %) and a smooth fold displacement (up to 3 px). Each image stresses one
perturbation family at a random strength over its whole range; the others stay mild.

Truth: the print's lattice in table mm, carried into the final image by the Jacobian
of the residual warp at the image centre (a perspective error changes the lattice
across the frame; the centre is where the pipeline reports it).

Reported: lattice success (found lattice = true one up to a unimodular change of basis,
vectors within 3 %), median relative error of w1 and w2, group accuracy with the
confusion matrix, per-family results, and seconds of ``detect_fabric`` per image.

    python -m bench vision                         # 20 images per group, 4000x3000
    python -c "from bench.vision import run; run(per_group=20, size=(1600, 1200))"
    python -c "from bench.vision import report_from_log as r; r('run.log', 20, (1600, 1200))"

A 4000x3000 frame takes the synthetic camera several seconds to render on a loaded
machine, so accuracy is also measured on 1600x1200 frames (the detector works on a
1024-pixel working image either way) and the speed on 4000x3000 ones.
"""

from __future__ import annotations

import math
import platform
import time
from datetime import date

import cv2
import numpy as np

from simulators.camera import CameraModel, Imaging, Pose, Sheet, SyntheticCamera
from simulators.fabric import random_print
from solver.wallpaper import GROUP_NAMES, gauss_reduce
from vision.calibration import Calibration
from vision.pipeline import detect_fabric
from vision.rectify import rectify

FAMILIES = ("rotation-scale", "perspective", "blur", "noise", "jpeg", "light", "fold")


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


def _lattice_ok(found: np.ndarray, truth: np.ndarray) -> tuple[bool, float]:
    """(same lattice within 3 %, largest relative vector error)."""
    t1, t2, _ = gauss_reduce(truth[:, 0], truth[:, 1])
    t = np.column_stack([t1, t2])
    u = np.linalg.solve(t, found)
    ur = np.round(u)
    if abs(abs(np.linalg.det(ur)) - 1) > 1e-9 or np.abs(u - ur).max() > 0.3:
        return False, float("inf")
    err = float(np.max(np.linalg.norm(found - t @ ur, axis=0) / np.linalg.norm(found, axis=0)))
    return err < 0.03, err


def run(per_group: int = 20, size: tuple[int, int] = (4000, 3000), seed: int = 0,
        verbose: bool = True, groups: tuple[str, ...] = GROUP_NAMES) -> dict:
    cam = CameraModel.default(size)
    height = 1000.0
    mm_px = height / cam.K[0, 0]
    field_mm = size[0] * mm_px
    rows = []
    for gi, group in enumerate(GROUP_NAMES):
        if group not in groups:
            continue
        for k in range(per_group):
            rng = np.random.default_rng(seed + 1000 * gi + k)
            family = FAMILIES[k % len(FAMILIES)]
            p = _params(family, rng)
            repeats = math.exp(rng.uniform(math.log(3), math.log(30)))
            pr = random_print(group, field_mm / repeats, rotation=rng.uniform(0, 90),
                              seed=int(rng.integers(1 << 30)))
            imaging = Imaging(light_ramp=p["ramp"], vignetting=p["vignetting"],
                              blur=p["blur"], noise=p["noise"], jpeg_quality=p["jpeg"])
            big = 3.0 * field_mm  # a sheet larger than the view (size=None is not supported)
            sheet = Sheet(pr, size=(big, big), shift=(-big / 2, -big / 2))
            sim = SyntheticCamera(sheet, camera=cam, imaging=imaging,
                                  poses=[Pose.overhead((0.0, 0.0), height)],
                                  seed=int(rng.integers(1 << 30)))
            frame = sim.read()
            hom = np.linalg.inv(sim.truth.homography)
            cal = Calibration(cam.K, cam.dist, cam.resolution, homography=hom / hom[2, 2])
            img, region, s = rectify(frame, cal)
            img, jac = _residual_warp(img, p, rng)
            truth = sim.truth.wallpaper
            t0 = time.perf_counter()
            det = detect_fabric(img, mm_per_px=s, offset=region[:2])
            sec = time.perf_counter() - t0
            tb = jac @ truth.basis
            ok, err = (False, float("inf"))
            if det.lattice.found:
                ok, err = _lattice_ok(det.lattice.basis, tb)
            rows.append(dict(group=group, family=family, found=det.classification.group,
                             ok=ok, err=err, sec=sec, shape=img.shape[:2],
                             repeats=repeats))
            if verbose:
                print(f"{group:5s} {family:15s} repeats {repeats:5.1f} -> "
                      f"{det.classification.group!s:5s} lattice {'ok ' if ok else 'BAD'} "
                      f"err {err:.4f} {sec:.2f} s", flush=True)
    return _report(rows, per_group, size)


def _report(rows: list[dict], per_group: int, size: tuple[int, int]) -> dict:
    n = len(rows)
    ok = np.array([r["ok"] for r in rows])
    errs = np.array([r["err"] for r in rows if np.isfinite(r["err"])])
    right = np.array([r["found"] == r["group"] for r in rows])
    secs = np.array([r["sec"] for r in rows])
    lines = [
        f"## Vision (`python -m bench vision`, {date.today().isoformat()}, "
        f"{platform.machine()}, {per_group} images per group, {size[0]}x{size[1]} frames)",
        "",
        f"- lattice success: {ok.mean() * 100:.1f} % ({ok.sum()}/{n})",
        f"- median relative error of w1, w2: {np.median(errs) * 100:.3f} %"
        if len(errs) else "- median relative error: n/a",
        f"- group accuracy: {right.mean() * 100:.1f} % ({right.sum()}/{n})",
        f"- seconds per image (detect_fabric: lattice, group, origin, distortion): "
        f"median {np.median(secs):.2f}, max {secs.max():.2f}",
        "",
        "| family | images | lattice ok | median err % | group ok |",
        "|---|---|---|---|---|",
    ]
    for fam in FAMILIES:
        sel = [r for r in rows if r["family"] == fam]
        if not sel:
            continue
        e = [r["err"] for r in sel if np.isfinite(r["err"])]
        lines.append(f"| {fam} | {len(sel)} | {sum(r['ok'] for r in sel)} | "
                     f"{np.median(e) * 100 if e else float('nan'):.3f} | "
                     f"{sum(r['found'] == r['group'] for r in sel)} |")
    lines += ["", "Confusion matrix (rows: truth, columns: found; '-' = no lattice):", "",
              "| truth \\ found | " + " | ".join(GROUP_NAMES) + " | - |",
              "|---" * (len(GROUP_NAMES) + 2) + "|"]
    for g in GROUP_NAMES:
        cells = [sum(1 for r in rows if r["group"] == g and r["found"] == h)
                 for h in GROUP_NAMES]
        none = sum(1 for r in rows if r["group"] == g and r["found"] is None)
        lines.append(f"| {g} | " + " | ".join(str(c) if c else "." for c in cells)
                     + f" | {none or '.'} |")
    text = "\n".join(lines)
    print(text)
    return {"lattice_success": float(ok.mean()), "median_error": float(np.median(errs))
            if len(errs) else float("nan"), "group_accuracy": float(right.mean()),
            "seconds_median": float(np.median(secs)), "markdown": text}


def report_from_log(path: str, per_group: int, size: tuple[int, int]) -> dict:
    """The report from the per-image lines a (possibly interrupted) run printed."""
    rows = []
    with open(path) as fh:
        for line in fh:
            parts = line.split()
            if len(parts) != 12 or parts[2] != "repeats" or parts[4] != "->":
                continue
            rows.append(dict(group=parts[0], family=parts[1],
                             found=None if parts[5] == "None" else parts[5],
                             ok=parts[7] == "ok", err=float(parts[9]), sec=float(parts[10]),
                             repeats=float(parts[3])))
    return _report(rows, per_group, size)


def main(per_group: int = 20, size: tuple[int, int] = (4000, 3000)) -> None:
    run(per_group=per_group, size=size)
