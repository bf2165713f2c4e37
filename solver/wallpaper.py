"""The 17 plane (wallpaper) groups and the closest-equivalent-point query.

Every later step (fit measure, ideal seams, print rendering, group classification,
nesting) derives from the one table ``_ITA_TABLE`` below, so there is no per-group
special case anywhere else.

Source of the operations: International Tables for Crystallography, Vol. A,
*Space-group symmetry* (ed. Th. Hahn, 5th ed., 2002), Part 6 "The 17 plane groups
(two-dimensional space groups)", the "Coordinates" lists of the general position of
plane groups No. 1 (p1) to No. 17 (p6mm), standard settings. The triplets are copied
as facts, in ITA's notation; the centred groups c1m1 (cm) and c2mm (cmm) are given there
on the conventional centred rectangular cell with centring (1/2, 1/2) and are converted
here to the primitive rhombic cell ``w1 = (a + b)/2``, ``w2 = (b - a)/2``.

Conventions (millimetres throughout):

- a point ``p`` has fractional coordinates ``f = W^-1 (p - origin)``, ``W = [w1 w2]``;
- an operation is ``f -> M f + t``; ``GroupInfo.ops`` holds them as ``(n, 2, 3)``
  arrays ``[M | t]``, ``ops[0]`` the identity, ``n`` the equivalent points per
  primitive cell;
- rectangular groups (pm, pg, pmm, pmg, pgg) need ``w1 ⟂ w2``; their mirror or glide
  lines of pm, pg and the m/g pair of pmg follow ITA (``-x, y``: mirror along ``w2``);
- centred groups (cm, cmm) need ``|w1| = |w2|`` (a rhombus); the mirror of cm runs
  along ``w1 + w2``;
- square groups need ``|w1| = |w2|`` at a right angle, hexagonal groups at 120°.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import untrusted
from solver.geometry import rotation_matrix
from solver.jsonfile import read_json
from solver.units import mm_per_unit

GROUP_NAMES: tuple[str, ...] = (
    "p1", "p2", "pm", "pg", "cm", "pmm", "pmg", "pgg", "cmm",
    "p4", "p4m", "p4g", "p3", "p3m1", "p31m", "p6", "p6m",
)  # fmt: skip

# name: (ITA symbol, lattice type, ITA coordinate triplets of the general position).
_ITA_TABLE: dict[str, tuple[str, str, tuple[str, ...]]] = {
    "p1": ("p1", "oblique", ("x,y",)),
    "p2": ("p2", "oblique", ("x,y", "-x,-y")),
    "pm": ("p1m1", "rectangular", ("x,y", "-x,y")),
    "pg": ("p1g1", "rectangular", ("x,y", "-x,y+1/2")),
    "cm": ("c1m1", "rhombic", ("x,y", "-x,y")),
    "pmm": ("p2mm", "rectangular", ("x,y", "-x,-y", "-x,y", "x,-y")),
    "pmg": ("p2mg", "rectangular", ("x,y", "-x,-y", "-x+1/2,y", "x+1/2,-y")),
    "pgg": ("p2gg", "rectangular", ("x,y", "-x,-y", "-x+1/2,y+1/2", "x+1/2,-y+1/2")),
    "cmm": ("c2mm", "rhombic", ("x,y", "-x,-y", "-x,y", "x,-y")),
    "p4": ("p4", "square", ("x,y", "-x,-y", "-y,x", "y,-x")),
    "p4m": ("p4mm", "square",
            ("x,y", "-x,-y", "-y,x", "y,-x", "-x,y", "x,-y", "y,x", "-y,-x")),
    "p4g": ("p4gm", "square",
            ("x,y", "-x,-y", "-y,x", "y,-x",
             "-x+1/2,y+1/2", "x+1/2,-y+1/2", "y+1/2,x+1/2", "-y+1/2,-x+1/2")),
    "p3": ("p3", "hexagonal", ("x,y", "-y,x-y", "-x+y,-x")),
    "p3m1": ("p3m1", "hexagonal",
             ("x,y", "-y,x-y", "-x+y,-x", "-y,-x", "-x+y,y", "x,x-y")),
    "p31m": ("p31m", "hexagonal",
             ("x,y", "-y,x-y", "-x+y,-x", "y,x", "x-y,-y", "-x,-x+y")),
    "p6": ("p6", "hexagonal",
           ("x,y", "-y,x-y", "-x+y,-x", "-x,-y", "y,-x+y", "x-y,x")),
    "p6m": ("p6mm", "hexagonal",
            ("x,y", "-y,x-y", "-x+y,-x", "-x,-y", "y,-x+y", "x-y,x",
             "-y,-x", "-x+y,y", "x,x-y", "y,x", "x-y,-y", "-x,-x+y")),
}  # fmt: skip

# Conventional (a, b) -> primitive (w1, w2) for the centred cell: [w1 w2] = [a b] P.
_CENTRED_TO_PRIMITIVE = np.array([[0.5, -0.5], [0.5, 0.5]])

LATTICE_RULES = {
    "oblique": "any two independent vectors",
    "rectangular": "w1 perpendicular to w2",
    "rhombic": "|w1| = |w2| (the primitive rhombus of a centred rectangular lattice)",
    "square": "|w1| = |w2| at a right angle",
    "hexagonal": "|w1| = |w2| at 120 degrees",
}


@dataclass(frozen=True)
class GroupInfo:
    """One plane group: its table of operations and the facts derived from it."""

    name: str
    ita_symbol: str
    lattice: str
    ops: np.ndarray  # (n, 2, 3) fractional affine maps [M | t] on the primitive cell
    rotation_order: int
    has_mirror: bool
    has_glide: bool

    @property
    def n_equivalent(self) -> int:
        return len(self.ops)


def _parse_triplet(triplet: str) -> np.ndarray:
    """ITA coordinate triplet such as ``-x+1/2,y+1/2`` -> 2x3 matrix [M | t]."""
    out = np.zeros((2, 3))
    for row, expr in enumerate(triplet.split(",")):
        terms = expr.replace("-", "+-").split("+")
        for term in filter(None, terms):
            sign = -1.0 if term.startswith("-") else 1.0
            body = term.lstrip("-")
            if body in ("x", "y"):
                out[row, "xy".index(body)] += sign
            else:
                num, _, den = body.partition("/")
                out[row, 2] += sign * float(num) / float(den or 1)
    return out


def _classify_op(op: np.ndarray) -> tuple[int, bool, bool]:
    """(rotation order, yields a mirror, yields a glide) of one operation's coset.

    Orders and reflections are basis independent, so the fractional matrix is enough.
    A reflection composed with a lattice translation L has the glide component
    ``(M (t + L) + t + L) / 2``: a mirror exists when it can be a lattice vector, a
    true glide when it can be something else (as in cm, where mirrors and glides
    alternate).
    """
    m, t = op[:, :2], op[:, 2]
    if round(float(np.linalg.det(m))) == 1:
        trace = round(float(np.trace(m)))
        return {2: 1, -2: 2, 1: 6, 0: 4, -1: 3}[trace], False, False
    shifts = np.array([(i, j) for i in (-1, 0, 1) for j in (-1, 0, 1)], float)
    g = ((t + shifts) @ m.T + t + shifts) / 2.0
    integral = np.all(np.isclose(g, np.round(g)), axis=1)
    return 1, bool(integral.any()), bool((~integral).any())


def _build_group(name: str) -> GroupInfo:
    symbol, lattice, triplets = _ITA_TABLE[name]
    ops = np.stack([_parse_triplet(t) for t in triplets])
    if lattice == "rhombic":
        p = _CENTRED_TO_PRIMITIVE
        p_inv = np.linalg.inv(p)
        ops = np.stack(
            [np.column_stack([p_inv @ op[:, :2] @ p, p_inv @ op[:, 2]]) for op in ops]
        )
    ops[:, :, 2] -= np.floor(ops[:, :, 2] + 1e-12)  # translations in [0, 1)
    kinds = [_classify_op(op) for op in ops]
    return GroupInfo(
        name=name,
        ita_symbol=symbol,
        lattice=lattice,
        ops=ops,
        rotation_order=max(k[0] for k in kinds),
        has_mirror=any(k[1] for k in kinds),
        has_glide=any(k[2] for k in kinds),
    )


GROUPS: dict[str, GroupInfo] = {name: _build_group(name) for name in GROUP_NAMES}


def gauss_reduce(w1: np.ndarray, w2: np.ndarray, *,
                 obtuse: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lagrange-Gauss reduction of a 2D lattice basis.

    Returns ``(u1, u2, U)`` with ``[u1 u2] = [w1 w2] U``, ``U`` unimodular, ``|u1| <= |u2|``
    and ``|u1 . u2| <= |u1|^2 / 2``. With such a basis the lattice vector closest to any
    point lies among the 3x3 neighbours of its rounded fractional coordinates.
    ``obtuse`` also makes ``u1 . u2 <= 0`` (angle 90-120 degrees; ``u2 - u1`` where it is as
    short as ``u2``), so equal lattices give equal bases up to a common sign, as lattice
    detection compares them.
    """
    b = np.column_stack([w1, w2]).astype(float)
    u = np.eye(2, dtype=np.int64)
    for _ in range(200):
        if b[:, 0] @ b[:, 0] > b[:, 1] @ b[:, 1]:
            b = b[:, ::-1]
            u = u[:, ::-1]
        mu = round(float(b[:, 0] @ b[:, 1] / (b[:, 0] @ b[:, 0])))
        if mu == 0:
            break
        b[:, 1] -= mu * b[:, 0]
        u[:, 1] -= mu * u[:, 0]
    if obtuse and b[:, 0] @ b[:, 1] > 0:
        diff = b[:, 1] - b[:, 0]
        if diff @ diff <= b[:, 1] @ b[:, 1] + 1e-9:
            b[:, 1], u[:, 1] = diff, u[:, 1] - u[:, 0]
        if b[:, 0] @ b[:, 1] > 0:
            b[:, 1], u[:, 1] = -b[:, 1], -u[:, 1]
    return b[:, 0].copy(), b[:, 1].copy(), u


