"""Beyond the paper: an alignment closer to the global optimum of E_fit.

The paper's translational step (Eq. 9) is a local descent on a landscape with one
basin per choice of "which equivalent point matches which" along every seam, so random
restarts find the best basin only by luck once there are more than a few pieces. Here:

1. run the paper's method with the same restarts and seed (its result is the floor:
   the answer is never worse);
2. for the best few distinct rotation solutions, place the pieces one by one along a
   maximum-weight spanning tree of the seam graph; each piece's offset is chosen by an
   exhaustive search over candidates that contains (a) for every sampled seam edge and
   every symmetry operation of the print the offset that makes that edge match exactly,
   and (b) a regular grid over the primitive cell, scored against *all* pieces placed
   so far (so seams closing cycles count too); and, as further starts, the exact grid
   optimum over that tree's seams (``solver.align.tree_dp``), which no greedy order can
   miss;
3. refine every tree placement with Eq. (9) to convergence and IRLS on E_fit itself,
   then run block-coordinate *exhaustive* sweeps: each piece in turn jumps to the best
   of the same candidates scored against all its neighbours (a move the local Eq. (9)
   can never make), each sweep followed by IRLS;
4. hop between rotation basins: random turns of a few degrees per piece, each with its
   own translational solve, keeping improvements (the r-RoSy field fixes angles, not
   the positions that E_fit measures);
5. with at most four movable pieces, also search the joint grid over all their
   translations (``solver.align.brute``, compiled), at interleaving grid sizes, coarse
   first and the next only while one finds a better basin: where the steps above
   already found the grid's best (most garments, and the 3-piece quotient of a
   symmetric t-shirt), the grid costs one coarse pass, not three and their polishing;
6. polish the best with BFGS over angles and translations and keep the lowest E_fit
   of all of these and of the paper's result; with few pieces, alternate joint grid and
   polish while the grid still finds a better basin at the polished angles.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import breadth_first_order, minimum_spanning_tree

from solver.align.brute import brute_force
from solver.align.problem import AlignProblem
from solver.align.refine import bfgs_refine, irls_translations
from solver.align.restarts import AlignResult, align_paper, enforce_fixed
from solver.align.translation import optimise_translations
from solver.align.tree_dp import tree_dp_placement
from solver.geometry import rotation_matrices

#: joint-grid points per cell axis inside the global method, by number of movable pieces,
#: coarse first: each size searches the best candidate while the previous one found a
#: better basin (the cheap pass decides whether finer ones are worth their cost); after
#: polishing, the sizes in turn search again (at most ``ALTERNATE_ROUNDS``) while they
#: find one
GLOBAL_GRID = {1: (40, 48), 2: (12, 16, 20), 3: (10, 12, 16), 4: (10, 12, 16)}
ALTERNATE_ROUNDS = 3
GRID_GAIN = 1e-3  # a joint grid "finds a better basin" when it lowers E_fit this much


def _tree_order(problem: AlignProblem, w: np.ndarray):
    """Pieces in placement order with their tree parent (-1 for roots)."""
    p = problem.n_pieces
    mst = minimum_spanning_tree(coo_matrix(-(w + w.T)).tocsr())
    tree = mst + mst.T
    order, parent = [], np.full(p, -1)
    seen = np.zeros(p, bool)
    strength = w.sum(axis=1)
    # roots: translation-fixed pieces first, then the most strongly sewn piece
    for root in sorted(range(p), key=lambda i: (not problem.fix_trans[i], -strength[i])):
        if seen[root]:
            continue
        nodes, pred = breadth_first_order(tree, root, directed=False)
        for n in nodes:
            if not seen[n]:
                seen[n] = True
                order.append(int(n))
                parent[n] = pred[n] if pred[n] >= 0 else -1
    return order, parent


def _cost(problem: AlignProblem, angles, t, c: int, cand: np.ndarray, rec: np.ndarray):
    """(K,) E_fit over records ``rec`` (own piece c) for candidate translations (K,2)."""
    tt = np.repeat(t[None], len(cand), axis=0)
    tt[:, c] = cand
    d, _ = problem.seam_mismatch(np.broadcast_to(angles, (len(cand), len(angles))), tt, rec)
    return np.hypot(d[..., 0], d[..., 1]) @ problem.record_weight[rec]


def _best_offset(problem: AlignProblem, angles, t, c: int, rec: np.ndarray, cell: np.ndarray,
                 sample: int, score_sample: int) -> tuple[np.ndarray, float]:
    """Exhaustive search for piece c's translation against the pieces across ``rec``.

    Candidates: for each of ``sample`` seam records and each symmetry operation the
    translation that makes that edge match exactly, plus a grid over the cell, plus the
    current translation; scored by E_fit over (up to ``score_sample``) records.
    """
    fr, ops = problem.frames, problem.wp.cartesian_ops()
    if len(rec) > score_sample:
        rec = rec[np.linspace(0, len(rec) - 1, score_sample).astype(int)]
    src = rec[np.linspace(0, len(rec) - 1, min(sample, len(rec))).astype(int)]
    o = fr.other[src]
    q_o = np.einsum("nji,nj->ni", rotation_matrices(angles[o]), fr.mid_other[src] - t[o])
    g_q = np.einsum("kij,nj->nki", ops[:, :2, :2], q_o) + ops[None, :, :2, 2]
    rc = rotation_matrices(angles[c])
    zeros = fr.mid[src][:, None, :] - g_q @ rc.T  # t_c with q_c = g(q_o) exactly
    cand = np.concatenate([zeros.reshape(-1, 2), t[c] - cell @ rc.T, t[c][None]])
    cost = _cost(problem, angles, t, c, cand, rec)
    k = int(np.argmin(cost))
    return cand[k], float(cost[k])


def _cell_grid(problem: AlignProblem, grid: int) -> np.ndarray:
    f = (np.arange(grid) + 0.5) / grid
    return np.stack(np.meshgrid(f, f, indexing="ij"), -1).reshape(-1, 2) @ problem.wp.basis.T


def tree_placement(problem: AlignProblem, angles: np.ndarray, t: np.ndarray, *,
                   grid: int = 6, sample: int = 16, score_sample: int = 64) -> np.ndarray:
    """Translations (P,2) placed piece by piece along the seam tree (module docstring)."""
    fr = problem.frames
    order, _ = _tree_order(problem, problem.piece_weights())
    t = t.copy()
    placed = np.zeros(problem.n_pieces, bool)
    live = problem.live_records()
    cell = _cell_grid(problem, grid)
    for c in order:
        rec = live[(fr.piece[live] == c) & placed[fr.other[live]]]
        placed[c] = True
        if problem.fix_trans[c] or len(rec) == 0:
            continue
        t[c], _ = _best_offset(problem, angles, t, c, rec, cell, sample, score_sample)
    return t


def exhaustive_sweep(problem: AlignProblem, angles: np.ndarray, t: np.ndarray, *,
                     grid: int = 6, sample: int = 12, score_sample: int = 48) -> np.ndarray:
    """One pass of per-piece exhaustive moves against all neighbours (block coordinate
    descent with a global search per block); a move is kept only if E_fit drops."""
    fr = problem.frames
    t = t.copy()
    live = problem.live_records()
    cell = _cell_grid(problem, grid)
    for c in range(problem.n_pieces):
        rec = live[fr.piece[live] == c]
        if problem.fix_trans[c] or len(rec) == 0:
            continue
        old = t[c].copy()
        before = float(_cost(problem, angles, t, c, old[None], rec)[0])
        new, _ = _best_offset(problem, angles, t, c, rec, cell, sample, score_sample)
        after = float(_cost(problem, angles, t, c, new[None], rec)[0])
        if after < before:
            t[c] = new
    return t


def _hop_rotations(problem: AlignProblem, a, t, e: float, rng: np.random.Generator,
                   hops: int, batch: int = 12):
    """Basin hopping over the rotations: the r-RoSy field leaves each piece's angle a
    few degrees from what suits E_fit (it measures angles, not positions), so random
    turns of a few degrees per piece are tried, each with its own translational solve
    (Eq. 9 + IRLS, batched), then an exhaustive sweep for the two best."""
    free = ~problem.fix_rot
    for k in range(hops):
        sigma = np.radians(4.0) / 2 ** k
        turn = rng.normal(0.0, sigma, (batch, problem.n_pieces)) * free
        ang = a[None] + turn
        if problem.grain is not None:
            ang = problem.grain.project(ang, problem.rosy, problem.fix_rot)
        tt = np.repeat(t[None], batch, axis=0)
        tt = optimise_translations(problem, ang, tt, polish_rounds=1).t
        tt = irls_translations(problem, ang, tt, iterations=8)
        en = problem.energy(ang, tt)
        for i in np.argsort(en, kind="stable")[:2]:
            moved = exhaustive_sweep(problem, ang[i], tt[i])
            tt[i] = irls_translations(problem, ang[i][None], moved[None])[0]
        en = problem.energy(ang, tt)
        i = int(np.argmin(en))
        if en[i] < e:
            a, t, e = ang[i], tt[i], float(en[i])
    return a, t, e


def align_global(problem: AlignProblem, *, restarts: int = 15, seed: int = 0,
                 rotation: bool = True, translation: bool = True, candidates: int = 4,
                 rotation_eps: float | None = None, sweeps: int = 2, hops: int = 2,
                 progress=None) -> AlignResult:
    """The method of the module docstring; never worse than ``align_paper`` with the
    same ``restarts`` and ``seed``."""
    kw = {} if rotation_eps is None else {"rotation_eps": rotation_eps}
    paper = align_paper(problem, restarts=restarts, seed=seed, rotation=rotation,
                        translation=translation, progress=progress, **kw)
    if not translation:  # rotations alone: E_fit needs positions, nothing more to search
        return _result(paper, paper.angles, paper.translations, problem)
    ang, t0 = _distinct_rotations(paper, candidates)
    if rotation and not problem.fix_rot.any():
        ang, t0 = _screen_common_turns(problem, ang, t0, candidates)
    cand_a, cand_t = _tree_candidates(problem, ang, t0)
    zero = 1e-9 * float(paper.random_energies.mean())  # nothing below this matters
    for _ in range(sweeps if problem.energy(cand_a, cand_t).min() > zero else 0):
        cand_t = _sweep_best(problem, cand_a, cand_t, candidates)
    e = problem.energy(cand_a, cand_t)
    if rotation and (~problem.fix_rot).any() and e.min() > zero:
        i = int(np.argmin(e))
        a_h, t_h, e_h = _hop_rotations(problem, cand_a[i], cand_t[i], float(e[i]),
                                       np.random.default_rng([seed, 1]), hops)
        cand_a = np.concatenate([cand_a, a_h[None]])
        cand_t = np.concatenate([cand_t, t_h[None]])
        e = np.append(e, e_h)
    perfect = float(e.min()) <= zero
    grids = GLOBAL_GRID.get(int((~problem.fix_trans).sum())) if not perfect else None
    if grids:
        cand_a, cand_t, e = _joint_grids(problem, cand_a, cand_t, e, grids)
    _refine_best(problem, cand_a, cand_t, e, 0 if perfect else 2, rotation)
    i = int(np.argmin(e))
    if grids:
        cand_a[i], cand_t[i], e[i] = _alternate(problem, cand_a[i], cand_t[i], float(e[i]),
                                                grids, rotation)
    best_a, best_t, best_e = paper.angles, paper.translations, paper.energy
    if e[i] < best_e:
        best_a, best_t = cand_a[i], cand_t[i]
    best_a, best_t = enforce_fixed(problem, best_a, best_t)
    out = _result(paper, best_a, best_t, problem)
    out.info["paper_energy"] = paper.energy
    return out


def _distinct_rotations(paper: AlignResult, candidates: int) -> tuple[np.ndarray, np.ndarray]:
    """Up to ``candidates`` of the paper's restarts with distinct rotations, best first:
    their angles (c, P) and translations (c, P, 2)."""
    picks: list[int] = []
    for k in np.argsort(paper.energies, kind="stable"):
        a = paper.all_angles[k]
        if all(np.abs(np.angle(np.exp(1j * (a - paper.all_angles[j])))).max() > 1e-3
               for j in picks):
            picks.append(int(k))
        if len(picks) >= candidates:
            break
    return paper.all_angles[picks], paper.all_translations[picks]


def _screen_common_turns(problem: AlignProblem, ang: np.ndarray, t0: np.ndarray,
                         candidates: int) -> tuple[np.ndarray, np.ndarray]:
    """The rotational energy hardly sees one rotation common to all pieces, so the
    paper's fields come out at a random overall angle to the print; E_fit does see it.
    Screen a grid of common turns over one r-th of a turn (Eq. 9 + IRLS, batched) and
    carry the best few on."""
    steps = max(8, 24 // problem.rosy)
    beta = 2 * np.pi * np.arange(steps) / (steps * problem.rosy)
    free = ~problem.fix_rot
    ang_b = (ang[:, None, :] + beta[None, :, None] * free).reshape(-1, problem.n_pieces)
    if problem.grain is not None:
        ang_b = problem.grain.project(ang_b, problem.rosy, problem.fix_rot)
    t_b = np.repeat(t0, steps, axis=0)
    t_b = optimise_translations(problem, ang_b, t_b, polish_rounds=1).t
    t_b = irls_translations(problem, ang_b, t_b, iterations=8)
    keep = np.argsort(problem.energy(ang_b, t_b), kind="stable")[:candidates]
    return ang_b[keep], t_b[keep]


def _tree_candidates(problem: AlignProblem, ang: np.ndarray, t0: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Per rotation three translation starts (the greedy tree, the tree DP, as given),
    each optimised (Eq. 9 from the trees) and IRLS-polished."""
    trees = np.stack([tree_placement(problem, ang[i], t0[i]) for i in range(len(ang))]
                     + [tree_dp_placement(problem, ang[i], t0[i]) for i in range(len(ang))])
    ts = optimise_translations(problem, np.concatenate([ang, ang]), trees)
    cand_a = np.concatenate([ang, ang, ang])
    return cand_a, irls_translations(problem, cand_a, np.concatenate([ts.t, t0]))


