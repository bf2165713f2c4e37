"""Reading untrusted input: files, JSON, TOML and parsed values, checked before any work.

The bottom of the package graph: ``solver``, ``gcode``, ``vision``, ``simulators`` and
``station`` may all import it, and it imports none of them. Every fault is an
:class:`InputError` whose text is the one line ``FILE: fault`` the commands print before
exiting with status 2. The limits live in :mod:`untrusted.limits`.
"""

from untrusted import limits
from untrusted.errors import InputError
from untrusted.files import (
    MissingInput,
    check_file,
    copy_file,
    decode_text,
    read_bytes,
    read_text,
)
from untrusted.images import read_image
from untrusted.shapes import count, integer, mapping, matrix, number, points, sequence, text, vector
from untrusted.structured import check_tree, parse_json, parse_toml, read_json, read_toml

__all__ = [
    "InputError", "MissingInput", "check_file", "check_tree", "copy_file", "count", "decode_text",
    "integer", "limits", "mapping", "matrix", "number", "parse_json", "parse_toml", "points",
    "read_bytes", "read_image", "read_json", "read_text", "read_toml", "sequence", "text",
    "vector",
]