def covering_radius(basis: np.ndarray) -> float:
    """Largest distance from a point of the plane to its nearest lattice point (mm).

    ``basis`` (2, 2) holds a lattice basis as columns. It is the circumradius of the acute
    triangle of the reduced basis (half the diagonal of a square cell, a/sqrt(3) for a
    hexagonal one).
    """
    b = np.asarray(basis, float)
    r1, r2, _ = gauss_reduce(b[:, 0], b[:, 1])
    if r1 @ r2 < 0:
        r2 = -r2
    area2 = abs(r1[0] * r2[1] - r1[1] * r2[0])
    return float(np.linalg.norm(r1) * np.linalg.norm(r2) * np.linalg.norm(r1 - r2)
                 / (2.0 * area2))


_IDENTITY_LIN = np.eye(2)[None]
_IDENTITY_SHIFT = np.zeros((1, 2))


def _lattice_fault(lattice: str, w1: np.ndarray, w2: np.ndarray, tol: float) -> str | None:
    """Why (w1, w2) does not fit the lattice type, or None when it does."""
    l1, l2 = float(np.hypot(*w1)), float(np.hypot(*w2))
    cos = float(w1 @ w2) / (l1 * l2)
    angle = math.degrees(math.acos(max(-1.0, min(1.0, cos))))
    lengths_equal = abs(l1 - l2) <= tol * max(l1, l2)
    tol_deg = math.degrees(tol)
    need_angle = {"rectangular": 90.0, "square": 90.0, "hexagonal": 120.0}.get(lattice)
    need_equal = lattice in ("rhombic", "square", "hexagonal")
    faults = []
    if need_equal and not lengths_equal:
        faults.append(f"|w1| = {l1:.4g} mm and |w2| = {l2:.4g} mm differ")
    if need_angle is not None and abs(angle - need_angle) > tol_deg:
        hint = ""
        if lattice == "hexagonal" and abs(angle - 60.0) <= tol_deg:
            hint = " (a 60 degree basis: use w2 - w1 as w2)"
        faults.append(f"the angle between w1 and w2 is {angle:.3f} degrees, "
                      f"not {need_angle:g}{hint}")
    if not faults:
        return None
    return "; ".join(faults) + f"; a {lattice} lattice needs {LATTICE_RULES[lattice]}"


