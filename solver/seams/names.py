"""What a piece's name says about where it sits: front, back, sleeve, ...; left or right.

Pattern makers name pieces in short codes (FR, BK, SL) or words in their own language;
a few common ones are enough to prefer a sleeve-to-body seam over a sleeve-to-sleeve one.
"""

from __future__ import annotations

import re
from functools import lru_cache

__all__ = ["front_or_back", "name_affinity", "name_parts"]

_KINDS = {
    "front": ("front", "fr", "frt", "ftorso", "vorder", "vorderteil", "devant", "delantero",
              "davanti", "frente", "voor", "f"),
    "back": ("back", "bk", "bck", "btorso", "ruecken", "rücken", "hinter", "dos", "espalda",
             "dietro", "espalda", "achter", "rug", "b"),
    "sleeve": ("sleeve", "sl", "slv", "arm", "aermel", "ärmel", "manche", "manga", "manica",
               "mouw"),
    "collar": ("collar", "co", "neck", "band", "rib", "kragen", "col", "cuello", "colletto"),
    "waistband": ("waistband", "wb", "waist", "bund", "ceinture", "cintura"),
    "cuff": ("cuff", "manschette", "poignet", "puño"),
}
_SIDES = {"left": ("left", "l", "lft", "links", "gauche", "izquierda", "sinistra"),
          "right": ("right", "r", "rt", "rechts", "droite", "derecha", "destra")}
_PLACES = frozenset(("front", "back"))
_LONG = sorted({w for words in _KINDS.values() for w in words if len(w) >= 4}, key=len,
               reverse=True)
# seams a garment usually has, between kinds of pieces (order does not matter)
_USUAL = {frozenset(p) for p in [("front", "back"), ("sleeve", "front"), ("sleeve", "back"),
                                 ("collar", "front"), ("collar", "back"), ("sleeve", "cuff"),
                                 ("waistband", "front"), ("waistband", "back"), ("front",),
                                 ("back",), ("sleeve",)]}


@lru_cache(maxsize=4096)  # asked for every candidate seam: a pattern has few names
def _tokens(name: str) -> tuple[str, ...]:
    spaced = re.sub(r"([a-z])([A-Z])", r"\1 \2", name)
    words = [w for w in re.split(r"[^0-9A-Za-zÀ-ÿ]+", spaced.lower()) if w]
    out = []
    for w in words:  # "teefr": a known code glued to the end of a word
        out.append(w)
        for code in ("fr", "bk", "sl", "co", "wb"):
            if w.endswith(code) and len(w) > len(code) + 2:
                out.append(code)
        for word in _LONG:  # "lfsleeve": left front sleeve, one letter each
            head = w[:-len(word)]
            if w.endswith(word) and head and len(head) <= 2 and set(head) <= set("lrfb"):
                out += [word, *head]
    return tuple(out)


@lru_cache(maxsize=4096)
def _raw_kinds(name: str) -> frozenset[str]:
    """Every kind a word of the name says, a sleeve's front or back half included."""
    toks = _tokens(name)
    return frozenset(k for k, words in _KINDS.items() for t in toks if t in words)


def name_parts(name: str) -> tuple[frozenset[str], str | None]:
    """(kinds, side) the name says: kinds from :data:`_KINDS`, side "left"/"right"/None."""
    toks = _tokens(name)
    kinds = _raw_kinds(name)
    if "sleeve" in kinds:  # "sleeve_f": the front half of a sleeve, still a sleeve
        kinds -= {"front", "back"}
    sides = {s for s, words in _SIDES.items() for t in toks if t in words}
    return kinds, (sides.pop() if len(sides) == 1 else None)


def _role(name: str) -> tuple[frozenset[str], str | None]:
    """(what the piece is, which half it joins): a sleeve, collar, waistband or cuff is what
    it is, its "front"/"back" only says where it sits ("wb_back": a waistband of the back);
    a piece with no such kind is a front or a back."""
    raw = _raw_kinds(name)
    specific = raw - _PLACES
    place = raw & _PLACES
    if specific:
        return specific, (next(iter(place)) if len(place) == 1 else None)
    return place, None


def front_or_back(name: str) -> tuple[frozenset[str], str] | None:
    """(what the piece is, besides a front or a back; "front" or "back") where the name says
    exactly one of the two ("sleeve_f": a sleeve's front half), else None."""
    raw = _raw_kinds(name)
    place = raw & _PLACES
    return (frozenset(raw - _PLACES), next(iter(place))) if len(place) == 1 else None


def _placement_affinity(a: str, b: str) -> float:
    """+0.25 when a piece that sits on the front (back) meets a front (back) piece, -0.5
    when it meets the other one (a back waistband to a front bodice)."""
    (ka, qa), (kb, qb) = _role(a), _role(b)
    score = 0.0
    for q, other in ((qa, kb), (qb, ka)):
        if q and other and other <= _PLACES:
            score += 0.25 if q in other else -0.5
    return score


def name_affinity(a: str, b: str) -> float:
    """How much the two names favour a seam between the pieces: about -1.5 (a right piece to
    a left one) to +0.75 (a sleeve's back half to a back on the same side)."""
    (ka, sa), (_, sb) = name_parts(a), name_parts(b)
    score = 0.0
    if sa and sb and sa == sb:
        score += 0.25
    elif sa and sb:  # left to right: only the centre seam between two halves of one kind
        # (a right sleeve's back half never meets a left sleeve's front half)
        score += 0.0 if ka and _raw_kinds(a) == _raw_kinds(b) else -1.0
    (role_a, _), (role_b, _) = _role(a), _role(b)
    if role_a and role_b:
        usual = any(frozenset((x, y)) in _USUAL for x in role_a for y in role_b)
        score += 0.25 if usual else -0.25
    return score + _placement_affinity(a, b)
