"""Fixtures of the vision tests; the helpers live in ``synth_prints.py`` next to them.

The suite runs with ``--import-mode=importlib``, so test directories are not on
``sys.path``: the helper module is loaded here by path and handed out as a fixture.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

_spec = importlib.util.spec_from_file_location(
    "vision_synth_prints", Path(__file__).with_name("synth_prints.py"))
synth_prints = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(synth_prints)


@pytest.fixture
def vt():
    """Synthetic prints, stripes, camera faults and the lattice/origin error measures."""
    return synth_prints


@pytest.fixture
def make_print():
    return synth_prints.synth


@pytest.fixture
def make_stripes():
    return synth_prints.stripes
