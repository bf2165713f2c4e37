"""Pictures for people: the pattern pieces over the print, seams coloured by mismatch.

As in the paper's Fig. 1: every seam edge is drawn on both twins, coloured from green
(0 mm) to red (``red_mm`` or more), over the print as it lies on each piece. The print is
always the fabric as it is: the rectified photograph of the table (:func:`photo_colours`),
or, for a fabric given only as a FABRIC.json, its lattice ruled on plain cloth
(:func:`lattice_colours`); never a motif invented for the group.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

import untrusted
from gcode.program import program_moves
from solver.fit import FitReport
from solver.garment.grain import grain_lines
from solver.jsonfile import read_json
from solver.nest.layout import Layout, Placed
from solver.placement import Placement
from solver.wallpaper import Wallpaper

ColourOf = Callable[[np.ndarray], np.ndarray]  # (N, 2) wallpaper mm -> (N, 3) BGR uint8


def mismatch_colours(distance: np.ndarray, red_mm: float = 20.0) -> np.ndarray:
    """(E,) mm -> (E, 3) BGR: green at 0 through yellow to red at ``red_mm``."""
    s = np.clip(np.asarray(distance, float) / red_mm, 0.0, 1.0)
    red = np.clip(2.0 * s, 0.0, 1.0)
    green = np.clip(2.0 * (1.0 - s), 0.0, 1.0)
    return (np.stack([np.zeros_like(s), green, red], -1) * 220).astype(np.uint8)


def lattice_colours(wallpaper, pixel_mm: float) -> ColourOf:
    """Plain cloth ruled with the print's lattice cells, for a fabric nobody photographed
    (a FABRIC.json given by hand): all the station knows of that print is its lattice,
    so that is all the picture shows; an invented motif would pass for the real cloth."""
    lengths = np.array([np.hypot(*wallpaper.w1), np.hypot(*wallpaper.w2)])
    half_line = np.maximum(0.75 * pixel_mm, 0.3) / lengths  # fractional half-width

    def colour_of(points: np.ndarray) -> np.ndarray:
        f = wallpaper.to_fractional(np.asarray(points, float))
        off = np.abs(f - np.round(f))  # distance to the nearest cell edge, in cells
        on_line = (off < half_line).any(axis=1)
        out = np.empty((len(f), 3), np.uint8)
        out[:] = (222, 226, 230)
        out[on_line] = (150, 150, 150)
        return out

    return colour_of


def photo_colours(photo: np.ndarray | None, mm_per_px: float, wallpaper) -> ColourOf | None:
    """Colours of the print as photographed (None without a photo): any fabric point is
    moved by whole lattice vectors into the middle of the photo and sampled there, so
    the pictures show the real cloth rather than a stand-in print."""
    if photo is None:
        return None
    s = float(mm_per_px)
    h, w = photo.shape[:2]
    centre = np.array([w, h], float) * s / 2
    base = wallpaper.to_fractional(centre[None])[0]

    def colour_of(points: np.ndarray) -> np.ndarray:
        f = wallpaper.to_fractional(np.asarray(points, float))
        f = base - 0.5 + (f - base + 0.5) % 1.0
        px = wallpaper.to_cartesian(f) / s
        n, width = len(px), 4096
        rows = -(-n // width)
        grid = np.zeros((rows * width, 2), np.float32)
        grid[:n] = px
        grid = grid.reshape(rows, width, 2)
        out = cv2.remap(photo, grid[..., 0], grid[..., 1], cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_REFLECT)
        return out.reshape(-1, 3)[:n]

    return colour_of


def fabric_picture(fabric_path: str | Path, wallpaper) -> ColourOf | None:
    """Colours of the print as the picture a FABRIC.json names shows it (``image``, with
    ``mm_per_px``, as `station simulate-fabric` writes them beside the lattice), None
    when it names no picture: the desk commands then rule the lattice on plain cloth.
    The picture is read within the limits of any untrusted image."""
    source = str(fabric_path)
    doc = read_json(fabric_path)
    if not isinstance(doc, dict) or doc.get("image") is None:
        return None
    image = Path(untrusted.text(doc["image"], source, "image", max_len=4096))
    if not image.is_absolute():
        image = Path(fabric_path).parent / image
    mm_per_px = untrusted.number(doc.get("mm_per_px"), source, "mm_per_px", lo=0.0,
                                 hi=1000.0, lo_open=True)
    return photo_colours(untrusted.read_image(image), mm_per_px, wallpaper)


def garment_credit(source: str | Path) -> str | None:
    """The acknowledgement a garment's licence asks for on every image made with it.

    The UC Berkeley Garment Library's terms require it; its README travels beside
    each copy of its files, so that is how we recognise them.
    """
    folder = Path(source).resolve().parent
    for candidate in (folder / "README.txt", folder / "BERKELEY-README.txt"):
        if candidate.is_file() and "UC Berkeley Garment Library" in candidate.read_text(
                errors="replace"):
            return "Garment model obtained from the UC Berkeley Garment Library"
    return None


def dashed(image: np.ndarray, ring_px: np.ndarray, colour, thickness: int = 1,
           dash_px: float = 6.0) -> None:
    """A closed polyline (cv2 fixed point, 4 fractional bits) drawn dashed: the sew line."""
    ring = np.vstack([ring_px, ring_px[:1]]).astype(float) / 16
    seg = np.hypot(*np.diff(ring, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if s[-1] <= 0:
        return
    marks = np.arange(0.0, s[-1], dash_px)
    pts = np.column_stack([np.interp(marks, s, ring[:, 0]), np.interp(marks, s, ring[:, 1])])
    pairs = list(np.round(pts[: len(pts) // 2 * 2].reshape(-1, 2, 2) * 16).astype(np.int32))
    # a light halo under the dark dash: readable on pale cloth and on a dark plaid alike
    cv2.polylines(image, pairs, False, (245, 245, 245), thickness + 2, cv2.LINE_AA, shift=4)
    cv2.polylines(image, pairs, False, colour, thickness, cv2.LINE_AA, shift=4)


def notch_ticks(image: np.ndarray, notches, to_px, min_mm: float) -> None:
    """Each notch as a red slit from the cut line inward (at least ``min_mm`` long)."""
    for at, d, depth in notches:
        at, d = np.asarray(at, float), np.asarray(d, float)
        a, b = to_px(np.stack([at, at + max(depth or 0.0, min_mm) * d]))
        cv2.line(image, tuple(map(int, a)), tuple(map(int, b)), (0, 0, 200), 2, cv2.LINE_AA,
                 shift=4)


@dataclass(frozen=True)
class _PatternFrame:
    """Pattern millimetres to picture pixels: y up in pattern space, down in the image, a
    banner above for the legend."""

    lo: np.ndarray
    hi: np.ndarray
    scale: float
    width_px: int
    height_px: int
    banner: int = 60

    @classmethod
    def around(cls, points: np.ndarray, width_px: int) -> _PatternFrame:
        lo, hi = points.min(axis=0), points.max(axis=0)
        margin = 0.04 * float(np.max(hi - lo))
        lo, hi = lo - margin, hi + margin
        scale = width_px / float(hi[0] - lo[0])
        return cls(lo, hi, scale, width_px, max(1, int(np.ceil((hi[1] - lo[1]) * scale))))

    def to_px(self, p: np.ndarray) -> np.ndarray:
        q = np.empty_like(p)
        q[:, 0] = (p[:, 0] - self.lo[0]) * self.scale
        q[:, 1] = (self.hi[1] - p[:, 1]) * self.scale + self.banner
        return np.round(q * 16).astype(np.int32)  # 4 fractional bits for cv2 shift

    def to_mm(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        return np.column_stack([xs / self.scale + self.lo[0],
                                self.hi[1] - (ys - self.banner) / self.scale])


def draw_fit(garment, placement: Placement, report: FitReport, path: str | Path, *,
             width_px: int = 1600, red_mm: float = 20.0,
             colour_of: ColourOf | None = None, title: str | None = None,
             cuts=None, notches=None, original=None) -> np.ndarray:
    """Draw the pieces (pattern space) over the print and save a PNG; returns the image.

    With ``cuts`` (per piece :class:`solver.garment.allowance.CutLine`) the seam allowance
    shows as a lighter band of the print, the cut line solid and the sew line dashed;
    ``notches`` (per piece, :class:`solver.garment.notches.Notch`) as red slits. Each piece
    shows its grain line as an arrow; ``original`` (the garment before reshaping) is
    overlaid as a thin grey outline so that the change can be seen.
    """
    uv = garment.uv
    frame = _PatternFrame.around(uv if not cuts else np.vstack([uv] + [c.outline for c in cuts]),
                                 width_px)
    colour_of = colour_of or lattice_colours(placement.fabric, 1.0 / frame.scale)
    image = _paint_pieces(garment, placement, frame, colour_of, cuts)
    _draw_outlines(image, garment, frame, cuts, notches, original)
    draw_grain_arrows(image, garment, frame.to_px, frame.scale)
    _draw_seam_fit(image, garment, report, frame, red_mm)
    _draw_legend(image, report, red_mm, title or f"{placement.fabric.group} print")
    credit = garment_credit(garment.source) if garment.source else None
    if credit:
        cv2.putText(image, credit, (12, image.shape[0] - 12), cv2.FONT_HERSHEY_SIMPLEX, 0.5,
                    (90, 90, 90), 1, cv2.LINE_AA)
    if not cv2.imwrite(str(path), image):
        raise ValueError(f"{path}: cannot write the picture (folder missing or not a .png?)")
    return image


def _paint_pieces(garment, placement: Placement, frame: _PatternFrame, colour_of: ColourOf,
                  cuts) -> np.ndarray:
    """Each piece's pixels in the colour of the print under them (the allowance band
    lighter): which piece covers a pixel comes from rasterising its triangles with its id."""
    to_px = frame.to_px
    label = np.zeros((frame.height_px + frame.banner, frame.width_px), np.int32)
    for piece, cut in enumerate(cuts or []):  # the allowance band: the print, lighter
        cv2.fillPoly(label, [to_px(cut.outline)], -(piece + 1), lineType=cv2.LINE_8, shift=4)
        for hole in cut.holes:
            cv2.fillPoly(label, [to_px(hole)], 0, lineType=cv2.LINE_8, shift=4)
    tri = to_px(garment.uv)[garment.faces]
    for piece in range(garment.n_pieces):
        mask = garment.piece_of_face() == piece
        cv2.fillPoly(label, list(tri[mask]), piece + 1, lineType=cv2.LINE_8, shift=4)
    image = np.full((frame.height_px + frame.banner, frame.width_px, 3), 245, np.uint8)
    ys, xs = np.nonzero(label)
    if len(xs):
        piece = np.abs(label[ys, xs]) - 1
        colours = colour_of(placement.to_wallpaper(frame.to_mm(xs, ys), piece)).astype(float)
        band = label[ys, xs] < 0
        colours[band] = 0.5 * colours[band] + 0.5 * 245
        image[ys, xs] = colours.astype(np.uint8)
    return image


def _draw_outlines(image: np.ndarray, garment, frame: _PatternFrame, cuts, notches,
                   original) -> None:
    """Sew lines (dashed under a cut line), cut lines, notches and the outline before
    reshaping."""
    to_px = frame.to_px
    for piece in range(garment.n_pieces):
        for loop in garment.piece_loops(piece):
            ring = to_px(garment.uv[loop])
            if cuts:
                dashed(image, ring, (60, 60, 60), 1)
            else:
                cv2.polylines(image, [ring], True, (60, 60, 60), 1, cv2.LINE_AA, shift=4)
    for cut in cuts or []:
        cv2.polylines(image, [to_px(r) for r in [cut.outline, *cut.holes]], True,
                      (30, 30, 30), 2, cv2.LINE_AA, shift=4)
    for per_piece in notches or []:
        notch_ticks(image, [slit for q in per_piece for slit in q.slits()], to_px,
                    4.0 / frame.scale)
    if original is not None:
        for piece in range(original.n_pieces):
            for loop in original.piece_loops(piece):
                cv2.polylines(image, [to_px(original.uv[loop])], True, (150, 150, 150), 1,
                              cv2.LINE_AA, shift=4)


def _draw_seam_fit(image: np.ndarray, garment, report: FitReport, frame: _PatternFrame,
                   red_mm: float) -> None:
    """Both twins of every seam edge coloured by its mismatch, one polylines call per colour
    level (not per edge)."""
    uv, edges, to_px = garment.uv, garment.seam_edges, frame.to_px
    segments = np.concatenate([
        np.stack([to_px(uv[edges[:, 0]]), to_px(uv[edges[:, 1]])], 1),
        np.stack([to_px(uv[edges[:, 2]]), to_px(uv[edges[:, 3]])], 1),
    ])
    levels = np.minimum((np.tile(report.distance, 2) / red_mm * 31).astype(int), 31)
    palette = mismatch_colours(np.arange(32) / 31 * red_mm, red_mm)
    for level in np.unique(levels):
        colour = tuple(int(v) for v in palette[level])
        cv2.polylines(image, list(segments[levels == level]), False, colour, 4,
                      cv2.LINE_AA, shift=4)


def draw_grain_arrows(image: np.ndarray, garment, to_px, scale: float) -> None:
    """Each piece's grain line, dark blue, arrow head at the grain's direction."""
    for tail, head in grain_lines(garment):
        a, b = to_px(np.array([tail])), to_px(np.array([head]))
        length = max(float(np.hypot(*(head - tail))) * scale, 1.0)
        cv2.arrowedLine(image, tuple(int(v) for v in a[0]), tuple(int(v) for v in b[0]),
                        (120, 40, 20), 2, cv2.LINE_AA, shift=4, tipLength=min(0.3, 20 / length))


def _draw_legend(image: np.ndarray, report: FitReport, red_mm: float, title: str) -> None:
    text = (f"{title}   E_fit = {report.e_fit_cm2:.1f} cm^2   "
            f"mean seam mismatch {report.distance.mean() if len(report.distance) else 0:.1f} mm")
    cv2.putText(image, text, (12, 26), cv2.FONT_HERSHEY_SIMPLEX, 0.7, (30, 30, 30), 2, cv2.LINE_AA)
    bar_w, x0 = 240, image.shape[1] - 260
    ramp = mismatch_colours(np.linspace(0, red_mm, bar_w), red_mm)
    image[36:50, x0:x0 + bar_w] = ramp[None]
    cv2.putText(image, "0 mm", (x0, 32), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (30, 30, 30), 1,
                cv2.LINE_AA)
    cv2.putText(image, f">= {red_mm:g} mm", (x0 + bar_w - 70, 32), cv2.FONT_HERSHEY_SIMPLEX,
                0.45, (30, 30, 30), 1, cv2.LINE_AA)


def cloth_image(layout: Layout, width_px: int, *, photo: np.ndarray | None = None,
                photo_mm_per_px: float = 1.0) -> np.ndarray:
    """The fabric under a marker, ``width_px`` wide over the layout's length (BGR): the
    rectified photo when there is one, else the layout's lattice ruled on plain cloth,
    else plain cloth. The console draws its live marker over this very picture."""
    length = layout.length or 1.0
    scale = width_px / length
    height_px = max(1, int(np.ceil(layout.width * scale)))
    if photo is not None:
        m = np.array([[scale * photo_mm_per_px, 0, 0], [0, scale * photo_mm_per_px, 0]])
        return cv2.warpAffine(photo, m, (width_px, height_px), flags=cv2.INTER_AREA)
    if not layout.fabric:
        return np.full((height_px, width_px, 3), 225, np.uint8)
    colour_of = lattice_colours(Wallpaper.from_dict(layout.fabric), 1.0 / scale)
    ys, xs = np.mgrid[0:height_px, 0:width_px]
    pts = np.column_stack([(xs.ravel() + 0.5) / scale, (ys.ravel() + 0.5) / scale])
    return colour_of(pts).reshape(height_px, width_px, 3)


def draw_marker(layout: Layout, path: str | Path, *, garment=None, report: FitReport | None = None,
                photo: np.ndarray | None = None, photo_mm_per_px: float = 1.0,
                width_px: int = 1600, red_mm: float = 20.0,
                credit: str | None = None, title: str | None = None) -> np.ndarray:
    """The marker: every piece where it lies on the fabric, seams coloured by mismatch;
    ``title`` (an order and its size ratio) heads the banner.

    ``layout`` is in fabric mm, x along the roll, y across it, drawn with y down like the
    rectified photo. The background is the rectified photo when
    given (pixel (c, r) at (c, r) * ``photo_mm_per_px`` mm), else the layout's lattice
    ruled on plain cloth (:func:`cloth_image`).
    """
    length = layout.length or 1.0
    scale = width_px / length
    cloth = cloth_image(layout, width_px, photo=photo, photo_mm_per_px=photo_mm_per_px)
    height_px = cloth.shape[0]
    banner = 40
    # Waste is dimmed so the pieces stand out.
    image = np.full((height_px + banner, width_px, 3), 245, np.uint8)
    image[banner:] = (0.45 * cloth + 0.55 * 245).astype(np.uint8)

    def to_px(p: np.ndarray) -> np.ndarray:
        p = np.asarray(p, float).reshape(-1, 2)
        return np.round(np.column_stack([p[:, 0] * scale, p[:, 1] * scale + banner]) * 16
                        ).astype(np.int32)

    mask = np.zeros(image.shape[:2], np.uint8)
    rings = [to_px(piece.outline) for piece in layout.pieces]
    cv2.fillPoly(mask, rings, 255, cv2.LINE_8, shift=4)
    full = np.full_like(image, 245)
    full[banner:] = cloth
    image[mask > 0] = full[mask > 0]
    cv2.polylines(image, rings, True, (40, 40, 40), 1, cv2.LINE_AA, shift=4)  # cut lines
    for piece in layout.pieces:
        if piece.sew_line is not None:
            dashed(image, to_px(piece.sew_line), (40, 40, 40), 1)
    _draw_marker_details(image, layout, to_px, scale)
    if garment is not None and report is not None:
        _draw_marker_seams(image, layout, garment, report, to_px, red_mm)
    for piece, ring in zip(layout.pieces, rings):
        centre = (ring.mean(axis=0) / 16).astype(int)
        for k, line in enumerate(_piece_label(piece)):
            cv2.putText(image, line, tuple(centre - [20, -14 * k]), cv2.FONT_HERSHEY_SIMPLEX,
                        0.4, (20, 20, 20), 1, cv2.LINE_AA)
    if credit:  # the garment's licence may ask for it on every image (garment_credit)
        _draw_credit(image, credit)
    text = (f"marker {length:.0f} x {layout.width:.0f} mm, {len(layout.pieces)} pieces, "
            f"density {100 * layout.density:.1f}%")
    if title:
        text = f"{title}; {text}"
    cv2.putText(image, text, (12, 26), cv2.FONT_HERSHEY_SIMPLEX, 0.65, (30, 30, 30), 2,
                cv2.LINE_AA)
    if not cv2.imwrite(str(path), image):
        raise ValueError(f"{path}: cannot write the picture")
    return image


def _piece_label(piece: Placed) -> list[str]:
    """A piece's label lines: its id, and for an order's piece its name and its size."""
    if not piece.garment:
        return [piece.id]
    return [piece.id.removeprefix(f"{piece.garment}."), f"size {piece.size or '-'}"]


def _draw_marker_details(image, layout: Layout, to_px, scale: float) -> None:
    """Keep-outs (red), holes, notches (red slits), marks (red crosses) and grain lines
    (green arrows)."""
    keepouts = [to_px(k) for k in layout.keepouts]
    if keepouts:
        shade = image.copy()
        cv2.fillPoly(shade, keepouts, (60, 60, 200), cv2.LINE_AA, shift=4)
        cv2.addWeighted(shade, 0.5, image, 0.5, 0, dst=image)
    holes = [to_px(h) for piece in layout.pieces for h in piece.holes]
    cv2.polylines(image, holes, True, (40, 40, 40), 1, cv2.LINE_AA, shift=4)
    arm = 3.0 / scale  # marks (drill holes, dart points) as small crosses, 3 px each way
    for piece in layout.pieces:
        notch_ticks(image, piece.notches, to_px, 4.0 / scale)
        for m in np.asarray(piece.marks, float).reshape(-1, 2):
            for d in ((arm, arm), (arm, -arm)):
                a, b = to_px(np.stack([m - d, m + d]))
                cv2.line(image, tuple(map(int, a)), tuple(map(int, b)), (0, 0, 200), 1,
                         cv2.LINE_AA, shift=4)
        if piece.grainline is not None:
            a, b = to_px(piece.grainline)
            cv2.arrowedLine(image, tuple(a), tuple(b), (0, 130, 0), 1, cv2.LINE_AA, shift=4)


def _draw_marker_seams(image, layout: Layout, garment, report, to_px, red_mm) -> None:
    """Seam edges carried from pattern space into the fabric by each piece's transform."""
    name_to_piece = {n: i for i, n in enumerate(garment.piece_names)}
    palette = mismatch_colours(np.arange(32) / 31 * red_mm, red_mm)
    edges = garment.seam_edges
    level = np.minimum((report.distance / red_mm * 31).astype(int), 31)
    for placed in layout.pieces:
        piece = name_to_piece.get(placed.name)
        if piece is None:
            continue
        t = placed.transform
        for a, b in ((0, 1), (2, 3)):
            mine = garment.piece_of_vertex[edges[:, a]] == piece
            if not mine.any():
                continue
            p0 = garment.uv[edges[mine, a]] @ t[:, :2].T + t[:, 2]
            p1 = garment.uv[edges[mine, b]] @ t[:, :2].T + t[:, 2]
            segments = np.stack([to_px(p0), to_px(p1)], 1)
            for lv in np.unique(level[mine]):
                colour = tuple(int(v) for v in palette[lv])
                cv2.polylines(image, list(segments[level[mine] == lv]), False, colour, 3,
                              cv2.LINE_AA, shift=4)


