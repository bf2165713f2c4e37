"""Minimise Eq. (10) with L-BFGS and the paper's gamma loop (Sec. 5, "Shape optimization").

Driver ``optimise`` + explicit ``OptimiseState`` + one L-BFGS iteration ``optimise_step``
(the gpytoolbox layout), so a caller can step, inspect and resume.

Why our own L-BFGS rather than ``scipy.optimize.minimize(method="L-BFGS-B")``:

- the line search must never step into a flip, and SciPy's does not cope with a barrier
  that returns +inf (or 1e300): on f(x) = (x-3)^2 - log(2-x), +inf for x >= 2, started at
  -50, SciPy 1.17's L-BFGS-B reports "CONVERGENCE" at x = -29 after two iterations (the
  minimum is at 1.63): once a trial step lands beyond the barrier it stops. Here every
  step is capped at 90 % of the first flip along the direction (per-face quadratic of the
  signed area, vectorised) and then backtracked (Armijo), so every iterate is flip-free
  by construction;
- the two-loop recursion starts from a sparse convex model of Eq. (10) (conformal matrix
  + proximity + Gauss-Newton parts of the length penalty and of the active barrier
  terms), factorised with CHOLMOD, again once gamma is 4x smaller than modelled or when
  the barrier starts to bind (steps cut below half, at most every ``refresh_every``
  iterations). SciPy's L-BFGS-B takes no such start matrix; without it the iteration
  count grows with the Laplacian's condition number (h^-2).

The gamma loop: gamma starts at ``gamma0`` and is halved each round until the twin
length mismatch ``L = sum_e |l_e - l_e'|`` is at most ``eps`` = half its initial value
(never below 1 mm per metre of seam), for at most 20 rounds, each warm-started: that is
the paper's (`ReshapeOptions.paper`). Ours keeps every twin pair's input length
difference (less ``ease_give_mm`` per seam line, `solver.reshape.ease.ease_targets`) and
stops once every seam line's ease is within ``ease_tol_mm`` of that.

The targets: first the paper's ideal seam lines (the matched targets on lines beyond
reach, `solver.reshape.ideal.initial_targets`), then up to ``refinements`` rounds of
matched targets from the pattern reached so far, as long as each lowers E_fit by at
least ``refine_gain``; the pattern with the lowest E_fit and L within eps is returned.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp
from cholespy import CholeskySolverD, MatrixType
from scipy.spatial import cKDTree

from solver.fit import fit_report
from solver.garment.symmetry import MirrorPair
from solver.geometry import signed_areas
from solver.reshape.ease import SeamSewing, across_only, ease_targets, eased_lines
from solver.reshape.energy import (
    PatternEnergy,
    area_gradients,
    length_constraints,
    move_barrier_diagonal,
    outline_bending_matrix,
    stiffened_conformal_matrix,
)
from solver.reshape.ideal import (
    UNIT_MM,
    IdealSeams,
    SeamTargets,
    ideal_seams,
    initial_targets,
    matched_seams,
)
from solver.reshape.outline import OutlineGuard
from solver.reshape.pairs import PairTie


@dataclass(frozen=True)
class ReshapeOptions:
    """Weights of Eq. (10) and the solver's limits (paper: alpha = beta = 1, gamma0 = 1)."""

    alpha: float = 1.0
    beta: float = 1.0
    gamma0: float = 1.0
    max_rounds: int = 20
    barrier_fraction: float = 0.25  # phi_f is active below this fraction of the input area
    memory: int = 8
    max_iterations_per_round: int = 200
    ftol: float = 1e-7  # relative energy decrease that ends a round
    xtol_mm: float = 1e-3  # largest vertex step (mm) that ends a round (cutters: 0.1 mm)
    refresh_every: int = 40  # fewest iterations between two factorisations in a round
    unit_mm: float = UNIT_MM  # seam length carrying one unit of proximity / penalty weight
    reach: float = 1.0  # ideal lines farther than this x covering radius (or the move
    # bound) start matched
    refinements: int = 4  # rounds of matched (closest equivalent point) targets
    refine_gain: float = 0.02  # relative E_fit gain below which refinement stops
    # eps never below this fraction of the seam length (1 mm per metre, 0.1 % strain, which
    # fabric stretch absorbs): twins sampled to equal lengths would otherwise ask for
    # L < 1e-12 mm and run all 20 rounds
    eps_floor: float = 1e-3
    refine: bool = True  # subdivide meshes whose seam edges outgrow the print's repeat
    dirichlet: float = 0.05  # Dirichlet stiffness added to E_conf (stiffened_conformal_matrix)
    smooth_mm: float = 10.0  # outline zig-zags shorter than this are smoothed away
    corner_smooth_mm: float = 14.0  # ... and shorter than this near seam-line ends
    max_move_mm: float = 10.0  # no pattern vertex moves farther (a constraint; inf: none)
    move_weight: float = 1.0  # strength of the move and area barriers in their last 10 %
    max_area_change: float = 0.01  # no piece's area changes by this fraction (inf: none)
    # twins keep the length difference they were given (a seam's ease), per edge pair;
    # False: they are pulled to equal lengths, as in the paper
    keep_ease: bool = True
    ease_give_mm: float = 0.5  # of which each seam line may give this much to the fit
    ease_tol_mm: float = 0.5  # ... and a round may end once every seam's is within this
    blend_shapes: bool = True  # ideal lines average the twins' shapes (False: the paper's)
    never_worse: bool = True  # return the input when no round fits better than it

    @classmethod
    def paper(cls, **changes) -> ReshapeOptions:
        """Sec. 5 as the paper writes it: Eq. (10) alone (no Dirichlet stiffness, outline
        bending, move or area bound), twins pulled to equal lengths, the ideal lines only
        (half the rigid motion each), the input mesh as it is. Flips and crossing
        outlines stay forbidden: those patterns cannot be cut."""
        preset = dict(dirichlet=0.0, smooth_mm=0.0, corner_smooth_mm=0.0,
                      max_move_mm=np.inf, max_area_change=np.inf, keep_ease=False,
                      blend_shapes=False, refinements=0, reach=np.inf, refine=False,
                      never_worse=False)
        return cls(**{**preset, **changes})


