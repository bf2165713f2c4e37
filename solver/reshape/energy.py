"""The pattern energy of paper Eq. (10), its terms and analytic gradients.

    E = E_prox + alpha E_conf + beta sum_f phi_f(A_f) + 1/(2 gamma) sum_e w_e (c_e / l0_e)^2
        + sum_v psi_v(|u_v - u0_v|)

Every term is vectorised over seam vertices, faces or seam edges (sparse matrices and
``np.bincount``); ``uv`` is always the (V,2) pattern in millimetres and every gradient has
the same shape.

- E_prox (Eq. 11): squared distance of seam vertices to their ideal positions, each
  weighted by its share of seam length (`solver.reshape.ideal`), so the sum approximates
  an integral along the seams and keeps its balance with E_conf under mesh refinement.
- E_conf: the LSCM / conformal energy E_D - A of Mullen et al. (2008), "Spectral
  Conformal Parameterization", with the input pattern as the reference shape. Per face
  it is ``A0/2 ((a-d)^2 + (b+c)^2)`` with Jacobian ``[[a, b], [c, d]]``: zero for every
  similarity, so the input pattern is its minimum. It is quadratic: ``1/2 u^T Q u``.
  Departures: a little Dirichlet energy of the displacement is added (5 % by default,
  `stiffened_conformal_matrix`), which keeps free boundaries from wiggling on fine
  meshes and pieces from growing or shrinking; and a bending energy of the outline's
  displacement (`outline_bending_matrix`) smooths away short notches. Both are constant
  quadratics and live in the same matrix ``q`` as E_conf.
- phi_f: the barrier of Schüller, Kavan, Panozzo and Sorkine-Hornung (2013), "Locally
  Injective Mappings": ``1/g(A/s) - 1`` with ``g(x) = x^3 - 3x^2 + 3x`` below the
  threshold area ``s`` (a fraction of the input area), 0 above it and +inf at or below
  zero area, so no flipped or degenerate triangle has finite energy.
- psi_v: a barrier on each vertex's move from the input pattern, zero below 90 % of
  ``max_move`` and +inf at it (`move_barrier`): a pattern maker accepts a bounded change,
  so the bound is a constraint (the line search never crosses it), not a weight.
- The same form on each piece's area change keeps it within ``area_tol`` (1 %) of the
  input area (`area_barrier`, step cap `max_area_step`).
- The twin-length penalty uses ``c_e = |e|^2 - |e'|^2`` as in the paper, divided by the
  input length ``l0_e`` of the pair so that gamma is dimensionless and means the same in
  mm or inches (the constraint c_e = 0 is unchanged); its weight ``w_e`` includes
  ``unit / l0_e`` so that it, too, integrates along the seam. By default each pair keeps
  instead the length difference it was drafted with (the seam's ease), in mm
  (`length_penalty`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from solver.geometry import edge_vectors, signed_areas

if TYPE_CHECKING:
    from solver.reshape.outline import OutlineGuard


def _corners(uv: np.ndarray, faces: np.ndarray):
    p = uv[faces]  # one gather (F,3,2)
    return p[:, 0], p[:, 1], p[:, 2]


def area_gradients(uv: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F,3,2) derivative of each face's signed area by its three corners."""
    a, b, c = _corners(uv, faces)
    g = np.empty((len(faces), 3, 2))
    for k, (p, q) in enumerate(((b, c), (c, a), (a, b))):
        g[:, k, 0] = 0.5 * (p[:, 1] - q[:, 1])
        g[:, k, 1] = 0.5 * (q[:, 0] - p[:, 0])
    return g


def _scatter(n: int, idx: np.ndarray, vals: np.ndarray) -> np.ndarray:
    """Sum (N,2) values into (n,2) rows ``idx`` (vectorised np.add.at)."""
    return np.stack([np.bincount(idx, weights=vals[:, 0], minlength=n),
                     np.bincount(idx, weights=vals[:, 1], minlength=n)], -1)


