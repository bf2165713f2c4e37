"""A job's seam allowances: station.toml [allowance], then the job's own options.

One place for the precedence, used by the commands (``--seam-allowance``, ``--allowance``)
and by the daemon (job options ``seam_allowance`` and ``allowance``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from typing import Any

from solver.garment.allowance import AllowanceRules
from station.config import Config


def rules_for(config: Config, seam_mm: float | None = None,
              overrides: Mapping[int | str, float] | None = None,
              source: str = "") -> AllowanceRules:
    """The rules: the station's defaults, the per-name overrides (from the file
    ``source``, named in their errors), then ``seam_mm``."""
    a = config["allowance"]
    rules = AllowanceRules(a["seam_mm"], a["hem_mm"], a["opening_mm"],
                           notch_depth_mm=a["notch_depth_mm"],
                           notch_spacing_mm=a["notch_spacing_mm"])
    more: dict[int | str, float] = dict(overrides or {})
    if seam_mm is not None:
        more["seam"] = float(seam_mm)
    return rules.with_overrides(more, source) if more else rules


def name_key(key: str) -> int | str:
    """A seam-line index for a key of ASCII digits (at most 9), else the name itself.

    ``str.isdigit`` alone also takes '²' or a 5000-digit key, which ``int`` refuses."""
    return int(key) if key.isascii() and key.isdigit() and len(key) <= 9 else key


def rules_for_job(config: Config, options: Mapping[str, Any]) -> AllowanceRules:
    """The rules of a submitted job (options ``seam_allowance`` MM, ``allowance`` {name: MM},
    ``match_notches``: balance notches on the print's lattice lines, as ``--match-notches``).

    JSON keys are strings: digit keys become seam-line indices, as in ``--allowance``.
    """
    given = options.get("allowance") or {}
    if not isinstance(given, Mapping):
        raise ValueError('job option allowance must be an object {"seam line": mm}')
    overrides = {name_key(k) if isinstance(k, str) else k: v for k, v in given.items()}
    seam = options.get("seam_allowance")
    if seam is not None and (isinstance(seam, bool) or not isinstance(seam, (int, float))
                             or seam < 0):
        raise ValueError(f"job option seam_allowance must be a number >= 0, got {seam!r}")
    rules = rules_for(config, seam, overrides)
    return replace(rules, notch_on_print=options.get("match_notches") is True)