class _Preconditioner:
    """Sparse Cholesky factor (CHOLMOD through cholespy) of the convex model restricted
    to the free coordinates. (An isotropic V x V model, one factor for x and y, is
    several times cheaper to factorise but misses the conformal energy's freedom to turn
    and scale pieces, so L-BFGS needs many more iterations.)"""

    def __init__(self, matrix: sp.spmatrix) -> None:
        c = sp.coo_matrix(matrix)
        self.n = c.shape[0]
        self._chol = CholeskySolverD(self.n, c.row.astype(np.int32), c.col.astype(np.int32),
                                     c.data.astype(np.float64), MatrixType.COO)

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """(n,) right-hand side -> (n,) solution."""
        b = np.ascontiguousarray(rhs, dtype=np.float64).reshape(-1, 1)
        out = np.zeros_like(b)
        self._chol.solve(b, out)
        return out.ravel()


@dataclass
class OptimiseState:
    """Everything one L-BFGS iteration reads and writes (inspectable, resumable)."""

    uv: np.ndarray  # (V,2) current pattern, mm
    free: np.ndarray  # (V,) bool vertices that may move
    gamma: float
    energy: float = np.nan
    grad: np.ndarray | None = None
    round: int = 0
    iterations: int = 0
    round_iterations: int = 0
    round_done: bool = False
    s_hist: deque = field(default_factory=deque)
    y_hist: deque = field(default_factory=deque)
    last_step_mm: float = np.inf
    precond: _Preconditioner | None = None
    precond_gamma: float = np.nan  # gamma the factor was built with
    history_gamma: float = np.nan  # gamma the L-BFGS pairs were collected with
    dofs: np.ndarray | None = None  # free coordinates, interleaved x/y
    refreshes: int = 0
    since_refresh: int = 0
    history: list = field(default_factory=list)  # per round: gamma, L, energy, iterations
    tie: PairTie | None = None  # mirror pairs whose displacements are one (solver.reshape.pairs)


