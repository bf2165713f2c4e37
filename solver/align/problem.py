"""One alignment problem: garment seams, print, weights, fixed pieces and grain, ready for
the vectorised steps; plus the batched E_fit used to compare restarts.

Restarts are run side by side: every state array carries a leading batch axis ``B`` (one
row per random start), so a sweep over the pieces costs a few NumPy calls for all starts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from solver.align.frames import SeamFrames, seam_frames
from solver.align.grain import GrainRule
from solver.align.kernels import seam_points
from solver.geometry import rotate_back
from solver.wallpaper import Wallpaper


def greedy_colouring(n: int, pairs: np.ndarray) -> list[np.ndarray]:
    """Colour classes of the piece graph: pieces of one class share no seam.

    Updating one class at once is then exactly the paper's sequential (Gauss-Seidel)
    sweep over the pieces in class order. Pieces are few, so a Python loop is fine.
    """
    adj = [set() for _ in range(n)]
    for a, b in pairs.tolist():
        if a != b:
            adj[a].add(b)
            adj[b].add(a)
    colour = np.full(n, -1)
    for v in sorted(range(n), key=lambda i: -len(adj[i])):
        used = {colour[u] for u in adj[v]}
        colour[v] = next(c for c in range(n + 1) if c not in used)
    return [np.flatnonzero(colour == c) for c in range(colour.max() + 1)]


@dataclass
class AlignProblem:
    """Everything the steps need, precomputed once per garment and print.

    ``weight`` is w_S per seam edge (garment weights, overridden by the user's file);
    records are the directed seam-edge records of :mod:`solver.align.frames`.
    ``fix_rot``/``fix_trans`` (P,) bool keep a piece's rotation/translation at ``init``.
    """

    wp: Wallpaper
    frames: SeamFrames
    weight: np.ndarray  # (E,) per seam edge
    n_pieces: int
    fix_rot: np.ndarray
    fix_trans: np.ndarray
    init_angles: np.ndarray
    init_translations: np.ndarray
    grain: GrainRule | None
    reflect: bool
    colours: list[np.ndarray]  # colour classes of the pieces
    rosy: int  # r of the r-RoSy

    def mismatch(self, p: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """p, q (..., 2) in wallpaper space -> d (..., 2) from p to the closest
        equivalent of q, and the operation's index (...,): ``Wallpaper.closest``."""
        return self.wp.closest(p, q)

    # -------------------------------------------------------------- construction
    @classmethod
    def build(cls, garment, wp: Wallpaper, *, weights=None, fix_rot=None, fix_trans=None,
              init_angles=None, init_translations=None, grain: GrainRule | None = None,
              reflect: bool = False, use_drape: bool = True) -> AlignProblem:
        p = garment.n_pieces
        w = garment.seam_weights() if weights is None else np.asarray(weights, float)
        if w.shape != (len(garment.seam_edges),):
            raise ValueError(f"{len(w)} seam weights for {len(garment.seam_edges)} seam edges")
        fr = seam_frames(garment, use_drape=use_drape)
        rec_w = np.concatenate([w, w])
        live = (fr.piece != fr.other) & (rec_w > 0)
        pairs = np.column_stack([fr.piece[live], fr.other[live]])
        return cls(
            wp=wp, frames=fr, weight=w, n_pieces=p,
            fix_rot=np.zeros(p, bool) if fix_rot is None else np.asarray(fix_rot, bool),
            fix_trans=np.zeros(p, bool) if fix_trans is None else np.asarray(fix_trans, bool),
            init_angles=np.zeros(p) if init_angles is None else np.asarray(init_angles, float),
            init_translations=(np.zeros((p, 2)) if init_translations is None
                               else np.asarray(init_translations, float).reshape(p, 2)),
            grain=grain, reflect=reflect, colours=greedy_colouring(p, pairs),
            rosy=wp.info.rotation_order,
        )

    # -------------------------------------------------------------- record views
    def sweep_plan(self, fixed: np.ndarray, normalise: bool = False) -> list:
        """Per colour class: its movable pieces, their live records and the scatter matrix.

        Pieces of one colour share no seam, so a class is updated at once, which equals
        the paper's piece-by-piece sweep. ``scatter[k, j]`` is w_S l_e of record j if it
        belongs to piece k (divided by the piece's total weight w_c when ``normalise``, as
        Eq. 9 needs).
        """
        fr, w = self.frames, self.record_weight
        movable = np.flatnonzero(~np.asarray(fixed, bool))
        plan = []
        for cls in self.colours:
            pieces = np.intersect1d(cls, movable)
            rec = self.live_records(pieces)
            if len(pieces) == 0 or len(rec) == 0:
                continue
            scatter = (fr.piece[rec][None, :] == pieces[:, None]) * w[rec][None, :]
            if normalise:
                total = scatter.sum(axis=1, keepdims=True)
                scatter = scatter / np.where(total > 0, total, 1.0)
            plan.append((pieces, rec, scatter))
        return plan

    @property
    def record_weight(self) -> np.ndarray:
        """(R,) w_S l_e of every directed record."""
        return np.concatenate([self.weight, self.weight]) * self.frames.length

    def live_records(self, pieces: np.ndarray | None = None) -> np.ndarray:
        """Indices of records that drive the updates: weight > 0, not a self-seam, and
        (optionally) whose updated piece is in ``pieces``."""
        fr = self.frames
        ok = (fr.piece != fr.other) & (self.record_weight > 0)
        if pieces is not None:
            ok &= np.isin(fr.piece, pieces)
        return np.flatnonzero(ok)

    def piece_weights(self) -> np.ndarray:
        """(P, P) summed weight of the live seam records of piece i facing piece j: the
        piece graph the tree placements span."""
        fr = self.frames
        rec = self.live_records()
        w = np.zeros((self.n_pieces, self.n_pieces))
        np.add.at(w, (fr.piece[rec], fr.other[rec]), self.record_weight[rec])
        return w

    # -------------------------------------------------------------- random starts
    def random_starts(self, rng: np.random.Generator, n: int):
        """(n,P) angles and (n,P,2) translations: uniform angle, uniform offset in a cell.

        Fixed pieces keep their ``init`` values.
        """
        ang = rng.uniform(0.0, 2 * np.pi, size=(n, self.n_pieces))
        frac = rng.uniform(0.0, 1.0, size=(n, self.n_pieces, 2))
        t = frac @ self.wp.basis.T + self.wp.origin
        ang = np.where(self.fix_rot, self.init_angles, ang)
        t = np.where(self.fix_trans[:, None], self.init_translations, t)
        if self.grain is not None:
            ang = self.grain.project(ang, self.rosy, self.fix_rot)
        return ang, t

    # -------------------------------------------------------------- energy
    def wallpaper_points(self, angles: np.ndarray, trans: np.ndarray, rec: np.ndarray):
        """Midpoints of records ``rec`` on both sides in wallpaper space: (B,n,2) twice."""
        fr = self.frames
        c, o = fr.piece[rec], fr.other[rec]
        return (rotate_back(angles[:, c], fr.mid[rec] - trans[:, c]),
                rotate_back(angles[:, o], fr.mid_other[rec] - trans[:, o]))

    def seam_mismatch(self, angles: np.ndarray, trans: np.ndarray,
                      rec: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Records ``rec`` under placements (B,P), (B,P,2): d (B,n,2) from each record's
        own point to the closest equivalent of its twin's point in wallpaper space, and
        the operation (B,n); `wallpaper_points` and `mismatch` in one compiled pass."""
        fr = self.frames
        angles = np.asarray(angles, float)
        trans = np.ascontiguousarray(trans, float)
        rec = np.ascontiguousarray(rec, np.int64)
        q_c = np.empty((len(trans), len(rec), 2))
        q_o = np.empty_like(q_c)
        seam_points(np.cos(angles), np.sin(angles), trans, rec, fr.piece, fr.other, fr.mid,
                    fr.mid_other, q_c, q_o)
        return self.wp.closest(q_c, q_o)

    def energy(self, angles: np.ndarray, trans: np.ndarray,
               weight: np.ndarray | None = None) -> np.ndarray:
        """(B,) E_fit of Eq. (1) for a batch of placements (as solver.fit computes it)."""
        rec = np.arange(self.frames.n_edges)  # side a: one record per twin pair
        w = (self.weight if weight is None else weight) * self.frames.length[rec]
        d, _ = self.seam_mismatch(angles, trans, rec)
        return np.hypot(d[..., 0], d[..., 1]) @ w
