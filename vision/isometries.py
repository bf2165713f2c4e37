"""The isometries of a lattice (integer matrices in its basis: its holohedry) and their
scores on a mean cell at every translation part at once. Because an isometry is an
integer matrix, ``M(A f)`` is an exact permutation of the cell's grid: no interpolation
blurs the test."""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from vision.consistency import beyond_rounding, rounding_slack

__all__ = ["correlation_at_shifts", "holohedry", "isometry_key", "isometry_label",
           "isometry_name", "reflection_classes", "rounded_score"]

def holohedry(basis: np.ndarray, tol: float = 0.2) -> list[np.ndarray]:
    """Integer matrices A (in the basis' fractional coordinates), A != I, that are
    isometries of the lattice up to ``tol`` (relative), i.e. A^T G A = G."""
    g = basis.T @ basis
    out = []
    for e in np.array(np.meshgrid(*[(-1, 0, 1)] * 4, indexing="ij")).reshape(4, -1).T:
        a = e.reshape(2, 2).astype(float)
        if abs(abs(np.linalg.det(a)) - 1) > 1e-9 or np.allclose(a, np.eye(2)):
            continue
        if np.abs(a.T @ g @ a - g).max() <= tol * np.trace(g) / 2:
            out.append(a.astype(int))
    return out


def isometry_key(a: np.ndarray) -> tuple[int, ...]:
    """A hashable key of the integer matrix ``a``: its entries, row by row."""
    return tuple(np.asarray(a).ravel().tolist())


def isometry_label(a: np.ndarray, basis: np.ndarray) -> str:
    """A short label of ``a`` as an isometry of the plane with lattice ``basis``:
    ``rot<order>(<degrees>)`` or ``refl(<axis degrees>)``, as the scores are keyed."""
    lin = basis @ a @ np.linalg.inv(basis)
    if np.linalg.det(lin) > 0:
        ang = round(math.degrees(math.atan2(lin[1, 0], lin[0, 0])) % 360)
        return f"rot{360 // math.gcd(360, ang)}({ang})"
    ev, vec = np.linalg.eig(lin)
    v = np.real(vec[:, np.argmax(np.real(ev))])
    return f"refl({round(math.degrees(math.atan2(v[1], v[0])) % 180)})"


def isometry_name(a: np.ndarray, basis: np.ndarray | None = None) -> str:
    """An isometry of a lattice (integer matrix ``a`` in its basis) in words: a turn's
    order follows from the integer trace, a reflection's axis (given ``basis``, working
    px) from the basis."""
    if round(np.linalg.det(a)) == 1:
        return {-2: "half turn", -1: "third turn", 0: "quarter turn",
                1: "sixth turn"}.get(int(round(np.trace(a))), "turn")
    if basis is None:
        return "reflection"
    return f"reflection at {isometry_label(a, basis)[5:-1]} degrees"


def correlation_at_shifts(motif: np.ndarray, a: np.ndarray) -> np.ndarray:
    """T[s] = <M(f), M(A f + s)> / <M, M> for every grid shift s (n, n)."""
    n = motif.shape[0]
    g = np.arange(n)
    fa, fb = np.meshgrid(g, g, indexing="ij")
    src_a = (a[0, 0] * fa + a[0, 1] * fb) % n
    src_b = (a[1, 0] * fa + a[1, 1] * fb) % n
    p = motif[src_a, src_b]  # P(f) = M(A f)
    fm = np.fft.fft2(motif)
    r = np.fft.ifft2(np.conj(fm) * np.fft.fft2(p)).real / max(float((motif**2).sum()), 1e-12)
    # T(s) = R(A^-1 s): gather on the grid (A^-1 is an integer matrix too).
    ainv = np.rint(np.linalg.inv(a)).astype(int)
    ta = (ainv[0, 0] * fa + ainv[0, 1] * fb) % n
    tb = (ainv[1, 0] * fa + ainv[1, 1] * fb) % n
    return r[ta, tb]


def rounded_score(motif: np.ndarray, a: np.ndarray, shift: np.ndarray,
                   rounding: np.ndarray) -> float:
    """:func:`correlation_at_shifts` at one ``shift`` of a cell that repeats by whole pixels,
    less what rounding its edges to the grid explains (:func:`vision.consistency.rounding_slack`):
    1 - |M - M(A f + s)|^2 / 2|M|^2, the residual taken beyond that slack."""
    n = motif.shape[0]
    g = np.arange(n)
    fa, fb = np.meshgrid(g, g, indexing="ij")
    image = motif[(a[0, 0] * fa + a[0, 1] * fb + shift[0]) % n,
                  (a[1, 0] * fa + a[1, 1] * fb + shift[1]) % n]
    slack = rounding_slack(np.fft.fft2(motif), np.fft.fft2(image), rounding)
    left = beyond_rounding(motif - image, slack)
    return 1.0 - float((left**2).sum()) / max(2.0 * float((motif**2).sum()), 1e-12)


def reflection_classes(a: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    return _reflection_classes_cached(isometry_key(a), n)


@lru_cache(maxsize=256)
def _reflection_classes_cached(key: tuple[int, ...], n: int) -> tuple[np.ndarray, np.ndarray]:
    """Boolean (n, n) masks of the shifts s for which (A, s) is a mirror, or a glide.

    (A, s) is a symmetry only if its square (A + I) s is a lattice vector; it is a
    mirror (up to a lattice translation) when s lies in the image of (I - A) on the
    torus, and a glide otherwise.
    """
    a = np.array(key, int).reshape(2, 2)
    g = np.arange(n)
    ka, kb = np.meshgrid(g, g, indexing="ij")
    ap = a + np.eye(2, dtype=int)
    valid = ((ap[0, 0] * ka + ap[0, 1] * kb) % n == 0) & ((ap[1, 0] * ka + ap[1, 1] * kb)
                                                          % n == 0)
    im = np.eye(2, dtype=int) - a
    g2 = np.arange(2 * n)
    oa, ob = np.meshgrid(g2, g2, indexing="ij")
    sa = im[0, 0] * oa + im[0, 1] * ob
    sb = im[1, 0] * oa + im[1, 1] * ob
    even = (sa % 2 == 0) & (sb % 2 == 0)
    mirror = np.zeros((n, n), bool)
    mirror[(sa[even] // 2) % n, (sb[even] // 2) % n] = True
    return mirror & valid, valid & ~mirror