def _in_subspace(state: OptimiseState, field: np.ndarray) -> np.ndarray:
    """``field`` (V,2) with fixed vertices at zero and mirror pairs tied."""
    field[~state.free] = 0.0
    if state.tie is not None:
        field = state.tie.project(field)
        field[~state.free] = 0.0
    return field


def _free_direction(state: OptimiseState, d: np.ndarray) -> np.ndarray:
    """A flat direction over the free coordinates, projected onto the tied subspace."""
    if state.tie is None:
        return d
    full = np.zeros_like(state.uv)
    full[state.free] = d.reshape(-1, 2)
    return _in_subspace(state, full)[state.free].ravel()


def _gauss_newton_matrix(energy: PatternEnergy, uv: np.ndarray, gamma: float) -> sp.csr_matrix:
    """(2V,2V) convex model of Eq. (10) at ``uv``, interleaved x/y.

    Conformal matrix + proximity diagonal + Gauss-Newton parts of the length penalty and of
    the barrier of the faces below their threshold. It is positive (semi)definite, so it
    serves as the L-BFGS start matrix H0^-1; refreshing it when the barrier starts to bind
    keeps the line search's steps long near the flip limit.
    """
    n = len(uv)
    # proximity: 2 w per coordinate
    prox = np.bincount(energy.vertex, weights=2.0 * energy.weight, minlength=n)
    diag = np.repeat(prox, 2)
    rows, cols, vals = [], [], []
    # length penalty: (w / gamma) grad(c/l0) grad(c/l0)^T per twin pair
    c, e1, e2 = length_constraints(uv, energy.seam_edges)
    jac = np.concatenate([-e1, e1, e2, -e2], axis=1) * (2.0 / energy.ref_length)[:, None]
    dofs = np.repeat(2 * energy.seam_edges, 2, axis=1) + np.tile([0, 1], 4)  # (E,8)
    k = energy.edge_weight / gamma
    block = k[:, None, None] * jac[:, :, None] * jac[:, None, :]
    # leave out the coupling between twins on different pieces: the model then falls apart
    # into one block per piece, which CHOLMOD factorises with far less fill; L-BFGS makes
    # up for what is left out
    side = np.repeat([0, 1], 4)
    across = energy.seam_across[:, None, None] & (side[:, None] != side[None, :])
    block = np.where(across, 0.0, block)
    rows.append(np.repeat(dofs, 8, axis=1).ravel())
    cols.append(np.tile(dofs, (1, 8)).ravel())
    vals.append(block.ravel())
    # barrier: phi''(A) grad A grad A^T on active faces
    area = signed_areas(uv, energy.faces)
    act = np.flatnonzero((area > 0) & (area < energy.threshold))
    if act.size:
        s = energy.threshold[act]
        x = area[act] / s
        gx = x * (x * (x - 3.0) + 3.0)
        d1 = 3.0 * (1.0 - x) ** 2 / s
        d2 = -6.0 * (1.0 - x) / s**2
        phi2 = (2.0 * d1**2 - gx * d2) / gx**3
        ga = area_gradients(uv, energy.faces[act]).reshape(-1, 6) * energy.beta
        fd = (np.repeat(2 * energy.faces[act], 2, axis=1) + np.tile([0, 1], 3))  # (A,6)
        rows.append(np.repeat(fd, 6, axis=1).ravel())
        cols.append(np.tile(fd, (1, 6)).ravel())
        vals.append((phi2[:, None, None] * ga[:, :, None] * ga[:, None, :]).ravel() / energy.beta)
    m = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(2 * n, 2 * n))
    diag = diag + np.repeat(move_barrier_diagonal(uv, energy.rest, energy.max_move,
                                                  energy.move_weight), 2)
    m = m + energy.alpha * energy.q + sp.diags(diag)
    reg = 1e-8 * float(np.abs(m.diagonal()).mean() or 1.0)
    return (m + reg * sp.eye(2 * n)).tocsr()