# ---------------------------------------------------------------------- E_prox
def prox_energy(uv: np.ndarray, vertex: np.ndarray, target: np.ndarray,
                weight: np.ndarray) -> tuple[float, np.ndarray]:
    """Eq. (11): ``sum w ||p - p_ideal||^2`` and its (V,2) gradient."""
    d = uv[vertex] - target
    e = float(np.sum(weight * np.einsum("ki,ki->k", d, d)))
    return e, _scatter(len(uv), vertex, 2.0 * weight[:, None] * d)


# ---------------------------------------------------------------------- E_conf
def gradient_operators(uv_ref: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per face the (3,2) gradients of the three hat functions and the reference area."""
    a, b, c = _corners(uv_ref, faces)
    m = np.stack([b - a, c - a], -1)  # (F,2,2) columns e1 e2
    ginv = np.linalg.inv(m)  # rows: d(local coords)/d(x, y)
    d = np.empty((len(faces), 3, 2))
    d[:, 1], d[:, 2] = ginv[:, 0], ginv[:, 1]
    d[:, 0] = -(d[:, 1] + d[:, 2])
    return d, 0.5 * np.abs(np.linalg.det(m))


def conformal_matrix(uv_ref: np.ndarray, faces: np.ndarray) -> sp.csr_matrix:
    """Q (2V,2V), interleaved x/y, with E_conf(uv) = 1/2 uv.ravel() Q uv.ravel()."""
    return stiffened_conformal_matrix(uv_ref, faces, 0.0)


def dirichlet_laplacian(uv_ref: np.ndarray, faces: np.ndarray) -> sp.csr_matrix:
    """Cotangent Laplacian (V,V): the Hessian of the Dirichlet energy per coordinate."""
    d, area = gradient_operators(uv_ref, faces)
    k = np.einsum("fid,fjd->fij", d, d) * area[:, None, None]
    rows = np.repeat(faces, 3, axis=1).ravel()
    cols = np.tile(faces, (1, 3)).ravel()
    n = len(uv_ref)
    return sp.csr_matrix((k.ravel(), (rows, cols)), shape=(n, n))


def conformal_energy(uv: np.ndarray, q: sp.csr_matrix,
                     rest: np.ndarray | None = None) -> tuple[float, np.ndarray]:
    """1/2 d^T Q d with d = uv - rest (uv itself without ``rest``), and its (V,2) gradient.

    For the conformal matrix Q rest = 0 (the rest shape is conformal to itself), so the
    displacement form equals 1/2 u^T Q u; it matters once Q carries a stiffness that
    does not vanish on the rest shape (`stiffened_conformal_matrix`).
    """
    d = uv.ravel() if rest is None else (uv - rest).ravel()
    g = q @ d
    return 0.5 * float(np.einsum("i,i->", d, g)), g.reshape(-1, 2)


def stiffened_conformal_matrix(uv_ref: np.ndarray, faces: np.ndarray,
                               dirichlet: float) -> sp.csr_matrix:
    """Q + ``dirichlet`` (L (x) I2): the conformal matrix plus a little Dirichlet energy of
    the displacement.

    LSCM leaves a free boundary (hems, necklines) almost unconstrained: on a fine mesh its
    softest modes are sawtooth wiggles of the boundary, so every Newton-like step along
    them is huge and stops at the first flip; the solver then crawls (hundreds of
    iterations on a fine mesh). A Dirichlet term of a few percent stiffens exactly those
    modes, and also resists what conformal maps allow but a garment should not get: pieces
    growing or shrinking as a whole. (It also charges a little for turning a piece, which
    the alignment has already chosen.)
    """
    n = len(uv_ref)
    d, area = gradient_operators(uv_ref, faces)
    # per face, in the order x0 x1 x2 y0 y1 y2: the LSCM residuals (a - d, b + c) as rows
    # v1, v2 give A (v1 v1^T + v2 v2^T); the Dirichlet part is A D D^T for x and for y
    v1 = np.concatenate([d[:, :, 0], -d[:, :, 1]], axis=1)
    v2 = np.concatenate([d[:, :, 1], d[:, :, 0]], axis=1)
    block = np.einsum("fi,fj->fij", v1, v1) + np.einsum("fi,fj->fij", v2, v2)
    if dirichlet > 0:
        ddt = dirichlet * np.einsum("fid,fjd->fij", d, d)
        block[:, :3, :3] += ddt
        block[:, 3:, 3:] += ddt
    block *= area[:, None, None]
    dofs = np.concatenate([2 * faces, 2 * faces + 1], axis=1)  # (F,6)
    return sp.csr_matrix((block.ravel(), (np.repeat(dofs, 6, axis=1).ravel(),
                                          np.tile(dofs, (1, 6)).ravel())),
                         shape=(2 * n, 2 * n))


def outline_bending_matrix(uv_ref: np.ndarray, loops: list[np.ndarray],
                           smooth_mm: float | np.ndarray, unit_mm: float) -> sp.csr_matrix:
    """(2V,2V) matrix K with 1/2 d^T K d ~ kappa/2 * integral |d''|^2 ds along every
    outline and hole, d the displacement from ``uv_ref``.

    The fit only asks seams to move, and conformal and Dirichlet energies are happy to let
    a seam take a notch or a wiggle a few millimetres long where two seam lines' targets
    meet at a corner or where neighbouring edges matched different symmetries. A tailor
    sees those at once. Bending the outline's displacement costs ``kappa / l^3`` per
    feature of length l while the proximity term pays ``l / unit`` for ignoring it, so
    with ``kappa = smooth_mm^4 / unit`` features shorter than ``smooth_mm`` are smoothed
    away and longer moves are left to the fit. The outline's own corners are kept: only
    the displacement is smoothed. ``smooth_mm`` may be given per vertex (V,).

    Outline edges longer than ``smooth_mm`` (a specification meshed at 2 cm along a
    straight side) are weighed as if they were ``smooth_mm`` long: the integral would let
    neighbouring vertices zig-zag by several millimetres there (an accordion that keeps
    twin lengths while the ends follow their targets), and a tailor sees the kink at each
    vertex however coarse the sampling is.
    """
    n = len(uv_ref)
    if np.all(np.asarray(smooth_mm) <= 0) or not loops:
        return sp.csr_matrix((2 * n, 2 * n))
    loops = [lp for lp in loops if len(lp) >= 3]
    here = np.concatenate(loops)
    prev = np.concatenate([np.roll(lp, 1) for lp in loops])
    nxt = np.concatenate([np.roll(lp, -1) for lp in loops])
    h = 0.5 * (np.linalg.norm(uv_ref[here] - uv_ref[prev], axis=1)
               + np.linalg.norm(uv_ref[nxt] - uv_ref[here], axis=1))
    smooth = np.broadcast_to(np.asarray(smooth_mm, float), (n,))[here]
    w = (smooth**4 / unit_mm) / np.minimum(np.maximum(h, 1e-9), np.maximum(smooth, 1e-9)) ** 3
    rows = np.repeat(np.arange(len(here)), 3)
    cols = np.column_stack([prev, here, nxt]).ravel()
    vals = np.tile([1.0, -2.0, 1.0], len(here)) * np.repeat(np.sqrt(w), 3)
    d2 = sp.csr_matrix((vals, (rows, cols)), shape=(len(here), n))
    return sp.kron((d2.T @ d2).tocsr(), sp.eye(2), format="csr")


# ---------------------------------------------------------------------- barrier
def barrier_energy(uv: np.ndarray, faces: np.ndarray,
                   threshold: np.ndarray) -> tuple[float, np.ndarray]:
    """sum_f phi_f(A_f) (Schüller et al. 2013) and its gradient; +inf if any A_f <= 0."""
    area = signed_areas(uv, faces)
    grad = np.zeros_like(uv)
    if np.any(area <= 0.0):
        return np.inf, grad
    active = area < threshold
    if not active.any():
        return 0.0, grad
    s = threshold[active]
    x = area[active] / s
    g = x * (x * (x - 3.0) + 3.0)  # 1 - (1 - x)^3
    dg = 3.0 * (1.0 - x) ** 2 / s
    e = float(np.sum(1.0 / g - 1.0))
    dphi = -dg / g**2  # d phi / d A
    fa = faces[active]
    ga = area_gradients(uv, fa) * dphi[:, None, None]
    return e, _scatter(len(uv), fa.ravel(), ga.reshape(-1, 2))


# ---------------------------------------------------------------------- move bound
MOVE_ONSET = 0.81  # the move barrier acts beyond 90 % of the bound (rho = (d / bound)^2)


def _move_terms(uv: np.ndarray, rest: np.ndarray, bound: float):
    """Displacements p, rho = |p|^2 / bound^2 and the vertices beyond the onset."""
    p = uv - rest
    rho = np.einsum("ij,ij->i", p, p) / (bound * bound)
    return p, rho, np.flatnonzero(rho > MOVE_ONSET)


def move_barrier(uv: np.ndarray, rest: np.ndarray, bound: float,
                 weight: float) -> tuple[float, np.ndarray]:
    """sum_v w ((rho - r0) / (1 - rho))^2 over vertices with rho = |p_v|^2 / bound^2 > r0,
    and its gradient; +inf once any vertex has moved ``bound`` or more.

    Like the flip barrier, it is C1 where it starts acting (value and slope 0 at r0) and
    infinite on the constraint, so the bound holds as a constraint, not as a weight: the
    line search caps every step before it (`max_bounded_step`) and no iterate crosses it.
    """
    grad = np.zeros_like(uv)
    if not np.isfinite(bound):
        return 0.0, grad
    p, rho, act = _move_terms(uv, rest, bound)
    if np.any(rho >= 1.0):
        return np.inf, grad
    if not act.size:
        return 0.0, grad
    r = rho[act]
    e = float(weight * np.sum(((r - MOVE_ONSET) / (1.0 - r)) ** 2))
    dphi = weight * 2.0 * (r - MOVE_ONSET) * (1.0 - MOVE_ONSET) / (1.0 - r) ** 3
    grad[act] = (dphi * 2.0 / (bound * bound))[:, None] * p[act]
    return e, grad


def move_barrier_diagonal(uv: np.ndarray, rest: np.ndarray, bound: float,
                          weight: float) -> np.ndarray:
    """(V,) isotropic Gauss-Newton curvature of `move_barrier` per vertex (for the model)."""
    out = np.zeros(len(uv))
    if not np.isfinite(bound):
        return out
    _, rho, act = _move_terms(uv, rest, bound)
    r = np.minimum(rho[act], 1.0 - 1e-12)
    k = 1.0 - MOVE_ONSET
    dphi = weight * 2.0 * (r - MOVE_ONSET) * k / (1.0 - r) ** 3
    d2phi = weight * 2.0 * k * (1.0 - r + 3.0 * (r - MOVE_ONSET)) / (1.0 - r) ** 4
    b2 = bound * bound
    out[act] = dphi * 2.0 / b2 + d2phi * 4.0 * r / b2  # |d rho / d u|^2 = 4 rho / b^2
    return out


def max_bounded_step(uv: np.ndarray, rest: np.ndarray, direction: np.ndarray,
                     bound: float) -> float:
    """Largest t with every vertex of ``uv + t direction`` within ``bound`` of ``rest``
    (per vertex the positive root of |p + t d|^2 = bound^2, vectorised)."""
    if not np.isfinite(bound):
        return np.inf
    moving = np.flatnonzero(np.any(direction != 0, axis=1))
    if not moving.size:
        return np.inf
    p, d = uv[moving] - rest[moving], direction[moving]
    a = np.einsum("ij,ij->i", d, d)
    b = np.einsum("ij,ij->i", p, d)
    c = np.einsum("ij,ij->i", p, p) - bound * bound  # < 0 inside
    t = (-b + np.sqrt(np.maximum(b * b - a * c, 0.0))) / a
    return float(max(t.min(), 0.0))


# ---------------------------------------------------------------------- piece areas
def _area_coefficients(uv: np.ndarray, faces: np.ndarray, direction: np.ndarray):
    """Per face A(t) = a0 + b1 t + c2 t^2 of the signed area along ``uv + t direction``."""
    ax, ay, bx, by = edge_vectors(uv, faces)
    fx, fy, gx, gy = edge_vectors(direction, faces)
    return (0.5 * (ax * by - ay * bx), 0.5 * (ax * gy + fx * by - ay * gx - fy * bx),
            0.5 * (fx * gy - fy * gx))


def area_barrier(uv: np.ndarray, faces: np.ndarray, piece: np.ndarray, area0: np.ndarray,
                 tol: float, weight: float) -> tuple[float, np.ndarray]:
    """The `move_barrier` form on each piece's relative area change x = (A - A0) / (tol
    A0), r = x^2: a piece's area stays within ``tol`` (a fraction) of its input area."""
    grad = np.zeros_like(uv)
    if not np.isfinite(tol):
        return 0.0, grad
    n = len(area0)
    area = np.bincount(piece, weights=signed_areas(uv, faces), minlength=n)
    x = (area - area0) / (tol * area0)
    r = x * x
    if np.any(r >= 1.0):
        return np.inf, grad
    act = r > MOVE_ONSET
    if not act.any():
        return 0.0, grad
    ra = r[act]
    e = float(weight * np.sum(((ra - MOVE_ONSET) / (1.0 - ra)) ** 2))
    dphi = np.zeros(n)
    dphi[act] = (weight * 2.0 * (ra - MOVE_ONSET) * (1.0 - MOVE_ONSET) / (1.0 - ra) ** 3
                 * 2.0 * x[act] / (tol * area0[act]))
    on = np.flatnonzero(act[piece])
    ga = area_gradients(uv, faces[on]) * dphi[piece[on]][:, None, None]
    return e, _scatter(len(uv), faces[on].ravel(), ga.reshape(-1, 2))


