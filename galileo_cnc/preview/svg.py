"""The vector preview: `preview -o out.svg`, a drawing a browser zooms without limit.

Drawn from the job's commands (not the step trace, so it costs no stepping: seconds
on the largest boards), in work mm with Y up (a flipped group; texts outside it):

1. the artwork: in ink mode the copper the ink was planned for, else the Program's
   paths at their aperture widths, flashes by their extent, regions filled (ART);
2. pen-up travel as thin grey lines that keep their width at any zoom;
3. each pen's strokes at that pen's width, round ends, a flash as the pen's disc.
   Given the copper, the copper is painted in UNINKED under the strokes (what stays
   orange is bare copper), the strokes inside it in STROKE and outside it in OUTSIDE
   (the same strokes drawn twice, each clipped to one side of the copper's edge);
   a board's outline and silk pens (`pen_roles`) in render.LINE_COLOURS, unclipped;
4. a legend (ink, bare copper, ink outside, outline, silk, travel), a scale bar, and the origin
   (work X 0, Y 0) as a cross.

The file's width and height are in mm: printed at 100 % it is the plot's size.
docs/preview.md, "SVG".
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import TextIO
from xml.sax.saxutils import escape

import numpy as np

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.job import ArcTo, Flash, Job, LineTo, PenDown, PenUp, Rapid
from galileo_cnc.preview.artwork import ART, path_width_mm
from galileo_cnc.preview.render import (LINE_COLOURS, OUTSIDE, STROKE, TRAVEL, UNINKED,
                                        copper_rings)
from galileo_cnc.program.extents import extents, start_points
from galileo_cnc.program.ops import I, J, KIND, NM_PER_MM, TOOL, VALUE, X, Y, OpKind, Program

#: the width of a pen whose width is unknown or 0 (centre mode), in mm
DEFAULT_PEN_MM = 0.15
MARGIN_MM = 2.0
LEGEND = (("ink", STROKE), ("bare copper", UNINKED), ("ink outside the copper", OUTSIDE),
          ("pen-up travel", TRAVEL))


@dataclass(frozen=True)
class SvgInfo:
    """What the SVG holds (work mm)."""

    path: str
    strokes: int                  # pen-down runs (a flash counts as one)
    drawn_mm: float
    travel_mm: float
    view_mm: tuple[float, float, float, float]
    copper: bool                  # bare copper and ink outside are shown

    def summary(self) -> str:
        w, h = self.view_mm[2] - self.view_mm[0], self.view_mm[3] - self.view_mm[1]
        ink = ", bare copper and ink outside it shown" if self.copper else ""
        return (f"vector preview {w:.1f} x {h:.1f} mm, {self.strokes} pen strokes, "
                f"{self.drawn_mm:.1f} mm drawn, {self.travel_mm:.1f} mm pen-up travel{ink} "
                "(open it in a browser to zoom)")


class _Paths:
    """Pen-down runs per pen width and pen-up travel, as SVG path data (mm)."""

    def __init__(self) -> None:
        self.down: dict[int, list[str]] = {}     # pen width nm -> path pieces
        self.dots: dict[int, list[tuple[float, float]]] = {}
        # a board's outline and silk: role -> their own `down` and `dots`
        self.lines: dict[str, tuple[dict[int, list[str]],
                                    dict[int, list[tuple[float, float]]]]] = {}
        self.travel: list[str] = []
        self.strokes = 0
        self.drawn_mm = self.travel_mm = 0.0
        self.lo = [math.inf, math.inf]
        self.hi = [-math.inf, -math.inf]

    def see(self, x: float, y: float) -> None:
        self.lo = [min(self.lo[0], x), min(self.lo[1], y)]
        self.hi = [max(self.hi[0], x), max(self.hi[1], y)]


def job_paths(job: Job, config: MachineConfig, widths_nm: dict[int, int],
              pen_roles: dict[int, str] | None = None) -> _Paths:
    """Walk the job from work (0, 0): pen state, pen in the holder, each move's path
    (the pens of `pen_roles` apart, in `lines`)."""
    mm = 1 / config.steps_per_mm
    default_nm = round(DEFAULT_PEN_MM * NM_PER_MM)
    paths = _Paths()
    x = y = 0
    down = False
    run: list[str] | None = None          # the pen-down run being drawn
    changes = job.pen_changes
    pen = next((job.aperture[k] for k, c in enumerate(job.commands)
                if isinstance(c, (PenDown, LineTo, ArcTo, Flash))), None)
    paths.see(0.0, 0.0)
    for index, command in enumerate(job.commands):
        if index in changes:
            pen = changes[index]
        width = int(widths_nm.get(pen) or 0) or default_nm
        role = (pen_roles or {}).get(pen)
        down_at, dots_at = (paths.down, paths.dots) if role is None else \
            paths.lines.setdefault(role, ({}, {}))
        if isinstance(command, (PenUp, Rapid)):
            down, run = False, None
        if isinstance(command, PenDown):
            down = True
        elif isinstance(command, Flash):
            dots_at.setdefault(width, []).append((x * mm, y * mm))
            paths.strokes += 1
            down, run = False, None
        elif isinstance(command, (Rapid, LineTo, ArcTo)):
            nx, ny = command.x_steps, command.y_steps
            step = _segment(command, x, y, mm)
            length = _length(command, x, y) * mm
            if down:
                if run is None:
                    run = [f"M{x * mm:.4f} {y * mm:.4f}"]
                    down_at.setdefault(width, []).append(run)  # type: ignore[arg-type]
                    paths.strokes += 1
                run.append(step)
                paths.drawn_mm += length
            else:
                paths.travel.append(f"M{x * mm:.4f} {y * mm:.4f}{step}")
                paths.travel_mm += length
            x, y = nx, ny
            paths.see(x * mm, y * mm)
    return paths


def _segment(command, x: int, y: int, mm: float) -> str:
    """The path data of one move from (x, y) steps."""
    ex, ey = command.x_steps * mm, command.y_steps * mm
    if not isinstance(command, ArcTo):
        return f"L{ex:.4f} {ey:.4f}"
    radius = math.hypot(command.i_steps, command.j_steps) * mm
    # Y is up inside the flipped group: counter-clockwise is SVG's sweep 1
    sweep = 0 if command.cw else 1
    if (command.x_steps, command.y_steps) == (x, y):     # a full circle: two halves
        cx, cy = (x + command.i_steps) * mm, (y + command.j_steps) * mm
        ox, oy = 2 * cx - x * mm, 2 * cy - y * mm
        return (f"A{radius:.4f} {radius:.4f} 0 0 {sweep} {ox:.4f} {oy:.4f}"
                f"A{radius:.4f} {radius:.4f} 0 0 {sweep} {ex:.4f} {ey:.4f}")
    large = 1 if _sweep_angle(command, x, y) > math.pi else 0
    return f"A{radius:.4f} {radius:.4f} 0 {large} {sweep} {ex:.4f} {ey:.4f}"


def _sweep_angle(command: ArcTo, x: int, y: int) -> float:
    cx, cy = x + command.i_steps, y + command.j_steps
    a0 = math.atan2(y - cy, x - cx)
    a1 = math.atan2(command.y_steps - cy, command.x_steps - cx)
    angle = (a0 - a1) if command.cw else (a1 - a0)
    angle %= 2 * math.pi
    return angle or 2 * math.pi


def _length(command, x: int, y: int) -> float:
    """Length of the move in steps."""
    if isinstance(command, ArcTo):
        return math.hypot(command.i_steps, command.j_steps) * _sweep_angle(command, x, y)
    return math.hypot(command.x_steps - x, command.y_steps - y)


def render_svg(program: Program, job: Job, config: MachineConfig, offset_nm: tuple[int, int],
               out_path: str | os.PathLike, *, copper=None,
               pen_widths_nm: dict[int, int] | None = None,
               pen_roles: dict[int, str] | None = None) -> SvgInfo:
    """Write the vector preview of `job` (planned from `program` with `offset_nm`);
    `copper` (an ink plan's, program nm): bare copper and ink outside shown;
    `pen_roles` (PlannedFile.pen_roles): a board's outline and silk pens in colours of
    their own."""
    widths = job.pen_widths_nm if pen_widths_nm is None else pen_widths_nm
    paths = job_paths(job, config, widths, pen_roles)
    ox, oy = offset_nm[0] / NM_PER_MM, offset_nm[1] / NM_PER_MM
    box = extents(program, with_apertures=True)
    if box is not None:
        paths.see(box[0] / NM_PER_MM - ox, box[1] / NM_PER_MM - oy)
        paths.see(box[2] / NM_PER_MM - ox, box[3] / NM_PER_MM - oy)
    widest = max([*paths.down, *paths.dots,
                  *(w for down, dots in paths.lines.values() for w in (*down, *dots))],
                 default=0) / NM_PER_MM
    pad = MARGIN_MM + widest / 2
    x0, y0 = paths.lo[0] - pad, paths.lo[1] - pad
    x1, y1 = paths.hi[0] + pad, paths.hi[1] + pad
    view = (x0, y0, x1, y1)
    legend_h = (3.5 + 1.4 * len(_legend(copper is not None, paths.lines))) * \
        _text_mm(view)                               # below it
    with open(out_path, "w", encoding="utf-8") as out:
        _write(out, program, paths, offset_nm, copper, view, legend_h)
    return SvgInfo(str(out_path), paths.strokes, paths.drawn_mm, paths.travel_mm, view,
                   copper is not None)


def _colour(rgb) -> str:
    return "#{:02x}{:02x}{:02x}".format(*rgb)


def _write(out: TextIO, program: Program, paths: _Paths, offset_nm, copper, view,
           legend_h: float) -> None:
    x0, y0, x1, y1 = view
    width, height = x1 - x0, y1 - y0 + legend_h
    text_mm = _text_mm(view)
    hairline = max(0.02, text_mm / 30)              # travel: thin at any size
    out.write('<?xml version="1.0" encoding="UTF-8"?>\n')
    out.write(f'<svg xmlns="http://www.w3.org/2000/svg" '
              f'xmlns:xlink="http://www.w3.org/1999/xlink" width="{width:.3f}mm" '
              f'height="{height:.3f}mm" viewBox="{x0:.4f} {-y1:.4f} {width:.4f} {height:.4f}">\n')
    out.write(f'<title>{escape(str(program.source))}: galileo-cnc preview (work mm)</title>\n')
    out.write(f'<rect id="paper" x="{x0:.4f}" y="{-y1:.4f}" width="{width:.4f}" '
              f'height="{height:.4f}" fill="#ffffff"/>\n')
    out.write('<defs>\n<g id="strokes" fill="none" stroke-linecap="round" '
              'stroke-linejoin="round">\n')
    _write_strokes(out, paths.down, paths.dots)
    out.write('</g>\n')
    rings = copper_rings(copper) if copper is not None else None
    if rings is not None:
        data = _rings_data(rings, offset_nm)
        out.write(f'<path id="copper" fill-rule="evenodd" d="{data}"/>\n')
        # clip paths, not masks: every renderer clips (evenodd: the copper's rings do
        # not overlap, so the frame with them is the paper outside the copper)
        frame = _frame_against(rings, view)
        out.write(f'<clipPath id="in-copper"><path clip-rule="evenodd" d="{data}"/></clipPath>\n')
        out.write(f'<clipPath id="off-copper"><path clip-rule="evenodd" d="{frame}{data}"/>'
                  '</clipPath>\n')
    out.write('</defs>\n')
    out.write('<g id="work" transform="scale(1,-1)">\n')        # work mm, Y up
    if rings is not None:
        out.write(f'<use id="bare-copper" xlink:href="#copper" fill="{_colour(UNINKED)}"/>\n')
    else:
        _write_artwork(out, program, offset_nm)
    if paths.travel:
        out.write(f'<path id="travel" fill="none" stroke="{_colour(TRAVEL)}" '
                  f'stroke-width="{hairline:.4f}" d="{"".join(paths.travel)}"/>\n')
    if rings is not None:
        out.write(f'<use id="ink" xlink:href="#strokes" color="{_colour(STROKE)}" '
                  'clip-path="url(#in-copper)"/>\n')
        out.write(f'<use id="ink-outside" xlink:href="#strokes" color="{_colour(OUTSIDE)}" '
                  'clip-path="url(#off-copper)"/>\n')
    else:
        out.write(f'<use id="ink" xlink:href="#strokes" color="{_colour(STROKE)}"/>\n')
    for role, (down, dots) in sorted(paths.lines.items()):
        out.write(f'<g id="{escape(role)}" fill="none" stroke-linecap="round" '
                  f'stroke-linejoin="round" color="{_colour(LINE_COLOURS.get(role, STROKE))}">\n')
        _write_strokes(out, down, dots)
        out.write('</g>\n')
    arm = 1.5 * text_mm
    out.write(f'<g id="origin" stroke="#d00000" stroke-width="{2 * hairline:.4f}">'
              f'<path d="M{-arm:.3f} 0H{arm:.3f}M0 {-arm:.3f}V{arm:.3f}"/></g>\n')
    out.write('</g>\n')
    out.write(f'<text x="{arm * 0.6:.3f}" y="{-arm * 0.6:.3f}" font-size="{text_mm:.2f}" '
              f'font-family="sans-serif" fill="#d00000">origin X 0, Y 0 (work)</text>\n')
    _write_scale_and_legend(out, view, text_mm, _legend(rings is not None, paths.lines))
    out.write('</svg>\n')


def _write_strokes(out: TextIO, down: dict[int, list], dots: dict[int, list]) -> None:
    """Runs at their pen's width and dots as the pen's disc, in currentColor."""
    for width_nm, runs in sorted(down.items()):
        data = "".join("".join(run) for run in runs)
        out.write(f'<path stroke-width="{width_nm / NM_PER_MM:.4f}" stroke="currentColor" '
                  f'd="{data}"/>\n')
    for width_nm, points in sorted(dots.items()):
        r = width_nm / NM_PER_MM / 2
        for x, y in points:
            out.write(f'<circle cx="{x:.4f}" cy="{y:.4f}" r="{r:.4f}" fill="currentColor"/>\n')


def _frame_against(rings, view) -> str:
    """The view's frame as path data wound against the copper's outer rings: with them
    it covers the paper outside the copper by the nonzero rule as by evenodd (some
    renderers clip by nonzero whatever the clip-rule says)."""
    x0, y0, x1, y1 = view
    areas = [_area2(ring) for ring in rings]
    outer = max(areas, key=abs, default=1.0)        # the largest ring is an outer one
    if outer > 0:                                    # outer counter-clockwise: frame clockwise
        return f"M{x0:.4f} {y0:.4f}V{y1:.4f}H{x1:.4f}V{y0:.4f}Z"
    return f"M{x0:.4f} {y0:.4f}H{x1:.4f}V{y1:.4f}H{x0:.4f}Z"


def _area2(ring) -> float:
    """Twice the signed area of a ring (positive: counter-clockwise, Y up)."""
    points = np.asarray(ring, dtype=np.float64)
    x, y = points[:, 0], points[:, 1]
    return float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _rings_data(rings, offset_nm) -> str:
    ox, oy = offset_nm
    parts = []
    for ring in rings:
        points = (np.asarray(ring, dtype=np.float64) - (ox, oy)) / NM_PER_MM
        flat = "L".join(f"{x:.4f} {y:.4f}" for x, y in points.tolist())
        parts.append(f"M{flat}Z")
    return "".join(parts)


def _write_scale_and_legend(out: TextIO, view, u: float, legend) -> None:
    """Below the drawing: a scale bar of a round length, then the legend (_legend);
    `u` is the text size (mm), the unit of the layout (_text_mm)."""
    x0, y0, x1, _ = view
    bar = _round_length((x1 - x0) / 4)
    left, top = x0 + u, -y0 + 1.5 * u                # SVG y of the row below the drawing
    out.write(f'<g id="scale" stroke="#000000"><path d="M{left:.3f} {top:.3f}h{bar:g}" '
              f'stroke-width="{0.15 * u:.3f}"/><path d="M{left:.3f} {top - 0.4 * u:.3f}'
              f'v{0.8 * u:.3f}M{left + bar:.3f} {top - 0.4 * u:.3f}v{0.8 * u:.3f}" '
              f'stroke-width="{0.08 * u:.3f}"/><text x="{left + bar + 0.5 * u:.3f}" '
              f'y="{top + 0.35 * u:.3f}" font-size="{u:.3f}" stroke="none" '
              f'font-family="sans-serif">{bar:g} mm</text></g>\n')
    out.write('<g id="legend" font-family="sans-serif">\n')
    for row, (label, colour) in enumerate(legend):
        y = top + (1.5 + 1.4 * row) * u
        out.write(f'<rect x="{left:.3f}" y="{y - 0.45 * u:.3f}" width="{1.8 * u:.3f}" '
                  f'height="{0.9 * u:.3f}" fill="{_colour(colour)}"/><text '
                  f'x="{left + 2.3 * u:.3f}" y="{y + 0.35 * u:.3f}" font-size="{u:.3f}">'
                  f'{escape(label)}</text>\n')
    out.write('</g>\n')


def _legend(copper: bool, lines=()):
    """The legend's rows: bare copper and ink outside only where the copper is shown,
    the outline and silk where they are drawn."""
    shown = [item for item in LEGEND if copper or item[1] not in (UNINKED, OUTSIDE)]
    return shown[:-1] + [(role, LINE_COLOURS.get(role, STROKE)) for role in sorted(lines)] + \
        shown[-1:]


def _text_mm(view) -> float:
    """The legend's text size: a fortieth of the drawing's larger side, 0.4 to 3 mm."""
    return max(0.4, min(3.0, max(view[2] - view[0], view[3] - view[1]) / 40))


def _round_length(mm: float) -> float:
    """The largest 1, 2 or 5 times a power of ten not above `mm` (at least 0.1 mm)."""
    if mm <= 0.1:
        return 0.1
    power = 10 ** math.floor(math.log10(mm))
    return max(m * power for m in (1, 2, 5) if m * power <= mm)


def _write_artwork(out: TextIO, program: Program, offset_nm) -> None:
    """The Program's paths at their aperture widths, flashes by their extent, regions
    filled; clear polarity is not drawn (ink mode shows the copper exactly)."""
    table = program.table
    if not len(table):
        return
    starts = start_points(table)
    ox, oy = offset_nm
    by_width: dict[float, list[str]] = {}
    flashes: list[str] = []
    region: list[str] = []
    regions: list[str] = []
    in_region = False
    for index, row in enumerate(table.tolist()):
        kind = row[KIND]
        if kind == OpKind.POLARITY and not row[VALUE]:
            continue
        sx, sy = (starts[index, 0] - ox) / NM_PER_MM, (starts[index, 1] - oy) / NM_PER_MM
        ex, ey = (row[X] - ox) / NM_PER_MM, (row[Y] - oy) / NM_PER_MM
        if kind == OpKind.REGION_BEGIN:
            in_region, region = True, []
        elif kind == OpKind.REGION_END:
            if region:
                regions.append("".join(region) + "Z")
            in_region = False
        elif kind in (OpKind.LINE, OpKind.ARC_CW, OpKind.ARC_CCW):
            if kind == OpKind.LINE:
                step = f"L{ex:.4f} {ey:.4f}"
            else:
                step = _program_arc(row, starts[index], ox, oy, kind == OpKind.ARC_CW)
            if in_region:
                region.append((f"M{sx:.4f} {sy:.4f}" if not region else "") + step)
                continue
            width = round(path_width_mm(program.apertures.get(row[TOOL])), 4)
            by_width.setdefault(width, []).append(f"M{sx:.4f} {sy:.4f}{step}")
        elif kind == OpKind.MOVE and in_region and region:
            regions.append("".join(region) + "Z")
            region = []
        elif kind == OpKind.FLASH:
            aperture = program.apertures.get(row[TOOL])
            e = aperture.extent_nm if aperture is not None else (-50_000, -50_000, 50_000, 50_000)
            w, h = (e[2] - e[0]) / NM_PER_MM, (e[3] - e[1]) / NM_PER_MM
            left, bottom = ex + e[0] / NM_PER_MM, ey + e[1] / NM_PER_MM
            shape = aperture.shape if aperture is not None else "rectangle"
            if shape == "circle":
                flashes.append(f'<circle cx="{ex:.4f}" cy="{ey:.4f}" r="{w / 2:.4f}"/>')
            else:
                round_mm = min(w, h) / 2 if shape == "obround" else 0.0
                flashes.append(f'<rect x="{left:.4f}" y="{bottom:.4f}" width="{w:.4f}" '
                               f'height="{h:.4f}" rx="{round_mm:.4f}"/>')
    colour = _colour(ART)
    out.write(f'<g id="artwork" fill="{colour}" stroke="{colour}">\n')
    if regions:
        out.write(f'<path stroke="none" d="{"".join(regions)}"/>\n')
    for width, pieces in sorted(by_width.items()):
        out.write(f'<path fill="none" stroke-linecap="round" stroke-width="{width:.4f}" '
                  f'd="{"".join(pieces)}"/>\n')
    if flashes:
        out.write('<g stroke="none">' + "".join(flashes) + "</g>\n")
    out.write('</g>\n')


def _program_arc(row, start, ox: int, oy: int, cw: bool) -> str:
    """An arc row of the Program as path data in work mm."""
    arc = ArcTo(int(row[X]) - ox, int(row[Y]) - oy, int(row[I]), int(row[J]), cw)
    return _segment(arc, int(start[0]) - ox, int(start[1]) - oy, 1 / NM_PER_MM)
