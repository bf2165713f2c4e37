"""Nesting: place pieces on the roll, densely, without losing the print alignment."""

from solver.nest.instance import Item, NestProblem, Piece, load_esicup
from solver.nest.lattice import nest_lattice
from solver.nest.layout import Layout, Placed, build_layout, verify_layout
from solver.nest.naive import nest_naive
from solver.nest.plain import nest_plain

__all__ = ["Item", "Layout", "NestProblem", "Piece", "Placed", "build_layout", "load_esicup",
           "nest_lattice", "nest_naive", "nest_plain", "verify_layout"]
