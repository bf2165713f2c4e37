"""Where the print lies on each pattern piece: ``p2D = R(angle) p_wp + t`` per piece.

A `Placement` is what alignment produces and what fitting, reshaping, nesting and the
previews consume. On disk it is PLACEMENT.json, with angles in degrees for people.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import untrusted
from solver.geometry import rotation_matrices
from solver.jsonfile import read_json
from solver.wallpaper import Wallpaper


def _pairs(value: Any, n_pieces: int) -> list[list]:
    """PLACEMENT.json "pairs", checked: two different piece indices and a mode each."""
    if not isinstance(value, list):
        raise ValueError('"pairs" must be a list of [i, j, "mirror" | "same"]')
    out = []
    for item in value:
        if not (isinstance(item, list) and len(item) == 3 and item[2] in ("mirror", "same")
                and all(isinstance(k, int) and not isinstance(k, bool) and 0 <= k < n_pieces
                        for k in item[:2]) and item[0] != item[1]):
            raise ValueError(f'pair {item!r} is not [i, j, "mirror" | "same"] with two '
                             f"different pieces of 0..{n_pieces - 1}")
        out.append([item[0], item[1], item[2]])
    return out


@dataclass
class Placement:
    """Per piece the rigid map from wallpaper space to pattern space.

    ``angles`` (P,) radians and ``translations`` (P, 2) mm, as in the paper
    (Sec. 3): ``p2D = R_c p_wp + t_c``.
    """

    angles: np.ndarray
    translations: np.ndarray
    fabric: Wallpaper
    garment: str | None = None
    piece_names: list[str] | None = None
    garment_units: str | None = None  # units the garment file was read in (it may not say)
    report: dict[str, Any] = field(default_factory=dict)
    # per piece {"grain_deg", "grain_source", "bias"} (solver.garment.grain), when known
    grains: list[dict[str, Any]] | None = None
    # the cutting rule: {"tolerance_deg": float | None (None: free rotation), "nap": bool,
    # "fabric_grain_deg": float}; nesting keeps to it
    grain_rule: dict[str, Any] = field(default_factory=dict)
    # left/right pairs and how each was kept: [[i, j, "mirror" | "same"], ...]
    pairs: list[list] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.angles = np.asarray(self.angles, float).reshape(-1)
        self.translations = np.asarray(self.translations, float).reshape(-1, 2)
        if len(self.angles) != len(self.translations):
            raise ValueError(f"placement has {len(self.angles)} angles but "
                             f"{len(self.translations)} translations")
        if not (np.all(np.isfinite(self.angles)) and np.all(np.isfinite(self.translations))):
            raise ValueError("placement angles and translations must be finite")

    @classmethod
    def identity(cls, n_pieces: int, fabric: Wallpaper, **kw) -> Placement:
        return cls(np.zeros(n_pieces), np.zeros((n_pieces, 2)), fabric, **kw)

    @property
    def n_pieces(self) -> int:
        return len(self.angles)

    def to_wallpaper(self, points: np.ndarray, piece: np.ndarray) -> np.ndarray:
        """Pattern points (N, 2) on pieces ``piece`` (N,) -> wallpaper space."""
        r = rotation_matrices(self.angles[piece])
        return np.einsum("nji,nj->ni", r, points - self.translations[piece])

    # ------------------------------------------------------------------ files
    def to_dict(self) -> dict[str, Any]:
        names = self.piece_names or [f"piece{i}" for i in range(self.n_pieces)]
        return {
            "version": 1,
            "garment": self.garment,
            "garment_units": self.garment_units,
            "fabric": self.fabric.to_dict(),
            "convention": "p2D = R(angle_deg) p_wp + translation_mm",
            "grain": self.grain_rule,
            "pieces": [
                {"index": i, "name": names[i], "angle_deg": float(np.degrees(a)),
                 "translation_mm": [float(t[0]), float(t[1])],
                 **(self.grains[i] if self.grains else {})}
                for i, (a, t) in enumerate(zip(self.angles, self.translations))
            ],
            "pairs": [[int(i), int(j), str(mode)] for i, j, mode in self.pairs],
            "report": self.report,
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Placement:
        try:
            pieces = sorted(d["pieces"], key=lambda p: p["index"])
            return cls(
                angles=np.radians([p["angle_deg"] for p in pieces]),
                translations=[p["translation_mm"] for p in pieces],
                fabric=Wallpaper.from_dict(d["fabric"], "fabric"),
                garment=d.get("garment"),
                garment_units=d.get("garment_units"),
                piece_names=[p.get("name", f"piece{p['index']}") for p in pieces],
                report=d.get("report", {}),
                grains=([{k: p[k] for k in ("grain_deg", "grain_source", "bias") if k in p}
                         for p in pieces] if all("grain_deg" in p for p in pieces) else None),
                grain_rule=dict(d.get("grain") or {}),
                pairs=_pairs(d.get("pairs", []), len(pieces)),
            )
        except (KeyError, TypeError, AttributeError) as exc:
            raise ValueError(f"placement lacks or misstates {exc}") from None

    def save(self, path: str | Path) -> None:
        Path(path).write_text(json.dumps(self.to_dict(), indent=2) + "\n")

    @classmethod
    def load(cls, path: str | Path) -> Placement:
        data = check_placement(read_json(path), str(path))
        try:
            return cls.from_dict(data)
        except ValueError as exc:
            raise untrusted.InputError(path, str(exc)) from None


def check_placement(d: Any, source: str) -> dict[str, Any]:
    """``d`` if it is a well-formed PLACEMENT.json: pieces indexed 0..P-1 once each, finite
    angles, translations within the table's range, text where text belongs."""
    lim = untrusted.limits
    d = untrusted.mapping(d, source)
    pieces = untrusted.sequence(d.get("pieces"), source, "pieces", min_len=1,
                                max_len=lim.MAX_PIECES)
    index = []
    for i, p in enumerate(pieces):
        where = f"pieces[{i}]"
        untrusted.mapping(p, source, where)
        index.append(untrusted.integer(p.get("index"), source, f"{where}.index", lo=0,
                                       hi=len(pieces) - 1))
        untrusted.number(p.get("angle_deg"), source, f"{where}.angle_deg", lo=-1e6, hi=1e6)
        untrusted.vector(p.get("translation_mm"), source, f"{where}.translation_mm")
        untrusted.text(p.get("name", ""), source, f"{where}.name")
    if len(set(index)) != len(index):
        raise untrusted.InputError(source, "pieces: each index 0..P-1 must appear exactly once")
    untrusted.mapping(d.get("fabric"), source, "fabric")
    for key in ("garment", "garment_units"):
        if d.get(key) is not None:
            untrusted.text(d[key], source, key, max_len=4096)
    untrusted.mapping(d.get("report", {}), source, "report")
    return d
