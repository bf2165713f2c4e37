"""GRBL 1.1 line pre-parser and word reader: a received line stripped as the protocol loop
does, split into words, and the words sorted into modal groups and values with the errors
GRBL finds while reading them (gcode.c's first step)."""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field

import simulators.grbl.codes as C
from simulators.grbl.parser_state import GrblError

_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)")


def preparse(raw: bytes) -> tuple[str, bool]:
    """Strip a received line as GRBL's protocol loop does; return (line, overflowed).

    Whitespace and control characters are dropped, `(...)` and `;` comments removed, `/` block
    delete ignored, letters upper-cased, and more than LINE_BUFFER_SIZE-1 (79) significant
    characters flag a line overflow (error:11).
    """
    out: list[str] = []
    paren = semicolon = overflow = False
    for byte in raw:
        c = chr(byte)
        if paren or semicolon or overflow:
            if c == ")" and paren:
                paren = False
            continue
        if byte <= 0x20 or c == "/":
            continue
        if c == "(":
            paren = True
        elif c == ";":
            semicolon = True
        elif len(out) >= C.LINE_BUFFER_SIZE - 1:
            overflow = True
        else:
            out.append(c.upper() if "a" <= c <= "z" else c)
    return "".join(out), overflow


def split_words(line: str) -> list[tuple[str, float]]:
    """`G1X10.5F300` -> [("G",1.0),("X",10.5),("F",300.0)]; error:1 / error:2 on bad syntax."""
    words = []
    i = 0
    while i < len(line):
        letter = line[i]
        if not ("A" <= letter <= "Z"):
            raise GrblError(C.E_EXPECTED_COMMAND_LETTER)
        m = _NUMBER.match(line, i + 1)
        if m is None:
            raise GrblError(C.E_BAD_NUMBER_FORMAT)
        words.append((letter, float(m.group())))
        i = m.end()
    return words


# Modal groups of the G and M words GRBL 1.1 accepts (commands.md "Modal Group Meaning").
_G_GROUPS = {
    4: 0, 10: 0, 28: 0, 30: 0, 53: 0, 92: 0,
    0: 1, 1: 1, 2: 1, 3: 1, 80: 1,
    17: 2, 18: 2, 19: 2,
    90: 3, 91: 3,
    93: 5, 94: 5,
    20: 6, 21: 6,
    40: 7,
    43: 8, 49: 8,
    54: 12, 55: 12, 56: 12, 57: 12, 58: 12, 59: 12,
    61: 13,
}  # fmt: skip
_G_MANTISSAS = {28: {0, 10}, 30: {0, 10}, 92: {0, 10}, 91: {0, 10}, 43: {10}}  # else {0}
_AXIS_NONMODAL = {10, 28, 30, 92}  # non-modal commands whose axis words are theirs
_M_GROUPS = {0: 4, 1: 4, 2: 4, 30: 4, 3: 7, 4: 7, 5: 7, 8: 8, 9: 8}
AXIS = {"X": 0, "Y": 1, "Z": 2}  # axis letter -> index
_VALUE_LETTERS = set("FIJKLNPRSTXYZ")


@dataclass
class Words:
    """The words of one block sorted by kind, as gcode.c's first step leaves them."""

    g: dict[int, tuple[int, int]] = field(default_factory=dict)  # group -> (G, mantissa x100)
    m: dict[int, int] = field(default_factory=dict)  # group -> M number
    values: dict[str, float] = field(default_factory=dict)  # letter -> value
    axis_command: str | None = None  # "nonmodal" | "motion": who owns the axis words


def read_words(line: str) -> Words:
    """Sort a block's words into modal groups and values; the first bad word's error."""
    words = Words()
    for letter, value in split_words(line):
        _WORD_READERS.get(letter, _read_value)(words, letter, value)
    return words


def _claim_axes(words: Words, command: str) -> None:
    if words.axis_command:
        raise GrblError(C.E_GCODE_AXIS_COMMAND_CONFLICT)
    words.axis_command = command


def _read_g(words: Words, letter: str, value: float) -> None:
    number = int(value)
    mantissa = int(round(100 * (value - number)))
    if number not in _G_GROUPS:  # G38.x too: no probe on a cutter
        raise GrblError(C.E_GCODE_UNSUPPORTED_COMMAND)
    if mantissa not in _G_MANTISSAS.get(number, {0}):
        if number == 90 or (number == 43 and mantissa == 0):
            raise GrblError(C.E_GCODE_UNSUPPORTED_COMMAND)
        raise GrblError(C.E_GCODE_COMMAND_VALUE_NOT_INTEGER)
    group = 4 if (number, mantissa) == (91, 10) else _G_GROUPS[number]  # G91.1: arc IJK mode
    if group == 0 and number in _AXIS_NONMODAL and mantissa == 0:
        _claim_axes(words, "nonmodal")
    elif group == 1:
        _claim_axes(words, "motion")
    if group in words.g:
        raise GrblError(C.E_GCODE_MODAL_GROUP_VIOLATION)
    words.g[group] = (number, mantissa)


def _read_m(words: Words, letter: str, value: float) -> None:
    number = int(value)
    if value != number:
        raise GrblError(C.E_GCODE_COMMAND_VALUE_NOT_INTEGER)
    if number not in _M_GROUPS:
        raise GrblError(C.E_GCODE_UNSUPPORTED_COMMAND)  # M7 needs ENABLE_M7
    group = _M_GROUPS[number]
    if group in words.m:
        raise GrblError(C.E_GCODE_MODAL_GROUP_VIOLATION)
    words.m[group] = number


def _read_value(words: Words, letter: str, value: float) -> None:
    if letter not in _VALUE_LETTERS:
        raise GrblError(C.E_GCODE_UNSUPPORTED_COMMAND)
    if letter in words.values:
        raise GrblError(C.E_GCODE_WORD_REPEATED)
    if letter in "FNPST" and value < 0:
        raise GrblError(C.E_NEGATIVE_VALUE)
    words.values[letter] = value


_WORD_READERS: dict[str, Callable[[Words, str, float], None]] = {"G": _read_g, "M": _read_m}
