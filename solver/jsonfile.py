"""Reading the station's JSON files: the checked reader of :mod:`untrusted`.

Kept as the solver's import point; the reading itself (size, UTF-8, NaN/inf, nesting) is
:func:`untrusted.read_json`.
"""

from __future__ import annotations

from untrusted import read_json

__all__ = ["read_json"]
