"""solver.nest is layered: the engine sits below the strategies, and no import circle holds.

The circle lattice -> naive -> regions -> lattice once held only because some imports sat
inside functions; these tests read every import (also inside functions) with ``ast``.
"""

from __future__ import annotations

import ast
import graphlib
import subprocess
import sys
from pathlib import Path

import pytest

import solver.nest

NEST = Path(solver.nest.__file__).parent
ROOT = NEST.parent.parent


def module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


MODULES = sorted(module_name(p) for p in NEST.glob("*.py"))


def nest_imports(path: Path) -> set[str]:
    """Every solver.nest module ``path`` imports, wherever the import statement sits."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            # ``from solver.nest import engine`` names a submodule, ``... import Piece`` the package
            names = [f"{node.module}.{a.name}" if f"{node.module}.{a.name}" in MODULES
                     else node.module for a in node.names]
        else:
            continue
        out |= {n for n in names if n in MODULES}
    return out


def import_graph() -> dict[str, set[str]]:
    return {module_name(p): nest_imports(p) - {module_name(p)} for p in NEST.glob("*.py")}


def test_the_nest_import_graph_has_no_cycle():
    graph = import_graph()
    assert len(graph) == len(MODULES) >= 10
    assert "solver.nest.regions" in graph["solver.nest.lattice"]  # the parse sees real edges
    try:
        order = list(graphlib.TopologicalSorter(graph).static_order())
    except graphlib.CycleError as exc:
        pytest.fail(f"import circle in solver.nest: {' -> '.join(exc.args[1])}")
    # the engine sits below every module that searches with it
    users = [m for m, deps in graph.items() if "solver.nest.engine" in deps]
    assert users and all(order.index(u) > order.index("solver.nest.engine") for u in users)


def test_cycle_detection_sees_imports_inside_functions(tmp_path):
    """The parser must not miss a lazy import (that is how the old circle hid)."""
    src = tmp_path / "m.py"
    src.write_text("def f():\n    from solver.nest.lattice import nest_lattice\n")
    assert nest_imports(src) == {"solver.nest.lattice"}


@pytest.mark.parametrize("module", MODULES)
def test_each_nest_module_imports_alone_in_a_fresh_interpreter(module):
    run = subprocess.run([sys.executable, "-c", f"import {module}"], cwd=ROOT,
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