def _sweep_best(problem: AlignProblem, cand_a: np.ndarray, cand_t: np.ndarray,
                candidates: int) -> np.ndarray:
    """One exhaustive sweep of the best ``candidates`` placements, then IRLS for all."""
    top = np.argsort(problem.energy(cand_a, cand_t), kind="stable")[:candidates]
    moved = cand_t.copy()
    moved[top] = np.stack([exhaustive_sweep(problem, cand_a[i], cand_t[i]) for i in top])
    return irls_translations(problem, cand_a, moved)


def _joint_grids(problem: AlignProblem, cand_a: np.ndarray, cand_t: np.ndarray,
                 e: np.ndarray, grids: tuple[int, ...]
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Few movable pieces: the joint grid over all their translations is affordable;
    grids of several sizes, as their sample points interleave and a basin narrower than
    one grid step ranks among the best grid points of one size, not another. The grid is
    worth its cost only where the tree, sweeps and hops missed a basin: the sizes are
    tried in turn while they find a better one. Each grid's answer is a new candidate."""
    i = int(np.argmin(e))
    e_best = float(e[i])
    for grid in grids:
        tb, eb = brute_force(problem, cand_a[i], cand_t[i], grid=grid, polish=False)
        cand_a = np.concatenate([cand_a, cand_a[i][None]])
        cand_t = np.concatenate([cand_t, tb[None]])
        e = np.append(e, eb)
        if eb >= e_best * (1 - GRID_GAIN):
            break
        e_best = eb
    return cand_a, cand_t, e


def _refine_best(problem: AlignProblem, cand_a: np.ndarray, cand_t: np.ndarray,
                 e: np.ndarray, n: int, rotation: bool) -> None:
    """BFGS on the ``n`` best candidates, kept (in place) where it lowers E_fit."""
    for i in np.argsort(e, kind="stable")[:n]:
        a, tt, ei = bfgs_refine(problem, cand_a[i], cand_t[i], rotations=rotation,
                                max_iter=60)
        if ei < e[i]:
            tt = irls_translations(problem, a[None], tt[None])[0]
            cand_a[i], cand_t[i] = a, tt
            e[i] = float(problem.energy(a[None], tt[None])[0])


def _alternate(problem: AlignProblem, a_i: np.ndarray, t_i: np.ndarray, e_i: float,
               grids: tuple[int, ...], rotation: bool) -> tuple[np.ndarray, np.ndarray, float]:
    """The polished angles may open a better joint-grid basin: grid and BFGS in turn
    while the grid finds one, so the answer is grid-optimal for its own final angles."""
    for grid in grids[:ALTERNATE_ROUNDS]:
        tb, eb = brute_force(problem, a_i, t_i, grid=grid, polish=False)
        if eb >= e_i * (1 - 1e-9):
            break
        a2, t2, e2 = bfgs_refine(problem, a_i, tb, rotations=rotation, max_iter=60)
        a_i, t_i, e_i = (a2, t2, e2) if e2 < eb else (a_i, tb, eb)
    return a_i, t_i, e_i


def _result(paper: AlignResult, a, t, problem: AlignProblem) -> AlignResult:
    e = float(problem.energy(a[None], t[None])[0])
    if e > paper.energy:  # rounding guard: the paper's answer is the floor
        a, t, e = paper.angles, paper.translations, paper.energy
    return AlignResult(
        angles=a, translations=t, energy=e, energies=paper.energies,
        random_energies=paper.random_energies,
        rotation_iterations=paper.rotation_iterations,
        translation_iterations=paper.translation_iterations,
        all_angles=paper.all_angles, all_translations=paper.all_translations,
        info={**paper.info, "paper_energy": paper.energy},
    )
