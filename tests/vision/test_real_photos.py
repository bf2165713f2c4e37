"""The hand-labelled real photographs of ../shared/data/fabric_photos (read in place,
never copied: their rights are unclear). Each gets its group or the labelled
alternative, or a safe subgroup with a confidence that sends it to the operator; never
a supergroup; plain cloth and stripes never a 2-D lattice; labelled lattices are found.
"""

from __future__ import annotations

import numpy as np
import pytest

from bench.vision import PHOTOS, evaluate, photo_crops, photo_turns, photo_views, photos
from vision.pipeline import CONFIRM_BELOW

pytestmark = pytest.mark.skipif(not (PHOTOS / "labels.csv").is_file(),
                                reason=f"the labelled photographs are not here ({PHOTOS}): "
                                       "they live outside the project, in ../shared")


@pytest.fixture(scope="module")
def results():
    return [(s, evaluate(s, with_baseline=False)) for s in photos()]


def test_every_labelled_photo_is_read(results):
    assert len(results) >= 10


def test_groups_are_right_or_safe_and_then_go_to_the_operator(results):
    for s, f in results:
        if s.truth in ("plain", "stripes"):
            continue
        assert f["outcome"] in ("right", "subgroup"), (s.name, f)
        if f["outcome"] == "subgroup":  # a safe error must not pass unconfirmed
            assert f["conf"] < CONFIRM_BELOW, (s.name, f)
    right = sum(f["outcome"] == "right" for s, f in results)
    assert right >= len(results) - 1


def test_no_supergroup_and_no_lattice_on_plain_cloth_or_stripes(results):
    for s, f in results:
        assert f["outcome"] not in ("supergroup", "false lattice", "other"), (s.name, f)
        if s.truth in ("plain", "stripes"):
            assert f["kind"] == s.truth or f["kind"] == s.alt, (s.name, f)


def test_labelled_lattices_are_found(results):
    for s, f in results:
        if f["lattice_ok"] is not None:
            assert f["lattice_ok"], (s.name, f)


@pytest.fixture(scope="module")
def crops():
    return [(s, evaluate(s, with_baseline=False)) for s in photo_crops(per_photo=8, seed=0)]


def _repeats_across(s) -> float:
    """How many labelled repeats fit across the crop's shorter side, along the longer
    lattice vector: below three no lattice can be told from the image."""
    return min(s.image.shape[:2]) / float(np.linalg.norm(s.basis, axis=0).max())


def test_cropped_rescaled_turned_photos_keep_their_answers(crops):
    """Each photograph cropped to 60-90 %, rescaled 0.6-1.4 times and turned: the same
    cloth, so the same answer, or a safe one that goes to the operator."""
    assert len(crops) >= 80
    for s, f in crops:
        assert f["outcome"] not in ("supergroup", "false lattice", "other"), (s.name, f)
        if f["outcome"] == "subgroup":
            assert f["conf"] < CONFIRM_BELOW, (s.name, f)
    right = sum(f["outcome"] == "right" for _, f in crops)
    assert right >= 0.8 * len(crops)
    # The lattice, where three repeats fit (a label holds at its region's centre only:
    # a crop of a photograph in perspective sees another part of it).
    seen = [f for s, f in crops if s.basis is not None and _repeats_across(s) >= 3]
    assert all(f["outcome"] != "missed" for f in seen)
    assert sum(bool(f["lattice_ok"]) for f in seen) >= 0.9 * len(seen)


@pytest.fixture(scope="module")
def turns():
    return [(s, evaluate(s, with_baseline=False)) for s in photo_turns(per_photo=3, seed=0)]


def test_photos_turned_off_the_axes_keep_their_answers(turns):
    """Each photograph turned by angles off the axes (its threads and shading bands
    across the pixel grid): plain cloth still has no lattice (turned, its shading bands
    made one of two repeats across), no answer is a supergroup or on a wrong lattice,
    and a safe subgroup goes to the operator."""
    assert len(turns) >= 30
    for s, f in turns:
        assert f["outcome"] not in ("supergroup", "false lattice", "other"), (s.name, f)
        if f["outcome"] == "subgroup":
            assert f["conf"] < CONFIRM_BELOW, (s.name, f)
    assert sum(f["outcome"] == "right" for _, f in turns) >= 0.7 * len(turns)
    seen = [f for s, f in turns if s.basis is not None and _repeats_across(s) >= 3]
    assert all(f["outcome"] != "missed" and f["lattice_ok"] for f in seen)


def test_photos_seen_in_perspective_never_pass_a_subgroup_unconfirmed():
    """Each photograph seen with one side of the frame shrunk 10-30 %: no supergroup,
    no lattice on plain cloth, and a subgroup goes to the operator (a dotted p4m seen
    that steeply read as cmm at 0.99 before the groups that hold only beyond the snap
    weighed against the answer). Where three repeats fit, a lattice is found."""
    views = [(s, evaluate(s, with_baseline=False)) for s in photo_views(per_photo=3, seed=0)]
    assert len(views) >= 30
    for s, f in views:
        assert f["outcome"] not in ("supergroup", "false lattice", "other"), (s.name, f)
        if f["outcome"] == "subgroup":
            assert f["conf"] < CONFIRM_BELOW, (s.name, f)
        if s.basis is not None and _repeats_across(s) >= 3:
            assert f["outcome"] != "missed", (s.name, f)
    assert sum(f["outcome"] == "right" for _, f in views) >= 0.6 * len(views)


def test_whole_photographs_are_read_or_sent_to_the_operator():
    """The ten photographs as taken: collars, pockets and drape around the garments'
    cloth, and line-scan frames whose repeat is a few working pixels. A printed cloth
    is never reported plain or stripes, a plain one never gets a lattice, no answer
    is a supergroup, and a subgroup goes to the operator."""
    frames = [(s, evaluate(s, with_baseline=False)) for s in photos(whole=True)]
    assert len(frames) >= 10
    for s, f in frames:
        if s.truth in ("plain", "stripes"):
            # No lattice either way: a striped tee amid the table around it reads plain
            # (its labelled region, above, reads its stripes).
            assert f["kind"] in ("plain", "stripes"), (s.name, f)
            continue
        assert f["kind"] == "lattice", (s.name, f)
        assert f["outcome"] in ("right", "subgroup"), (s.name, f)
        if f["outcome"] == "subgroup":
            assert f["conf"] < CONFIRM_BELOW, (s.name, f)
