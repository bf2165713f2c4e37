"""What a reshape run achieved: the numbers the issue asks for, JSON-ready."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from solver.fit import fit_report


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

    @property
    def e_fit_ratio(self) -> float:
        """after / before (0 when before is 0: nothing to improve)."""
        return self.e_fit_after_mm2 / self.e_fit_before_mm2 if self.e_fit_before_mm2 else 0.0

    def to_dict(self) -> dict:
        d = asdict(self)
        d["e_fit_before_cm2"] = self.e_fit_before_mm2 / 100.0
        d["e_fit_after_cm2"] = self.e_fit_after_mm2 / 100.0
        d["e_fit_ratio"] = self.e_fit_ratio
        return d


def reshape_report(garment, placement, result, *, subdivisions: int = 0) -> ReshapeReport:
    """Measure ``result`` (an ``OptimiseResult``) against the ``garment`` it reshaped."""
    disp = np.hypot(*(result.uv - garment.uv).T)
    ideal = result.ideal
    ideal_disp = (np.hypot(*(ideal.target - garment.uv[ideal.vertex]).T)
                  if len(ideal.vertex) else np.zeros(1))
    st = result.state
    return ReshapeReport(
        e_fit_before_mm2=fit_report(garment, placement).e_fit_mm2,
        e_fit_after_mm2=fit_report(garment, placement, uv=result.uv).e_fit_mm2,
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
    )