def max_area_step(uv: np.ndarray, faces: np.ndarray, piece: np.ndarray, area0: np.ndarray,
                  tol: float, direction: np.ndarray) -> float:
    """Largest t with every piece's area within ``tol`` x its input area along ``uv + t
    direction`` (per piece a quadratic in t: the first positive root of A(t) - A0 = +-tol
    A0, vectorised)."""
    if not np.isfinite(tol):
        return np.inf
    n = len(area0)
    a0, b1, c2 = (np.bincount(piece, weights=c, minlength=n)
                  for c in _area_coefficients(uv, faces, direction))
    best = np.full(n, np.inf)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for side in (-1.0, 1.0):
            c0 = a0 - area0 * (1.0 + side * tol)
            disc = b1 * b1 - 4.0 * c2 * c0
            real = disc >= 0
            den = -0.5 * (b1 + np.copysign(np.sqrt(np.maximum(disc, 0.0)), b1))
            for root in (den / c2, c0 / den):
                best = np.minimum(best, np.where(real & (root > 0), root, np.inf))
    return float(best.min()) if n else np.inf


# ---------------------------------------------------------------------- penalty
def length_constraints(uv: np.ndarray, seam_edges: np.ndarray) -> tuple[np.ndarray, ...]:
    """c_e = |e|^2 - |e'|^2 and the edge vectors e, e' of every twin pair."""
    e1 = uv[seam_edges[:, 1]] - uv[seam_edges[:, 0]]
    e2 = uv[seam_edges[:, 3]] - uv[seam_edges[:, 2]]
    c = np.einsum("ki,ki->k", e1, e1) - np.einsum("ki,ki->k", e2, e2)
    return c, e1, e2


