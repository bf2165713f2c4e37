"""The subgroup table behind "never a supergroup": closed, and true to the symmetry."""

from __future__ import annotations

import pytest

from solver.wallpaper import GROUP_NAMES, GROUPS
from vision.subgroups import SUBGROUPS, error_kind, is_subgroup


def test_every_group_and_only_those_are_listed():
    assert set(SUBGROUPS) == set(GROUP_NAMES)
    for g, subs in SUBGROUPS.items():
        assert {g, "p1"} <= subs <= set(GROUP_NAMES)


def test_inclusion_is_transitive():
    for g in GROUP_NAMES:
        for h in SUBGROUPS[g]:
            assert SUBGROUPS[h] <= SUBGROUPS[g], (h, g)


def test_a_subgroup_never_has_more_point_symmetry_a_rotation_or_mirror_the_group_lacks():
    for g in GROUP_NAMES:
        for h in SUBGROUPS[g]:
            a, b = GROUPS[h], GROUPS[g]
            assert len(a.ops) <= len(b.ops), (h, g)  # point-group orders
            assert b.rotation_order % a.rotation_order == 0, (h, g)
            assert b.has_mirror or not a.has_mirror, (h, g)


@pytest.mark.parametrize(("found", "truth", "alt", "kind"), [
    ("p4m", "p4m", None, "right"), ("pmm", "p4m", "pmm", "right"),
    ("pmm", "p4m", None, "subgroup"), ("p1", "cmm", None, "subgroup"),
    ("p4m", "pmm", None, "supergroup"), ("p6m", "p3m1", None, "supergroup"),
    ("cmm", "pmm", None, "other"), ("p3", "p2", None, "other"),
    (None, "p2", None, "missed")])
def test_error_kinds(found, truth, alt, kind):
    assert error_kind(found, truth, alt) == kind


def test_mirrors_are_never_subgroups_of_rotation_only_groups():
    for g in ("p2", "p3", "p4", "p6"):
        assert not any(is_subgroup(h, g) for h in ("pm", "pg", "cm"))
