"""Topology of a triangle mesh given as index arrays: its connected components and its
boundary half-edges.

The garment model, the specification importer, the openings and the symmetriser all ask
these two questions; they live here, below every garment module, so that none of those
imports another only for them.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components as _scipy_components


def connected_components(n: int, pairs: np.ndarray) -> tuple[int, np.ndarray]:
    """Connected components of an n-vertex graph given (k, 2) vertex pairs: their number
    and the (n,) label of each vertex."""
    graph = coo_matrix(
        (np.ones(len(pairs), dtype=np.int8), (pairs[:, 0], pairs[:, 1])), shape=(n, n)
    )
    return _scipy_components(graph, directed=False)


def loop_edge_keys(loops: list[np.ndarray], n: int) -> np.ndarray:
    """Key ``a * n + b`` of every edge a->b of the closed vertex ``loops`` of an n-vertex
    mesh (directed as the loops run, which is as in the faces for a piece's outline),
    loop after loop."""
    return np.concatenate([lp * n + np.roll(lp, -1) for lp in loops])


def edge_keys(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    """Key of each undirected edge a-b of an n-vertex mesh (the same both ways round)."""
    return np.minimum(a, b).astype(np.int64) * n + np.maximum(a, b)


def boundary_half_edges(he: np.ndarray, n: int) -> np.ndarray:
    """The (k, 2) half-edges of ``he`` (all half-edges of an n-vertex mesh) that have no
    twin, i.e. whose undirected edge occurs once."""
    key = edge_keys(he[:, 0], he[:, 1], n)
    _, inv, counts = np.unique(key, return_inverse=True, return_counts=True)
    return he[counts[inv] == 1]