def program_paths(program) -> list[tuple[bool, int, np.ndarray]]:
    """Every move of a checked G-code program as (cutting, piece number or 0, (k, 2) points),
    as the program checker read it (`gcode.program.program_moves`)."""
    return [(on, piece, pts) for _, on, piece, pts in program_moves(program)]


def draw_toolpath(program, machine, path: str | Path, *, width_px: int = 1600,
                  credit: str | None = None) -> np.ndarray:
    """The program over the machine's work area: cuts coloured by piece (numbered in cut
    order), rapid travel as thin grey lines, the totals in the banner."""
    x0, y0, x1, y1 = machine.work_area
    scale = width_px / float(x1 - x0)
    height_px = max(1, int(np.ceil((y1 - y0) * scale)))
    banner = 40
    image = np.full((height_px + banner, width_px, 3), 250, np.uint8)
    cv2.rectangle(image, (0, banner), (width_px - 1, banner + height_px - 1), (180, 180, 180), 1)

    def to_px(p: np.ndarray) -> np.ndarray:
        return np.round(np.column_stack([(p[:, 0] - x0) * scale,
                                         (p[:, 1] - y0) * scale + banner]) * 16).astype(np.int32)

    hues = np.linspace(0, 179, 13)[:-1].astype(np.uint8)
    firsts: dict[int, np.ndarray] = {}
    for on, piece, pts in program_paths(program):
        if not on:
            cv2.polylines(image, [to_px(pts)], False, (170, 170, 170), 1, cv2.LINE_AA, shift=4)
            continue
        hsv = np.uint8([[[hues[(piece * 5) % len(hues)], 220, 190]]])
        colour = tuple(int(v) for v in cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)[0, 0])
        cv2.polylines(image, [to_px(pts)], False, colour, 2, cv2.LINE_AA, shift=4)
        firsts.setdefault(piece, pts[0])
    for piece, p in firsts.items():
        q = (to_px(p[None])[0] / 16).astype(int)
        cv2.circle(image, tuple(q), 4, (0, 0, 0), -1, cv2.LINE_AA)
        cv2.putText(image, str(piece), tuple(q + [6, -6]), cv2.FONT_HERSHEY_SIMPLEX, 0.5,
                    (0, 0, 0), 1, cv2.LINE_AA)
    summary = program.summary()
    text = (f"toolpath: {summary['pieces']} pieces, cut {summary['cut_length_mm'] or 0:.0f} mm, "
            f"travel {summary['travel_length_mm'] or 0:.0f} mm, "
            f"about {(summary['estimated_seconds'] or 0) / 60:.1f} min")
    cv2.putText(image, text, (12, 26), cv2.FONT_HERSHEY_SIMPLEX, 0.65, (30, 30, 30), 2,
                cv2.LINE_AA)
    if credit:
        _draw_credit(image, credit)
    if not cv2.imwrite(str(path), image):
        raise ValueError(f"{path}: cannot write the picture")
    return image


def _draw_credit(image: np.ndarray, credit: str) -> None:
    """The acknowledgement line at the bottom left, on a light band so it stays legible."""
    h = image.shape[0]
    image[h - 24:h] = (0.3 * image[h - 24:h] + 0.7 * 245).astype(np.uint8)
    cv2.putText(image, credit, (12, h - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (60, 60, 60), 1,
                cv2.LINE_AA)