def length_penalty(uv: np.ndarray, seam_edges: np.ndarray, weight: np.ndarray,
                   ref_length: np.ndarray, gamma: float,
                   ease: np.ndarray | None = None) -> tuple[float, np.ndarray]:
    """1/(2 gamma) sum w r_e^2 and its (V,2) gradient.

    Without ``ease``, r_e = c_e / l0_e, the paper's pull to equal lengths. With ``ease``
    (E,), each pair's input length difference l0_e - l0_e', r_e = 2 (l_e - l_e' -
    ease_e): the twins keep the difference their maker gave them (a sleeve cap eased into
    an armhole), in millimetres, not in squared lengths, whose difference drifts when
    both edges shrink. Both forms are about 2 (l_e - l_e') for equal input lengths.
    """
    c, e1, e2 = length_constraints(uv, seam_edges)
    if ease is None:
        r = c / ref_length
        d1, d2 = e1 * (2.0 / ref_length)[:, None], e2 * (2.0 / ref_length)[:, None]
    else:
        n1, n2 = np.hypot(*e1.T), np.hypot(*e2.T)
        r = 2.0 * (n1 - n2 - ease)
        d1 = e1 * (2.0 / np.maximum(n1, 1e-12))[:, None]
        d2 = e2 * (2.0 / np.maximum(n2, 1e-12))[:, None]
    e = float(np.sum(weight * r * r)) / (2.0 * gamma)
    k = (weight * r / gamma)[:, None]  # dE/dr; dr/d(e) = d1, dr/d(e') = -d2
    vals = np.concatenate([-k * d1, k * d1, k * d2, -k * d2])
    idx = seam_edges.T.ravel()
    return e, _scatter(len(uv), idx, vals)