def _dot(a: np.ndarray, b: np.ndarray) -> float:
    """Inner product without BLAS: on a busy machine BLAS threads spin and a dot of 10^5
    numbers can take milliseconds; einsum stays single-threaded and predictable."""
    return float(np.einsum("i,i->", a, b))


def refresh_preconditioner(state: OptimiseState, energy: PatternEnergy) -> None:
    """Factorise the convex model of Eq. (10) at the current pattern."""
    m = _gauss_newton_matrix(energy, state.uv, state.gamma)
    state.precond = _Preconditioner(m[state.dofs][:, state.dofs])
    state.precond_gamma = state.gamma
    state.refreshes += 1
    state.since_refresh = 0


def _descent_without(state: OptimiseState, direction: np.ndarray,
                     stuck: np.ndarray) -> tuple[np.ndarray, float]:
    """A descent direction over the free coordinates that leaves ``stuck`` vertices where
    they are: ``direction`` with them zeroed if that still descends, else the model's
    Newton step on the other vertices, else the plain negative gradient there."""
    free = state.free
    keep = ~stuck[free]
    gf = state.grad[free]
    masked = np.where(keep[:, None], direction[free], 0.0).ravel()
    g_kept = np.where(keep[:, None], gf, 0.0).ravel()
    candidates = (masked, lambda: -state.precond.solve(g_kept) * np.repeat(keep, 2),
                  lambda: -g_kept)
    for cand in candidates:
        d = _free_direction(state, cand() if callable(cand) else cand)
        slope = _dot(gf.ravel(), d)
        if slope < 0:
            return d, slope
    return d, slope


def optimise_step(state: OptimiseState, energy: PatternEnergy,
                  options: ReshapeOptions) -> bool:
    """One L-BFGS iteration with a flip-capped Armijo line search; True when the round ends."""
    free = state.free
    gf = state.grad[free].ravel()
    if not np.any(gf):
        state.round_done = True
        return True
    if state.precond is None:
        refresh_preconditioner(state, energy)
    d, slope = _lbfgs_direction(state, gf)
    direction = np.zeros_like(state.uv)
    direction[free] = d.reshape(-1, 2)
    e0 = state.energy
    found = _line_search(state, energy, direction, d, slope)
    if found is None:
        state.round_done = True
        return True
    t, d, trial, e1, g1 = found
    _take_step(state, options, t, t * d, gf, trial, e1, _in_subspace(state, g1))
    small_f = (e0 - e1) <= options.ftol * max(1.0, abs(e1))
    small_x = state.last_step_mm <= options.xtol_mm
    state.round_done = (small_f or small_x
                        or state.round_iterations >= options.max_iterations_per_round)
    return state.round_done


def _lbfgs_direction(state: OptimiseState, gf: np.ndarray) -> tuple[np.ndarray, float]:
    """The L-BFGS direction over the free unknowns (two-loop recursion, H0 = the convex
    model's inverse) and its slope; the model's Newton direction, the memory cleared,
    when the recursion lost descent."""
    q = gf.copy()
    alphas = []
    for s, y in zip(reversed(state.s_hist), reversed(state.y_hist)):
        rho = 1.0 / _dot(y, s)
        a = rho * _dot(s, q)
        q -= a * y
        alphas.append((a, rho, s, y))
    r = state.precond.solve(q)
    for a, rho, s, y in reversed(alphas):
        b = rho * _dot(y, r)
        r += s * (a - b)
    d = _free_direction(state, -r)
    slope = _dot(gf, d)
    if not slope < 0:  # lost descent: restart from the model's Newton direction
        state.s_hist.clear()
        state.y_hist.clear()
        d = _free_direction(state, -state.precond.solve(gf))
        slope = _dot(gf, d)
    return d, slope


