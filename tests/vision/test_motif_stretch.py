"""``bench.vision.stretch_scores``: how far a print must be stretched for each isometry
of its lattice to map it onto itself. The evidence behind issue 15's last photograph
(a knitted check whose quarter turn the image does not carry); checked here on prints
whose symmetry is known."""

from __future__ import annotations

import numpy as np

from bench.vision import Sample, stretch_scores
from simulators.cloth import stretch
from simulators.fabric import random_print, render_print
from vision.classify import HOLOHEDRY_TOL

STRETCHES = (0.0, 0.2)


def _quarter_turns(group: str, cloth_stretch: float) -> list[list[float]]:
    pr = random_print(group, 40.0, seed=7,
                      w1=np.array([40.0, 0.0]), w2=np.array([0.0, 40.0]))
    img = render_print(pr, (400.0, 400.0), 1.0)
    jac = np.eye(2)
    if cloth_stretch:
        img, jac = stretch(img, 1.0 + cloth_stretch, angle_deg=30.0)
    s = Sample("test", group, img, 1.0, group, basis=jac @ pr.wallpaper.basis)
    return [scores for _, kind, scores in stretch_scores(s, STRETCHES, tol=HOLOHEDRY_TOL)
            if kind == "quarter turn"]


def test_a_p4m_print_needs_no_stretch_even_on_stretched_cloth():
    """The lattice's own frame undoes the cloth's stretch: the quarter turn holds as it
    is, and stretching its image only loses the match."""
    for cloth in (0.0, 0.12):
        turns = _quarter_turns("p4m", cloth)
        assert len(turns) == 2
        for scores in turns:
            assert scores[0] > 0.97, (cloth, scores)
            assert scores[0] > scores[1] + 0.1, (cloth, scores)


def test_a_pmm_print_on_a_square_lattice_has_no_quarter_turn_at_any_stretch():
    for scores in _quarter_turns("pmm", 0.0):
        assert max(scores) < 0.9, scores
