"""What a reshape run achieved: the numbers the issue asks for, JSON-ready."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from solver.fit import FitReport, fit_report
from solver.geometry import signed_areas
from solver.reshape.ideal import IdealSeams, ideal_move_rms
from solver.reshape.quality import outline_roughness, seam_ease_changes


@dataclass(frozen=True)
class ReshapeReport:
    """E_fit before/after (mm²), twin length mismatch L (mm), effort and damage done."""

    e_fit_before_mm2: float
    e_fit_after_mm2: float
    length_mismatch_initial_mm: float
    length_mismatch_final_mm: float
    epsilon_mm: float
    gamma_rounds: int
    gamma_final: float
    iterations: int
    factorisations: int
    seconds: float
    max_displacement_mm: float
    max_ideal_displacement_mm: float
    flipped_triangles: int
    faces: int
    vertices: int
    subdivisions: int = 0  # times the input mesh was subdivided first (faces x 4 each)
    max_move_bound_mm: float = float("inf")  # the bound the moves were held to
    area_change_max_pct: float = 0.0  # largest |area change| of a piece, % of its area
    # per piece: name, largest move (mm), area change (%), seam length change (mm and %)
    pieces: tuple[dict, ...] = ()
    # per seam line: its pieces, both sides' lengths and length changes, its ease change
    # (`solver.reshape.quality.seam_ease_changes`), all mm
    seams: tuple[dict, ...] = ()
    ease_change_max_mm: float = 0.0  # the largest |ease change| of a seam line
    sewn_drift_max_mm: float = 0.0  # the largest drift of a notch from its partner
    # the outline's displacement that its 10 mm moving average does not explain
    # (`solver.reshape.quality.outline_roughness`): 95th percentile and largest, mm
    roughness_p95_mm: float = 0.0
    roughness_max_mm: float = 0.0
    # the seam lines whose ideal lines lie beyond reach (`seam_reach`): no reshape within
    # the bound fits them, so their mismatch stays; named so the report can say so
    seams_out_of_reach: tuple[str, ...] = ()

    @property
    def e_fit_ratio(self) -> float:
        """after / before (0 when before is 0: nothing to improve)."""
        return self.e_fit_after_mm2 / self.e_fit_before_mm2 if self.e_fit_before_mm2 else 0.0

    def to_dict(self) -> dict:
        d = asdict(self)
        d["pieces"] = list(self.pieces)
        d["seams"] = list(self.seams)
        d["seams_out_of_reach"] = list(self.seams_out_of_reach)
        d["max_move_bound_mm"] = (None if not np.isfinite(self.max_move_bound_mm)
                                  else self.max_move_bound_mm)
        d["e_fit_before_cm2"] = self.e_fit_before_mm2 / 100.0
        d["e_fit_after_cm2"] = self.e_fit_after_mm2 / 100.0
        d["e_fit_ratio"] = self.e_fit_ratio
        return d


def piece_changes(garment, uv: np.ndarray) -> list[dict]:
    """Per piece what reshaping to ``uv`` changed: its largest vertex move (mm), its area
    (%) and the length of its seams (mm and %), so a pattern maker can judge it."""
    n, pf = garment.n_pieces, garment.piece_of_face()
    move = np.zeros(n)
    np.maximum.at(move, garment.piece_of_vertex, np.hypot(*(uv - garment.uv).T))
    a0 = np.bincount(pf, weights=signed_areas(garment.uv, garment.faces), minlength=n)
    a1 = np.bincount(pf, weights=signed_areas(uv, garment.faces), minlength=n)
    e = garment.seam_edges
    sides = np.concatenate([e[:, :2], e[:, 2:]])  # both twins: each piece's own seam edges
    owner = garment.piece_of_vertex[sides[:, 0]]

    def seam_length(points: np.ndarray) -> np.ndarray:
        lengths = np.hypot(*(points[sides[:, 1]] - points[sides[:, 0]]).T)
        return np.bincount(owner, weights=lengths, minlength=n)

    s0, s1 = seam_length(garment.uv), seam_length(uv)
    return [{"piece": garment.piece_names[i], "max_move_mm": round(float(move[i]), 4),
             "area_change_pct": round(float(100.0 * (a1[i] - a0[i]) / a0[i]), 4),
             "seam_length_change_mm": round(float(s1[i] - s0[i]), 4),
             "seam_length_change_pct": round(float(100.0 * (s1[i] - s0[i]) / s0[i]), 4)
             if s0[i] > 0 else 0.0}
            for i in range(n)]


def seam_reach(garment, ideal: IdealSeams, after: FitReport, reach_mm: float
               ) -> list[dict]:
    """Per seam line what fitting it would take and what reshaping reached: the turn
    (degrees) and the RMS move (mm) its ideal lines ask of it, whether that is within
    ``reach_mm`` (`solver.reshape.ideal.reach_mm`), and the print's mismatch across it
    after reshaping (mean and 90th percentile over its seam edges, mm). A seam out of
    reach cannot fit within the bound: its two sides run in directions no symmetry of
    the print relates (a set-in sleeve's cap against its armhole on a plaid), and tailors
    match such a seam at one notch only."""
    rms = ideal_move_rms(garment, ideal)
    line = np.asarray(garment.seam_line_of_edge, np.int64)
    out = []
    for k in range(len(garment.seam_lines)):
        d = after.distance[line == k]
        out.append({"ideal_turn_deg": round(float(np.degrees(abs(ideal.theta[k]))), 2),
                    "ideal_move_rms_mm": round(float(rms[k]), 3),
                    "within_reach": bool(rms[k] <= reach_mm),
                    "mismatch_mean_mm": round(float(d.mean()), 3) if len(d) else 0.0,
                    "mismatch_p90_mm": round(float(np.percentile(d, 90)), 3) if len(d) else 0.0})
    return out


def reshape_report(garment, placement, result, *, subdivisions: int = 0,
                   max_move_mm: float = float("inf"), reach_mm: float = float("inf")
                   ) -> ReshapeReport:
    """Measure ``result`` (an ``OptimiseResult``) against the ``garment`` it reshaped;
    ``reach_mm``: how far an ideal line may lie and still be pulled to."""
    disp = np.hypot(*(result.uv - garment.uv).T)
    pieces = piece_changes(garment, result.uv)
    after = fit_report(garment, placement, uv=result.uv)
    reach = seam_reach(garment, result.ideal, after, reach_mm)
    seams = [{**ease, **r} for ease, r in zip(seam_ease_changes(garment, result.uv), reach)]
    rough = outline_roughness(garment, result.uv)
    ideal = result.ideal
    ideal_disp = (np.hypot(*(ideal.target - garment.uv[ideal.vertex]).T)
                  if len(ideal.vertex) else np.zeros(1))
    st = result.state
    return ReshapeReport(
        e_fit_before_mm2=fit_report(garment, placement).e_fit_mm2,
        e_fit_after_mm2=after.e_fit_mm2,
        length_mismatch_initial_mm=result.length_mismatch_initial_mm,
        length_mismatch_final_mm=result.length_mismatch_final_mm,
        epsilon_mm=result.eps_mm,
        gamma_rounds=len(st.history),
        gamma_final=float(st.gamma),
        iterations=int(st.iterations),
        factorisations=int(st.refreshes),
        seconds=float(result.seconds),
        max_displacement_mm=float(disp.max()) if len(disp) else 0.0,
        max_ideal_displacement_mm=float(ideal_disp.max()),
        flipped_triangles=int(result.flipped_triangles),
        faces=int(len(garment.faces)),
        vertices=int(garment.n_vertices),
        subdivisions=subdivisions,
        max_move_bound_mm=float(max_move_mm),
        area_change_max_pct=max((abs(p["area_change_pct"]) for p in pieces), default=0.0),
        pieces=tuple(pieces),
        seams=tuple(seams),
        ease_change_max_mm=max((abs(s["ease_change_mm"]) for s in seams), default=0.0),
        sewn_drift_max_mm=max((s["sewn_drift_mm"] for s in seams), default=0.0),
        roughness_p95_mm=float(np.percentile(rough, 95)) if len(rough) else 0.0,
        roughness_max_mm=float(rough.max(initial=0.0)),
        seams_out_of_reach=tuple(s["seam"] for s in seams if not s["within_reach"]),
    )