def _line_search(state: OptimiseState, energy: PatternEnergy, direction: np.ndarray,
                 d: np.ndarray, slope: float) -> tuple | None:
    """Armijo backtracking from a step capped short of the first flip and of the move
    bound (every iterate satisfies both): ``(t, d, trial uv, energy, gradient)``, or None
    when no step decreases the energy. ``direction`` (V,2) is ``d`` on the free vertices;
    both change when outline vertices near a crossing sit the step out."""
    t = min(1.0, 0.9 * energy.max_step(state.uv, direction))
    e0 = state.energy
    for _ in range(60):
        trial = state.uv + t * direction
        e1, g1 = energy(trial, state.gamma)
        if np.isfinite(e1) and e1 <= e0 + 1e-4 * t * slope:
            return t, d, trial, e1, g1
        if not np.isfinite(e1) and energy.outline is not None:
            # the outline vertices near a crossing sit this step out, so that one dart
            # pressed shut does not stop everything else from moving
            stuck = energy.outline.crossing_vertices(trial) & state.free
            if np.any(direction[stuck]):
                d, slope = _descent_without(state, direction, stuck)
                if not slope < 0:
                    return None
                direction[state.free] = d.reshape(-1, 2)
                continue
        t *= 0.5
    return None


def _take_step(state: OptimiseState, options: ReshapeOptions, t: float, step: np.ndarray,
               gf: np.ndarray, trial: np.ndarray, e1: float, g1: np.ndarray) -> None:
    """Move to ``trial`` (the step ``t`` along the direction), remembering the curvature
    pair when it is positive; a short step means the barrier binds and the model is
    stale, so it is refactorised before the next step."""
    yv = g1[state.free].ravel() - gf
    if _dot(yv, step) > 1e-12 * _dot(step, step):
        state.s_hist.append(step)
        state.y_hist.append(yv)
        while len(state.s_hist) > options.memory:
            state.s_hist.popleft()
            state.y_hist.popleft()
    state.uv, state.energy, state.grad = trial, e1, g1
    state.iterations += 1
    state.round_iterations += 1
    state.last_step_mm = float(np.abs(step).max())
    state.since_refresh += 1
    if t < 0.5 and state.since_refresh >= options.refresh_every:
        state.precond = None


@dataclass
class OptimiseResult:
    """The reshaped pattern and what it took."""

    uv: np.ndarray
    ideal: IdealSeams
    state: OptimiseState
    length_mismatch_initial_mm: float
    length_mismatch_final_mm: float
    eps_mm: float
    seconds: float
    flipped_triangles: int
    ease_change_max_mm: float = 0.0  # the largest change of a seam line's ease


def build_energy(garment, targets: SeamTargets, options: ReshapeOptions) -> PatternEnergy:
    """Eq. (10) for ``garment`` with the input pattern as reference shape.

    The twin-length penalty weighs each pair by ``unit_mm / l0``: ``(c_e / l0)^2`` is
    about ``4 (l_e - l_e')^2``, so the weight turns the sum into an integral of squared
    strain along the seam, which does not weaken when the mesh is refined.
    """
    uv0 = garment.uv
    faces = garment.faces
    e = garment.seam_edges
    l1 = np.linalg.norm(uv0[e[:, 1]] - uv0[e[:, 0]], axis=1)
    l2 = np.linalg.norm(uv0[e[:, 3]] - uv0[e[:, 2]], axis=1)
    ref = np.maximum(0.5 * (l1 + l2), 1e-9)
    # sewability does not depend on visibility: a seam weighted 0 for the fit still has
    # to keep equal twin lengths, so the penalty weight is max(w_S, 1)
    w_edge = (np.maximum(garment.seam_weights(), 1.0) * options.unit_mm / ref
              if len(e) else np.zeros(0))
    return PatternEnergy(
        faces=faces,
        q=(stiffened_conformal_matrix(uv0, faces, options.dirichlet)
           + outline_bending_matrix(uv0, [lp for i in range(garment.n_pieces)
                                          for lp in garment.piece_loops(i)],
                                    _smoothing(garment, options), options.unit_mm)).tocsr(),
        rest=uv0,
        threshold=options.barrier_fraction * signed_areas(uv0, faces),
        vertex=targets.vertex,
        target=targets.target,
        weight=targets.weight,
        seam_edges=e,
        edge_weight=w_edge,
        ref_length=ref,
        alpha=options.alpha,
        beta=options.beta,
        outline=OutlineGuard(garment),
        seam_across=garment.piece_of_vertex[e[:, 0]] != garment.piece_of_vertex[e[:, 2]],
        max_move=options.max_move_mm,
        move_weight=options.move_weight,
        piece=garment.piece_of_face(),
        area0=garment.piece_areas(),
        area_tol=options.max_area_change,
        ease=ease_targets(garment, options.ease_give_mm)[0] if options.keep_ease else None,
    )