def _standard_basis(lattice: str, w1: np.ndarray, w2: np.ndarray, tol: float):
    """A basis of the same lattice in the group's standard form, or None.

    Accepts non-reduced input (e.g. w2 + 3 w1): tries the small unimodular changes of
    the reduced basis and keeps the one whose first vector is closest in direction to
    the given w1, so an operator's choice of axes is kept where the lattice allows.
    """
    if _lattice_fault(lattice, w1, w2, tol) is None:
        return w1, w2
    u1, u2, _ = gauss_reduce(w1, w2)
    best, best_score = None, -np.inf
    rng = range(-1, 2)
    for a in rng:
        for b in rng:
            for c in rng:
                for d in rng:
                    if a * d - b * c != 1:
                        continue
                    v1, v2 = a * u1 + c * u2, b * u1 + d * u2
                    if _lattice_fault(lattice, v1, v2, tol) is not None:
                        continue
                    score = float(v1 @ w1) / (np.hypot(*v1) * np.hypot(*w1))
                    if score > best_score:
                        best, best_score = (v1, v2), score
    return best


class Wallpaper:
    """A wallpaper print: group, lattice ``w1, w2`` and origin ``w0`` in millimetres.

    ``tol`` is the relative length tolerance (and the angle tolerance in radians) of
    the lattice check; 1e-3 accepts a hand-measured lattice and rejects a wrong one.
    Use :meth:`snapped` for a measured lattice that should be forced to its group.
    """

    def __init__(self, group: str, w1, w2, origin=(0.0, 0.0), *, tol: float = 1e-3,
                 motif: np.ndarray | None = None) -> None:
        if group not in GROUPS:
            raise ValueError(f"unknown wallpaper group {group!r}; expected one of "
                             f"{', '.join(GROUP_NAMES)}")
        w1, w2, origin = (np.asarray(v, dtype=float).reshape(2) for v in (w1, w2, origin))
        if not np.all(np.isfinite(np.concatenate([w1, w2, origin]))):
            raise ValueError("wallpaper lattice and origin must be finite numbers")
        if abs(w1[0] * w2[1] - w1[1] * w2[0]) <= 1e-9 * max(w1 @ w1, w2 @ w2, 1e-300):
            raise ValueError(f"w1 = {w1.tolist()} and w2 = {w2.tolist()} are parallel or zero: "
                             "a lattice needs two independent vectors")
        self.info = GROUPS[group]
        standard = _standard_basis(self.info.lattice, w1, w2, tol)
        if standard is None:
            raise ValueError(f"lattice does not fit group {group}: "
                             f"{_lattice_fault(self.info.lattice, w1, w2, tol)}")
        self.group = group
        self.w1, self.w2 = standard
        self.origin = origin
        self.motif = motif
        self.basis = np.column_stack([self.w1, self.w2])
        self._basis_inv = np.linalg.inv(self.basis)
        r1, r2, _ = gauss_reduce(self.w1, self.w2)
        self._reduced = np.column_stack([r1, r2])
        self._reduced_inv = np.linalg.inv(self._reduced)
        self._ops_cart = self._cartesian_ops()
        self._lin = np.ascontiguousarray(self._ops_cart[:, :2, :2])
        self._shift = np.ascontiguousarray(self._ops_cart[:, :2, 2])
        # the same operations in the reduced basis' fractional coordinates (the kernel's)
        self._flin = np.ascontiguousarray(
            np.einsum("ij,njk,kl->nil", self._reduced_inv, self._lin, self._reduced))
        self._fshift = np.ascontiguousarray(self._shift @ self._reduced_inv.T)

    # ---------------------------------------------------------------- construction
    @classmethod
    def snapped(cls, group: str, w1, w2, origin=(0.0, 0.0), *, snap_tol: float = 0.2,
                **kw) -> Wallpaper:
        """The nearest lattice that fits ``group`` exactly (for measured lattices).

        Lengths are averaged where they must be equal and the two vectors are turned
        symmetrically about their bisector where the angle is fixed. ``snap_tol`` is how
        far (relative length, angle in radians) a measured lattice may be off the group's.
        """
        lattice = GROUPS[group].lattice
        w1, w2 = np.asarray(w1, float), np.asarray(w2, float)
        if lattice == "oblique":
            return cls(group, w1, w2, origin, **kw)
        u = _standard_basis(lattice, w1, w2, tol=snap_tol)
        if u is None:
            raise ValueError(f"lattice {w1.tolist()}, {w2.tolist()} is too far from a "
                             f"{lattice} lattice for group {group}")
        v1, v2 = u
        l1, l2 = np.hypot(*v1), np.hypot(*v2)
        if lattice in ("rhombic", "square", "hexagonal"):
            l1 = l2 = math.sqrt(l1 * l2)
        a1, a2 = math.atan2(v1[1], v1[0]), math.atan2(v2[1], v2[0])
        need = {"rectangular": 90.0, "square": 90.0, "hexagonal": 120.0}.get(lattice)
        if need is not None:
            sweep = (a2 - a1 + math.pi) % (2 * math.pi) - math.pi
            mid, half = a1 + sweep / 2, math.copysign(math.radians(need) / 2, sweep)
            a1, a2 = mid - half, mid + half
        return cls(group, l1 * np.array([math.cos(a1), math.sin(a1)]),
                   l2 * np.array([math.cos(a2), math.sin(a2)]), origin, **kw)

    @classmethod
    def from_dict(cls, d: dict[str, Any], source: str = "fabric description") -> Wallpaper:
        """FABRIC.json content -> Wallpaper, converting ``units`` to millimetres.

        Each lattice vector must be 1 mm .. 2 m long (the field's repeats), so a bad file
        cannot make later steps tile a table with billions of cells.
        """
        d = untrusted.mapping(d, source)
        missing = [k for k in ("group", "w1", "w2") if k not in d]
        if missing:
            raise untrusted.InputError(source, f"fabric description lacks {', '.join(missing)}")
        units = untrusted.text(d.get("units", "mm"), source, "units", max_len=8)
        try:
            scale = mm_per_unit(units)
        except ValueError as exc:
            raise untrusted.InputError(source, str(exc)) from None
        group = untrusted.text(d["group"], source, "group", max_len=8)
        lo, hi = untrusted.limits.MIN_REPEAT_MM, untrusted.limits.MAX_REPEAT_MM
        w = [untrusted.vector(d[k], source, k, max_abs=math.inf) * scale for k in ("w1", "w2")]
        for k, vec in zip(("w1", "w2"), w):
            if not lo <= float(np.hypot(*vec)) <= hi:
                raise untrusted.InputError(source, f"{k} is {float(np.hypot(*vec)):g} mm long; "
                                           f"a print repeats every {lo:g} to {hi:g} mm")
        origin = untrusted.vector(d.get("origin", [0.0, 0.0]), source, "origin") * scale
        try:
            return cls(group, w[0], w[1], origin)
        except ValueError as exc:
            raise untrusted.InputError(source, str(exc)) from None

    @classmethod
    def load(cls, path: str | Path) -> Wallpaper:
        return cls.from_dict(read_json(path), str(path))

    def to_dict(self) -> dict[str, Any]:
        return {"group": self.group, "w1": self.w1.tolist(), "w2": self.w2.tolist(),
                "origin": self.origin.tolist(), "units": "mm"}

    def reduced(self) -> Wallpaper:
        """The same print described by a Gauss-reduced basis where the group allows it."""
        r1, r2 = self._reduced[:, 0], self._reduced[:, 1]
        if _lattice_fault(self.info.lattice, r1, r2, 1e-9) is None:
            return Wallpaper(self.group, r1, r2, self.origin, motif=self.motif)
        return self

    def moved(self, rotation: float = 0.0, translation=(0.0, 0.0)) -> Wallpaper:
        """The print after the rigid motion ``p -> R(rotation) p + translation``."""
        r = rotation_matrix(rotation)
        return Wallpaper(self.group, r @ self.w1, r @ self.w2,
                         r @ self.origin + np.asarray(translation, float), motif=self.motif)

    def __repr__(self) -> str:
        return (f"Wallpaper({self.group!r}, w1={self.w1.round(6).tolist()}, "
                f"w2={self.w2.round(6).tolist()}, origin={self.origin.round(6).tolist()})")

    # ---------------------------------------------------------------- geometry
    @property
    def n_equivalent(self) -> int:
        return self.info.n_equivalent

    def to_fractional(self, p) -> np.ndarray:
        return (np.asarray(p, float) - self.origin) @ self._basis_inv.T

    def to_cartesian(self, f) -> np.ndarray:
        return np.asarray(f, float) @ self.basis.T + self.origin

    def _cartesian_ops(self) -> np.ndarray:
        ops = self.info.ops
        w, w_inv, o = self.basis, self._basis_inv, self.origin
        lin = np.einsum("ij,njk,kl->nil", w, ops[:, :, :2], w_inv)
        shift = ops[:, :, 2] @ w.T + o - lin @ o
        h = np.zeros((len(ops), 3, 3))
        h[:, :2, :2], h[:, :2, 2], h[:, 2, 2] = lin, shift, 1.0
        return h

    def cartesian_ops(self) -> np.ndarray:
        """(n, 3, 3) homogeneous maps in mm, each taking a point to an equivalent one."""
        return self._ops_cart.copy()

    def equivalent_points(self, p) -> np.ndarray:
        """(N, n, 2): the image of each point under every operation (not cell-reduced)."""
        p = np.asarray(p, float).reshape(-1, 2)
        ops = self._ops_cart
        return np.einsum("nij,pj->pni", ops[:, :2, :2], p) + ops[None, :, :2, 2]

    def closest(self, p, q) -> tuple[np.ndarray, np.ndarray]:
        """The closest-equivalent-point query, for whole batches of pairs.

        ``p, q`` (..., 2) broadcast together -> ``d`` (..., 2), the vector from each ``p``
        to the closest point equivalent to its ``q`` (the image of q under any operation
        and any lattice translation), and ``op`` (...,) the index into `cartesian_ops` of
        that operation. Every user (E_fit, alignment, reshaping, nesting, vision) goes
        through this one compiled kernel (:mod:`solver._closest`).
        """
        return self._run_kernel(p, q, self._flin, self._fshift)

    @property
    def kernel_tables(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(flin, fshift, reduced, reduced_inv)`` as the compiled kernel
        (:func:`solver._closest.closest_pair`) takes them: the operations' linear parts
        (n, 2, 2) and shifts (n, 2) in the fractional coordinates of the reduced basis, that
        basis as columns (mm) and its inverse."""
        return self._flin, self._fshift, self._reduced, self._reduced_inv

    @property
    def cartesian_tables(self) -> tuple[np.ndarray, np.ndarray]:
        """``(lin, shift)``: the operations' linear parts (n, 2, 2) and shifts (n, 2) in mm,
        contiguous (`cartesian_ops` without the homogeneous row)."""
        return self._lin, self._shift

    def _run_kernel(self, p, q, lin: np.ndarray, shift: np.ndarray):
        # numba costs ~0.35 s to import: loaded on the first query, not with the CLI
        from solver._closest import closest_equivalent

        p, q = np.asarray(p, float), np.asarray(q, float)
        full = np.broadcast_shapes(p.shape, q.shape)
        shape = full[:-1]
        # contiguous and writeable (numba warns on read-only views): broadcast_to's stride-0
        # views are copied, arrays of the full shape are passed as they are
        p2 = np.require((p if p.shape == full else np.broadcast_to(p, full)).reshape(-1, 2),
                        float, ["C", "W"])
        q2 = np.require((q if q.shape == full else np.broadcast_to(q, full)).reshape(-1, 2),
                        float, ["C", "W"])
        d = np.empty_like(p2)
        op = np.empty(len(p2), np.int64)
        closest_equivalent(p2, q2, lin, shift, self._reduced, self._reduced_inv, d, op)
        return d.reshape(*shape, 2), op.reshape(shape)

    def lattice_residual(self, d) -> np.ndarray:
        """Shortest representative of each vector ``d`` (..., 2) modulo the lattice."""
        return self._run_kernel(np.zeros(2), d, _IDENTITY_LIN, _IDENTITY_SHIFT)[0]

    @property
    def covering_radius(self) -> float:
        """Largest distance from any point to its nearest lattice point (mm), hence a
        bound on every `mismatch` (see :func:`covering_radius`)."""
        return covering_radius(self._reduced)

    def mismatch(self, p, q) -> np.ndarray:
        """(N, 2) vector from each ``p`` to the closest point equivalent to ``q``.

        Equivalent = the image of q under any operation and any lattice translation.
        """
        return self.closest(np.reshape(p, (-1, 2)), np.reshape(q, (-1, 2)))[0]

    def closest_symmetry(self, p, q) -> tuple[np.ndarray, np.ndarray]:
        """The symmetry taking each ``q`` closest to its ``p``: operation index (N,)
        into `cartesian_ops` and whole lattice vector (N, 2) added after it, so that
        ``ops[k] q + lattice - p == mismatch(p, q)``."""
        p, q = np.reshape(p, (-1, 2)), np.reshape(q, (-1, 2))
        d, op = self.closest(p, q)
        g = self._ops_cart[op]
        image = np.einsum("nij,nj->ni", g[:, :2, :2], q) + g[:, :2, 2]
        return op, d - (image - p)

    def mismatch_distance(self, p, q) -> np.ndarray:
        return np.hypot(*self.mismatch(p, q).T)