def twin_lengths(uv: np.ndarray, seam_edges: np.ndarray) -> np.ndarray:
    """(E,) l_e - l_e', the length difference of every twin pair in mm."""
    _, e1, e2 = length_constraints(uv, seam_edges)
    return np.hypot(*e1.T) - np.hypot(*e2.T)


def twin_length_mismatch(uv: np.ndarray, seam_edges: np.ndarray,
                         rest: np.ndarray | float = 0.0) -> float:
    """L = sum_e | l_e - l_e' - rest_e | in mm (the paper's stopping measure, with
    ``rest`` = 0; with the input's own differences it measures how far the ease moved)."""
    return float(np.sum(np.abs(twin_lengths(uv, seam_edges) - rest)))


# ---------------------------------------------------------------------- flips
def max_flip_free_step(uv: np.ndarray, faces: np.ndarray, direction: np.ndarray) -> float:
    """Largest t with every face area positive on [0, t) along ``uv + t direction``.

    Area(t) = A + B t + C t^2 per face; the first positive root of each quadratic
    bounds the step (vectorised, as in Smith and Schaefer 2015). Faces whose corners do
    not move are skipped.
    """
    moving = np.any(direction != 0, axis=1)
    if not moving.any():
        return np.inf
    if not moving.all():
        faces = faces[moving[faces].any(axis=1)]
    ax, ay, bx, by = edge_vectors(uv, faces)
    fx, fy, gx, gy = edge_vectors(direction, faces)
    a0 = 0.5 * (ax * by - ay * bx)
    c2 = 0.5 * (fx * gy - fy * gx)
    b1 = 0.5 * (ax * gy + fx * by - ay * gx - fy * bx)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        # numerically stable roots; with C = 0 the second one is the linear root -A/B
        disc = b1 * b1 - 4.0 * c2 * a0
        real = disc >= 0
        den = -0.5 * (b1 + np.copysign(np.sqrt(np.maximum(disc, 0.0)), b1))
        r1 = den / c2
        r2 = a0 / den
        t = np.minimum(np.where(real & (r1 > 0), r1, np.inf),
                       np.where(real & (r2 > 0), r2, np.inf))
    return float(t.min()) if len(t) else np.inf


