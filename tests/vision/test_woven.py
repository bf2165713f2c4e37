"""Yarn-dyed woven checks: the print is read above the yarn.

Each crossing of a woven gingham shows the colour of the thread on top, warp or weft
in plain-weave order, so at thread scale the cloth is pmm or p4
(:func:`simulators.classics.woven_check`); it was designed p4m. The detector finds the
yarn's repeat, smooths it away and reads the group above it; an uneven woven check
keeps pmm (no quarter turn invented), and plain cloth, whose only structure is its
yarn, stays plain.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import vision.pipeline as pipeline
from bench.vision import woven
from simulators.classics import classic_print, woven_check
from simulators.cloth import plain_cloth
from simulators.fabric import random_print, render_print
from vision.lattice import prepare_image, yarn_repeat
from vision.pipeline import CONFIRM_BELOW, detect_fabric
from vision.subgroups import error_kind


def _yarn(img: np.ndarray, mm: float) -> float:
    flat, scale = prepare_image(img)
    return yarn_repeat(flat, mm / scale)


@pytest.mark.parametrize(("threads", "repeat", "mm", "turn"),
                         [(10, 8.0, 0.1, 20.0), (16, 12.0, 0.08, 63.0), (7, 9.0, 0.12, 0.0)])
def test_the_yarn_repeat_is_the_plain_weaves_two_thread_diagonal(threads, repeat, mm, turn):
    img = render_print(woven_check(repeat, threads, rotation=turn), (64.0, 48.0), mm)
    thread = repeat / (2 * threads)
    assert _yarn(img, mm) == pytest.approx(math.sqrt(2) * thread, rel=0.1)


def test_printed_checks_and_prints_show_no_yarn():
    mm = 0.1
    for pr in (classic_print("gingham", 10.0, rotation=20.0),
               classic_print("tartan", 14.0, rotation=5.0),
               random_print("p4m", 9.0, rotation=30.0, seed=3),
               random_print("p6", 12.0, seed=4)):
        assert math.isnan(_yarn(render_print(pr, (64.0, 48.0), mm), mm)), pr.name


@pytest.fixture(scope="module")
def woven_samples():
    return list(woven(3, seed=11))  # 6 ginghams (p4m), 3 uneven checks (pmm)


def _outcomes(samples):
    out = []
    for s in samples:
        det = detect_fabric(s.image, mm_per_px=s.mm_per_px)
        out.append((error_kind(det.classification.group, s.truth),
                    det.classification.confidence, det.lattice.found))
    return out


def test_woven_checks_read_as_designed_never_more(woven_samples):
    outcomes = _outcomes(woven_samples)
    assert all(found for _, _, found in outcomes), outcomes
    assert not any(kind == "supergroup" for kind, _, _ in outcomes), outcomes
    for kind, conf, _ in outcomes:
        assert kind in ("right", "subgroup"), outcomes
        if kind == "subgroup":  # a safe error must go to the operator
            assert conf < CONFIRM_BELOW, outcomes
    assert sum(kind == "right" for kind, _, _ in outcomes) >= len(outcomes) - 1, outcomes


def test_read_at_thread_scale_the_same_checks_lose_their_group(woven_samples, monkeypatch):
    """What the smoothing buys: without it most of the same cloths read wrong."""
    monkeypatch.setattr(pipeline, "yarn_repeat", lambda *a, **k: float("nan"))
    outcomes = _outcomes(woven_samples)
    assert sum(kind == "right" for kind, _, _ in outcomes) <= len(outcomes) // 2, outcomes


def test_twill_woven_checks_never_gain_symmetry_and_unsure_ones_go_to_the_operator():
    """2/2 twill breaks every mirror thread by thread; above the yarn most read as
    designed, and the rest as subgroups below the operator's threshold."""
    outcomes = _outcomes(list(woven(4, seed=5, weave="twill")))
    for kind, conf, found in outcomes:
        assert found and kind in ("right", "subgroup"), outcomes
        if kind == "subgroup":
            assert conf < CONFIRM_BELOW, outcomes
    assert sum(kind == "right" for kind, _, _ in outcomes) >= len(outcomes) // 2, outcomes


@pytest.mark.parametrize("weave", ["plain", "twill"])
def test_plain_cloth_whose_yarn_shows_stays_plain(weave):
    seen = 0
    for seed, (mm, thread) in enumerate(((0.05, 0.3), (0.08, 0.45), (0.1, 0.6))):
        img = plain_cloth((900, 700), thread / mm, weave=weave, seed=seed)
        seen += bool(np.isfinite(_yarn(img, mm)))
        det = detect_fabric(img, mm_per_px=mm)
        assert det.lattice.kind == "plain", (weave, thread, det.lattice.message)
        assert det.classification.group is None
    assert seen >= 2  # the case this is about: the yarn found, nothing above it