def _smoothing(garment, options: ReshapeOptions) -> np.ndarray:
    """(V,) bending scale: ``corner_smooth_mm`` within that distance of a vertex where a
    seam line ends (where two lines' targets disagree and leave a step), else
    ``smooth_mm``."""
    smooth = np.full(garment.n_vertices, options.smooth_mm)
    if options.corner_smooth_mm <= options.smooth_mm or not len(garment.seam_edges):
        return smooth
    e, line = garment.seam_edges, np.asarray(garment.seam_line_of_edge, np.int64)
    n_lines = len(garment.seam_lines)
    keys, counts = np.unique(np.concatenate([e[:, :2], e[:, 2:]]).ravel() * n_lines
                             + np.tile(np.repeat(line, 2), 2), return_counts=True)
    ends = np.unique(keys[counts == 1] // n_lines)
    if not len(ends):
        return smooth
    boundary = np.unique(garment.boundary_half_edges())
    d, _ = cKDTree(garment.uv[ends]).query(garment.uv[boundary])
    smooth[boundary[d < options.corner_smooth_mm]] = options.corner_smooth_mm
    return smooth


def _gamma_rounds(state: OptimiseState, energy: PatternEnergy, options: ReshapeOptions,
                  sewn: SeamSewing, targets: str,
                  e_fit: Callable[[np.ndarray], float],
                  progress: Callable[[dict], None] | None) -> None:
    """The paper's gamma loop from ``state.gamma``: minimise, halve gamma until ``sewn``;
    every round's record (with its E_fit) goes to ``state.history`` and ``progress``."""
    while True:
        state.round_iterations, state.round_done = 0, False
        # new targets leave the Hessian as it was (the proximity term's is constant), so
        # the L-BFGS pairs and the factor carry over; a smaller gamma stiffens the length
        # penalty: new pairs at once, a new factor once it is 4x stiffer than modelled
        if state.gamma != state.history_gamma:
            state.s_hist.clear()
            state.y_hist.clear()
            state.history_gamma = state.gamma
        if not state.gamma > 0.25 * state.precond_gamma:
            state.precond = None
        state.energy, grad = energy(state.uv, state.gamma)
        state.grad = _in_subspace(state, grad)
        if state.dofs.size:
            while not optimise_step(state, energy, options):
                pass
        state.round += 1
        length = sewn.mismatch(state.uv)
        state.history.append({"round": state.round, "targets": targets, "gamma": state.gamma,
                              "L_mm": length, "e_fit_mm2": e_fit(state.uv),
                              "energy": state.energy, "iterations": state.round_iterations})
        if progress is not None:
            progress(state.history[-1])
        if sewn(state.uv) or state.round >= options.max_rounds:
            return
        state.gamma *= 0.5


def optimise(garment, placement, *, fixed: np.ndarray | None = None,
             options: ReshapeOptions | None = None,
             progress: Callable[[dict], None] | None = None,
             pairs: Sequence[MirrorPair] = ()) -> OptimiseResult:
    """Reshape ``garment``'s pattern towards its ideal seam lines (paper Sec. 5).

    First towards the paper's ideal seam lines, then (``options.refinements`` times at
    most) towards the matched targets of the pattern reached so far, keeping the pattern
    with the lowest E_fit among those whose seams sew (the input included, unless
    ``options.never_worse`` is off, so that reshaping never makes the fit worse).
    ``fixed`` (n_pieces,) bool: pieces that must keep their shape and position;
    ``progress`` is called with each finished round's history entry; ``pairs`` (mirror
    pairs of `solver.garment.symmetry`) move as one: the second piece's displacement is
    the first's, mirrored.
    """
    options = options or ReshapeOptions()
    start = time.perf_counter()
    fixed = (np.zeros(garment.n_pieces, bool) if fixed is None
             else np.asarray(fixed, bool).reshape(garment.n_pieces))
    if np.any(signed_areas(garment.uv, garment.faces) <= 0):
        raise ValueError("the input pattern has flipped or degenerate triangles; "
                         "reshaping needs a valid pattern to start from")
    unit = options.unit_mm
    ideal = ideal_seams(garment, placement, fixed=fixed, unit_mm=unit,
                        blend_shapes=options.blend_shapes)
    eased = (eased_lines(garment) if options.keep_ease
             else np.zeros(len(garment.seam_lines), bool))
    energy = build_energy(garment, across_only(garment, initial_targets(
        garment, placement, ideal, fixed=fixed, unit_mm=unit, reach=options.reach,
        max_move_mm=options.max_move_mm),
        garment.uv, eased), options)
    state = _start_state(garment, fixed, pairs, options)
    sewn = SeamSewing(garment, keep_ease=options.keep_ease, give_mm=options.ease_give_mm,
                      ease_tol_mm=options.ease_tol_mm, eps_floor=options.eps_floor)

    def e_fit(uv: np.ndarray) -> float:
        return fit_report(garment, placement, uv=uv).e_fit_mm2

    _gamma_rounds(state, energy, options, sewn, "ideal", e_fit, progress)
    best_uv, best_fit = state.uv, state.history[-1]["e_fit_mm2"]
    if options.never_worse and best_fit > e_fit(garment.uv):  # the input sews, too
        best_uv, best_fit = garment.uv.copy(), e_fit(garment.uv)
    for _ in range(options.refinements):
        targets = across_only(garment, matched_seams(garment, placement, uv=state.uv,
                                                     fixed=fixed, unit_mm=unit),
                              state.uv, eased)
        energy = replace(energy, vertex=targets.vertex, target=targets.target,
                         weight=targets.weight)
        _gamma_rounds(state, energy, options, sewn, "matched", e_fit, progress)
        fit = state.history[-1]["e_fit_mm2"]
        gain = (best_fit - fit) / max(best_fit, 1e-12)
        if fit < best_fit and _sews_as_well(sewn, state.uv, best_uv):
            best_uv, best_fit = state.uv, fit
        if gain < options.refine_gain:
            break
    flipped = int(np.sum(signed_areas(best_uv, garment.faces) <= 0))
    return OptimiseResult(
        uv=best_uv,
        ideal=ideal,
        state=state,
        length_mismatch_initial_mm=sewn.initial_mm,
        length_mismatch_final_mm=sewn.mismatch(best_uv),
        eps_mm=sewn.eps_mm,
        seconds=time.perf_counter() - start,
        flipped_triangles=flipped,
        ease_change_max_mm=sewn.ease_change(best_uv),
    )


def _start_state(garment, fixed: np.ndarray, pairs: Sequence[MirrorPair],
                 options: ReshapeOptions) -> OptimiseState:
    """The optimisation's start: the input pattern, the free vertices (those of pieces
    not ``fixed``) and their unknowns, mirror pairs that move tied."""
    free = ~fixed[garment.piece_of_vertex]
    idx = np.flatnonzero(free)
    moving = [p for p in pairs if not (fixed[p.first] or fixed[p.second])]
    return OptimiseState(uv=garment.uv.copy(), free=free, gamma=options.gamma0,
                         dofs=(2 * idx[:, None] + np.array([0, 1])).ravel(),
                         tie=PairTie(garment, moving) if moving else None)


def _sews_as_well(sewn: SeamSewing, uv: np.ndarray, best_uv: np.ndarray) -> bool:
    """``uv``'s seams sew, or their length mismatch is no worse than ``best_uv``'s."""
    return bool(sewn(uv) or sewn.mismatch(uv) <= sewn.mismatch(best_uv))
