"""Near-symmetric prints: a bold layer with more symmetry than the print, broken by thin
faint strokes (the failure the npm ``wallpaper-groups`` reference showed: a p1 drawing
whose bold bars are their own half turns read as p2). Simulator images only
(``simulators.lineart``); the outside reference itself needs node and stays in the
benchmark."""

from __future__ import annotations

import numpy as np
import pytest

from simulators.lineart import degrade, layered_print
from solver.wallpaper import GROUPS
from vision.classify import Classification, classify
from vision.decision import ADDED_OPERATION_LAG, lagging_subgroup
from vision.groupfit import GroupFit
from vision.lattice import detect_lattice
from vision.subgroups import error_kind


def _classify(group: str, faint: str, seed: int) -> tuple[str, Classification]:
    rng = np.random.default_rng(seed)
    img, truth, _ = layered_print(group, rng.uniform(30, 50), (320, 240), seed=seed,
                                  faint_contrast=(0.5, 0.7), faint_ops=GROUPS[faint].ops)
    img = degrade(img, rng, blur=1.0, noise=3.0, jpeg=(80, 95))
    return truth, classify(img, detect_lattice(img, mm_per_px=0.25))


def _read(group: str, faint: str, seed: int) -> tuple[str, str | None]:
    truth, found = _classify(group, faint, seed)
    return truth, found.group


def test_a_group_over_p1_must_not_lag_behind_the_translations():
    """p1's only operations are the translations (score: the reliability, 1 here, less
    the single repeats' disagreement): a half turn scoring 0.94 lags them by 0.06, more
    than allowed on alike repeats, and is allowed when repeats differ by 0.08."""
    rot = ((-1, 0, 0, -1), "rot")
    best = {"p1": GroupFit(0.0, None, None, [], frozenset()),
            "p2": GroupFit(1.0, None, None, [], frozenset({rot}))}
    assert lagging_subgroup("p2", best, {rot: 0.94}, 1.0, ADDED_OPERATION_LAG) == (
        "p1", pytest.approx(0.06))
    assert not lagging_subgroup("p2", best, {rot: 0.99}, 1.0, ADDED_OPERATION_LAG)
    assert not lagging_subgroup("p2", best, {rot: 0.94}, 1.0 - 0.08, ADDED_OPERATION_LAG)


def test_bold_half_turns_with_faint_asymmetric_strokes_are_mostly_p1():
    outcomes = []
    for seed in range(12):
        truth, found = _read("p2", "p1", seed)
        assert truth == "p1"  # measured on the drawing: the faint strokes break the turn
        outcomes.append(found)
    assert set(outcomes) <= {"p1", "p2"}, outcomes
    # Before the translations counted as p1's operations: p2 on 9 of these 12.
    assert outcomes.count("p2") <= 4, outcomes


def test_the_operator_is_told_why_a_likelier_group_was_not_taken():
    """Where the bold half turns make p2 the likelier group but the answer is p1, the
    message names p2, its probability and the check it failed."""
    told = 0
    for seed in range(12):
        _, found = _classify("p2", "p1", seed)
        post = found.posterior
        if found.group == "p1" and post["p2"] > post["p1"]:
            assert found.message.startswith(f"p2 is likelier ({post['p2']:.2f}) but not "
                                            "taken: "), found.message
            assert "half turn" in found.message or "translations" in found.message
            told += 1
        elif found.group == "p2":
            assert "not taken" not in found.message, found.message
    assert told >= 1


def test_true_line_prints_keep_their_group():
    kinds = []
    for i, group in enumerate(("p2", "pm", "pg", "cm", "pmm", "p4")):
        for seed in (100 + i, 200 + i):
            truth, found = _read(group, group, seed)
            kinds.append(error_kind(found, truth))
    assert kinds.count("supergroup") == 0, kinds
    assert kinds.count("right") >= 11, kinds