# ---------------------------------------------------------------------- total
@dataclass
class PatternEnergy:
    """Eq. (10) for one garment and one set of ideal seams, with the constants it needs.

    ``vertex, target, weight``: the E_prox rows; ``seam_edges, edge_weight, ref_length``:
    the penalty; ``threshold`` (F,): barrier areas; ``q``: the (stiffened) conformal
    matrix and ``rest`` the input pattern it measures displacements from.
    """

    faces: np.ndarray
    q: sp.csr_matrix
    rest: np.ndarray
    threshold: np.ndarray
    vertex: np.ndarray
    target: np.ndarray
    weight: np.ndarray
    seam_edges: np.ndarray
    edge_weight: np.ndarray
    ref_length: np.ndarray
    seam_across: np.ndarray  # (E,) twins on different pieces (for the solver's model)
    alpha: float = 1.0
    beta: float = 1.0
    outline: OutlineGuard | None = None  # rejects crossing outlines
    max_move: float = np.inf  # no vertex moves this far (mm) from ``rest``
    move_weight: float = 1.0
    piece: np.ndarray | None = None  # (F,) piece of each face, for the area bound
    area0: np.ndarray | None = None  # (P,) input area of each piece
    area_tol: float = np.inf  # no piece's area changes by this fraction or more
    ease: np.ndarray | None = None  # (E,) l0_e - l0_e' the twins keep; None: equal lengths

    def terms(self, uv: np.ndarray, gamma: float) -> dict[str, tuple[float, np.ndarray]]:
        """Each term's value and gradient (for reports and gradient checks)."""
        return {
            "prox": prox_energy(uv, self.vertex, self.target, self.weight),
            "conf": conformal_energy(uv, self.q, self.rest),
            "barrier": barrier_energy(uv, self.faces, self.threshold),
            "length": length_penalty(uv, self.seam_edges, self.edge_weight,
                                     self.ref_length, gamma, self.ease),
            "move": move_barrier(uv, self.rest, self.max_move, self.move_weight),
            "area": self.area_term(uv),
        }

    def area_term(self, uv: np.ndarray) -> tuple[float, np.ndarray]:
        if self.piece is None or self.area0 is None:
            return 0.0, np.zeros_like(uv)
        return area_barrier(uv, self.faces, self.piece, self.area0, self.area_tol,
                            self.move_weight)

    def max_step(self, uv: np.ndarray, direction: np.ndarray) -> float:
        """Largest step along ``direction`` before a flip, the move bound or the area
        bound (each iterate must satisfy all three)."""
        t = min(max_flip_free_step(uv, self.faces, direction),
                max_bounded_step(uv, self.rest, direction, self.max_move))
        if self.piece is not None and self.area0 is not None:
            t = min(t, max_area_step(uv, self.faces, self.piece, self.area0, self.area_tol,
                                     direction))
        return t

    def __call__(self, uv: np.ndarray, gamma: float) -> tuple[float, np.ndarray]:
        """Total energy and (V,2) gradient; +inf (zero gradient) for any flip or crossing
        outline, so that no line search can step into a pattern that cannot be cut."""
        eb, gb = barrier_energy(uv, self.faces, self.threshold)
        if not np.isfinite(eb) or (self.outline is not None and not self.outline(uv)):
            return np.inf, gb
        ep, gp = prox_energy(uv, self.vertex, self.target, self.weight)
        ec, gc = conformal_energy(uv, self.q, self.rest)
        el, gl = length_penalty(uv, self.seam_edges, self.edge_weight, self.ref_length, gamma,
                                self.ease)
        em, gm = move_barrier(uv, self.rest, self.max_move, self.move_weight)
        ea, ga = self.area_term(uv)
        if not (np.isfinite(em) and np.isfinite(ea)):
            return np.inf, gm
        e = ep + self.alpha * ec + self.beta * eb + el + em + ea
        return e, gp + self.alpha * gc + self.beta * gb + gl + gm + ga
