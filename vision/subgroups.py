"""Which wallpaper groups are subgroups of which: the safe and the unsafe errors.

Reading a print as a subgroup of its group (p4m as pmm) loses alignment freedom but
never places a piece on a symmetry that is not there; reading it as a supergroup
invents one. ``SUBGROUPS[g]`` lists every group isomorphic to a subgroup of ``g``
(any index, ``g`` itself included), from the maximal t- and k-subgroups of the
International Tables for Crystallography, Vol. A, closed under inclusion. Three
pairs contain each other (pm/cm, pmm/cmm, p3m1/p31m): confusing them swaps mirrors for
glides, so it counts as neither safe nor supergroup but as "other".
"""

from __future__ import annotations

__all__ = ["SUBGROUPS", "error_kind", "is_subgroup"]

_RECT = ("p1", "p2", "pm", "pg", "cm", "pmm", "pmg", "pgg", "cmm")

SUBGROUPS: dict[str, frozenset[str]] = {
    "p1": frozenset({"p1"}),
    "p2": frozenset({"p1", "p2"}),
    "pm": frozenset({"p1", "pm", "pg", "cm"}),
    "pg": frozenset({"p1", "pg"}),
    "cm": frozenset({"p1", "pm", "pg", "cm"}),
    "pmm": frozenset(_RECT),
    "pmg": frozenset({"p1", "p2", "pm", "pg", "cm", "pmg", "pgg"}),
    "pgg": frozenset({"p1", "p2", "pg", "pgg"}),
    "cmm": frozenset(_RECT),
    "p4": frozenset({"p1", "p2", "p4"}),
    "p4m": frozenset(_RECT + ("p4", "p4m", "p4g")),
    "p4g": frozenset(_RECT + ("p4", "p4g")),
    "p3": frozenset({"p1", "p3"}),
    "p3m1": frozenset({"p1", "pm", "pg", "cm", "p3", "p3m1", "p31m"}),
    "p31m": frozenset({"p1", "pm", "pg", "cm", "p3", "p3m1", "p31m"}),
    "p6": frozenset({"p1", "p2", "p3", "p6"}),
    "p6m": frozenset(_RECT + ("p3", "p3m1", "p31m", "p6", "p6m")),
}


def is_subgroup(h: str, g: str) -> bool:
    """True when group ``h`` is (isomorphic to) a subgroup of ``g``."""
    return h in SUBGROUPS[g]


def error_kind(found: str | None, truth: str, alt: str | None = None) -> str:
    """"right" (the group or the labelled alternative), "subgroup" (safe), "supergroup"
    (an invented symmetry), "other" (neither) or "missed" (no lattice found)."""
    if found is None:
        return "missed"
    if found in (truth, alt):
        return "right"
    down, up = is_subgroup(found, truth), is_subgroup(truth, found)
    if down and not up:
        return "subgroup"
    if up and not down:
        return "supergroup"
    return "other"
