"""Wallpaper alignment (paper Sec. 4): per piece a rotation and a translation of the
print so that it runs on, or mirrors, across the seams.

    placement = align(garment, fabric, method="paper" | "global", restarts=15, seed=0)
"""

from solver.align.driver import METHODS, align, parse_fix
from solver.align.global_ import align_global
from solver.align.restarts import AlignResult, align_paper

__all__ = ["METHODS", "AlignResult", "align", "align_global", "align_paper", "parse_fix"]
