"""A cutting room's order: styles x sizes x quantities, read as untrusted input.

An order file (TOML, or the same in JSON) names each style's pattern relative to the order
file and how many garments of each size to cut::

    name = "PO-1234"
    [[garment]]
    pattern = "MEN_CLASSIC_TEE.DXF"
    sizes = { "48" = 1, "50" = 2, "52" = 1 }
    units = "in"            # optional, when the pattern file does not say

``match_notches = true`` (optional, at the top) puts every garment's balance notches where
the print's lattice lines cross its seams, as ``--match-notches`` does for one garment.
A pattern without sizes (OBJ, pattern JSON) gives ``copies = N`` instead of ``sizes``.
Everything that could make the order fail later (a missing or escaping pattern path, an
unknown size, a quantity of 0, too many garments) is refused here, with one line naming
the order file, before any garment is loaded or aligned.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import untrusted
from solver.garment.allowance import AllowanceRules
from solver.garment.dxf_file import read_blocks, texts
from solver.units import mm_per_unit
from untrusted import limits

MAX_ORDER_GARMENTS = 60  # garments (style x size x copy) aligned and nested in one marker
MAX_STYLES = 20
MAX_QUANTITY = 60  # garments of one size
_SIZE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,15}$")  # one word: it names G-code pieces
_KEYS = {"name", "garment", "match_notches"}
_GARMENT_KEYS = {"pattern", "sizes", "copies", "units"}


@dataclass(frozen=True)
class OrderGarment:
    """One garment to cut: a style's pattern in one size (None: ungraded), copy 1, 2, ..."""

    pattern: Path
    size: str | None
    copy: int
    units: str | None = None

    @property
    def style(self) -> str:
        return re.sub(r"[^A-Za-z0-9_-]+", "_", self.pattern.stem)

    @property
    def label(self) -> str:
        """The garment's one-word name in layouts, pictures and G-code piece markers."""
        return "-".join([self.style, *([self.size] if self.size else []), str(self.copy)])


@dataclass(frozen=True)
class Order:
    """An order's garments in the file's order, each copy its own garment."""

    name: str
    source: Path
    garments: tuple[OrderGarment, ...]
    match_notches: bool = False

    def job_options(self, options: dict[str, Any]) -> dict[str, Any]:
        """A job's ``options`` with what the order file asks for the whole marker (its
        ``match_notches``; the job's own option, when given, wins)."""
        return {"match_notches": True, **options} if self.match_notches else dict(options)

    def rules(self, rules: AllowanceRules) -> AllowanceRules:
        """A command line's allowance ``rules`` with the order's ``match_notches``."""
        return replace(rules, notch_on_print=True) if self.match_notches else rules

    def ratio(self) -> dict[str, int]:
        """Garments per size (the marker's size ratio), in the order's order."""
        out: dict[str, int] = {}
        for g in self.garments:
            out[g.size or "-"] = out.get(g.size or "-", 0) + 1
        return out

    def ratio_text(self) -> str:
        """``44:1 50:1 56:1``: the size ratio as a marker maker writes it."""
        return " ".join(f"{s}:{n}" for s, n in self.ratio().items())

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "source": str(self.source), "ratio": self.ratio(),
                "match_notches": self.match_notches,
                "garments": [{"garment": g.label, "pattern": str(g.pattern), "size": g.size,
                              "copy": g.copy, "units": g.units} for g in self.garments]}


def is_order_file(path: str | Path) -> bool:
    """Whether ``path`` names an order: a .toml file, or a .json of at most 1 MiB whose
    top holds ``garment`` (a list of styles)."""
    path = Path(path)
    if path.suffix.lower() == ".toml":
        return True
    if path.suffix.lower() != ".json" or not path.is_file():
        return False
    if path.stat().st_size > limits.MAX_TOML_BYTES:  # an order is small: a big JSON is a
        return False  # garment, never parsed twice (nor in the daemon, before the check)
    try:
        data = untrusted.read_json(path, what="order file", max_bytes=limits.MAX_TOML_BYTES)
    except untrusted.InputError:
        return False
    return isinstance(data, dict) and isinstance(data.get("garment"), list)


def read_order(path: str | Path) -> Order:
    """The order in ``path``, every garment checked; an InputError names what is wrong."""
    path = Path(path)
    data = _order_data(path)
    _no_unknown_keys(data, _KEYS, path, "the order")
    name = untrusted.text(data.get("name", path.stem), path, "name", max_len=80)
    styles = data.get("garment")
    if not isinstance(styles, list) or not styles:
        raise untrusted.InputError(path, "the order lists no [[garment]]")
    if len(styles) > MAX_STYLES:
        raise untrusted.InputError(path, f"{len(styles)} styles; an order holds at most "
                                   f"{MAX_STYLES}")
    garments: list[OrderGarment] = []
    for k, style in enumerate(styles):
        garments += _style_garments(style, path, f"garment[{k}]")
        if len(garments) > MAX_ORDER_GARMENTS:
            raise untrusted.InputError(path, f"more than {MAX_ORDER_GARMENTS} garments; cut "
                                       "the order into several markers")
    match_notches = data.get("match_notches", False)
    if not isinstance(match_notches, bool):
        raise untrusted.InputError(path, f"match_notches = {match_notches!r}: true or false")
    return Order(name, path, tuple(garments), match_notches)


def _no_unknown_keys(d: dict, known: set[str], path: Path, where: str) -> None:
    unknown = sorted(set(d) - known)
    if unknown:
        raise untrusted.InputError(path, f"{where}: unknown key {unknown[0]!r} (known: "
                                   f"{', '.join(sorted(known))})")


def _style_garments(style: Any, path: Path, where: str) -> list[OrderGarment]:
    """The garments of one ``[[garment]]`` table: its pattern found beside the order, its
    sizes checked against the pattern's, each quantity expanded into copies."""
    if not isinstance(style, dict):
        raise untrusted.InputError(path, f"{where} is not a table")
    _no_unknown_keys(style, _GARMENT_KEYS, path, where)
    pattern = _pattern_path(style.get("pattern"), path, where)
    units = style.get("units")
    if units is not None:
        units = untrusted.text(units, path, f"{where}.units", max_len=8)
        try:
            mm_per_unit(units)
        except ValueError as exc:
            raise untrusted.InputError(path, f"{where}.units: {exc}") from None
    if ("sizes" in style) == ("copies" in style):
        raise untrusted.InputError(path, f"{where}: give sizes = {{ \"50\" = 2, ... }} for a "
                                   "graded pattern, or copies = N for one without sizes")
    if "copies" in style:
        wanted = {None: _quantity(style["copies"], path, f"{where}.copies")}
    else:
        wanted = _sizes(style["sizes"], pattern, path, where)
    return [OrderGarment(pattern, size, c + 1, units)
            for size, n in wanted.items() for c in range(n)]


def _pattern_path(value: Any, order: Path, where: str) -> Path:
    """The pattern file, named relative to the order file's folder and never outside it."""
    path = order.parent / _relative_pattern(value, order, where)
    untrusted.check_file(path, what=f"pattern of {where}", max_bytes=limits.MAX_DXF_BYTES)
    return path


def _relative_pattern(value: Any, order: Path, where: str) -> str:
    """A pattern's name inside the order file's folder: no absolute path and no ``..``
    (a link the order's owner placed in the folder is theirs to make)."""
    rel = untrusted.text(value, order, f"{where}.pattern", max_len=255)
    parts = Path(rel).parts
    if not rel.strip() or Path(rel).is_absolute() or ".." in parts or "\\" in rel:
        raise untrusted.InputError(order, f"{where}.pattern {rel[:60]!r}: give a path inside "
                                   "the order file's folder, relative to it")
    return rel


def order_patterns(path: str | Path) -> list[str]:
    """The pattern names an order file gives (relative to it), read from the order alone:
    what a submission copies beside the order before any pattern is parsed."""
    path = Path(path)
    data = _order_data(path)
    styles = data.get("garment")
    if not isinstance(styles, list) or not 0 < len(styles) <= MAX_STYLES:
        raise untrusted.InputError(path, f"an order lists 1 to {MAX_STYLES} [[garment]]")
    return list(dict.fromkeys(
        _relative_pattern(s.get("pattern") if isinstance(s, dict) else None, path,
                          f"garment[{k}]") for k, s in enumerate(styles)))


def _order_data(path: Path) -> dict[str, Any]:
    data = (untrusted.read_toml(path, what="order file") if path.suffix.lower() == ".toml"
            else untrusted.read_json(path, what="order file",
                                     max_bytes=limits.MAX_TOML_BYTES))
    if not isinstance(data, dict):
        raise untrusted.InputError(path, "an order is a table with name and [[garment]]")
    return data


def _quantity(value: Any, path: Path, where: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise untrusted.InputError(path, f"{where} = {value!r}: a quantity is a whole number")
    if not 1 <= value <= MAX_QUANTITY:
        raise untrusted.InputError(path, f"{where} = {value}: a quantity is 1 to "
                                   f"{MAX_QUANTITY} (leave a size out to cut none)")
    return value


def _sizes(value: Any, pattern: Path, path: Path, where: str) -> dict[str | None, int]:
    """``{size: quantity}`` with every size one the pattern file grades."""
    if not isinstance(value, dict) or not value:
        raise untrusted.InputError(path, f"{where}.sizes: give sizes as {{ \"50\" = 2 }}")
    for size in value:
        if not _SIZE.match(size):
            raise untrusted.InputError(path, f"{where}.sizes: {size[:20]!r} is not a size name")
    graded = pattern_sizes(pattern)
    missing = [s for s in value if s not in graded]
    if missing:
        have = f"sizes are {', '.join(graded)}" if graded else "it has no sizes (copies = N)"
        raise untrusted.InputError(path, f"{where}: {pattern.name} has no size "
                                   f"{', '.join(missing)}; {have}")
    return {s: _quantity(q, path, f"{where}.sizes.{s}") for s, q in value.items()}


def pattern_sizes(pattern: Path) -> list[str]:
    """The sizes a pattern file grades (a DXF's ``Size:`` texts; other formats: none)."""
    if pattern.suffix.lower() != ".dxf":
        return []
    try:
        _, _, blocks = read_blocks(pattern)
    except ValueError as exc:
        raise untrusted.InputError(pattern, str(exc)) from None
    return [s for s in dict.fromkeys(texts(ents).get("size") for _, ents in blocks) if s]
