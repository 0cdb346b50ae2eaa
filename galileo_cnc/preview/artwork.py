"""The artwork layer of a preview: pygerber's raster, or our own drawing of the Program.

pygerber draws Gerber exactly but slowly (~30 kB/s) and not every file; it is used
for files up to a size limit whose extent agrees with ours (else its picture would
sit elsewhere than the pen strokes). Otherwise the Program is drawn with Pillow:
paths at the aperture width, flashes by shape, regions filled, clear polarity in
the background colour. Coordinates are work mm (file nm minus the offset), Y up.
"""

from __future__ import annotations

import logging
import math
import warnings
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from galileo_cnc.program.extents import extents, start_points
from galileo_cnc.program.ops import (I, J, KIND, NM_PER_MM, TOOL, VALUE, X, Y, Aperture,
                                     OpKind, Program)

BACKGROUND = (255, 255, 255)
ART = (160, 215, 160)           # light green
DEFAULT_PYGERBER_LIMIT = 200_000   # bytes; pygerber reads ~30 kB/s
# Width of artwork paths that have no aperture (G-code), in mm.
_BARE_PATH_MM = 0.5


class PixelFrame:
    """Work mm -> Pillow coordinates (pixel centres at integers; Y flipped)."""

    def __init__(self, view, scale: float):
        self.x0, self.y1, self.scale = view[0], view[3], scale

    def xy(self, x_mm, y_mm):
        return ((np.asarray(x_mm) - self.x0) * self.scale - 0.5,
                (self.y1 - np.asarray(y_mm)) * self.scale - 0.5)

    def length(self, mm: float) -> float:
        return mm * self.scale



# ---- artwork: pygerber -------------------------------------------------------------

def artwork_box(program: Program, offset_nm, pygerber_limit: int, notes: list[str]):
    """(pygerber's parsed file or None, artwork box in work mm or None); the
    reasons for not using pygerber go to `notes`."""
    box = extents(program, with_apertures=True)
    ours = None if box is None else tuple(
        (v - offset_nm[k % 2]) / NM_PER_MM for k, v in enumerate(box))
    if program.format != "gerber":
        return None, ours
    if program.metadata.get("side") == "bottom":
        notes.append("a board's bottom side is drawn mirrored; pygerber would draw the file "
                     "as it is")
        return None, ours
    parsed, why = _pygerber_parse(program.source, pygerber_limit)
    if parsed is None:
        notes.append(why)
        return None, ours
    theirs = _pygerber_box(parsed, offset_nm)
    if ours is not None and _disagree(theirs, ours):
        # pygerber read the file differently (units, image transforms...): its
        # picture would sit elsewhere than the strokes, so do not show it.
        notes.append("pygerber's artwork extent differs from ours: "
                     f"{_fmt_box(theirs)} vs {_fmt_box(ours)} mm (work)")
        return None, ours
    return parsed, theirs


def _pygerber_box(parsed, offset_nm) -> tuple[float, float, float, float]:
    """pygerber's bounding box (file mm, apertures included) in work mm."""
    bb = parsed._command_buffer.get_bounding_box()
    ox, oy = offset_nm[0] / NM_PER_MM, offset_nm[1] / NM_PER_MM
    return (float(bb.min_x.as_millimeters()) - ox, float(bb.min_y.as_millimeters()) - oy,
            float(bb.max_x.as_millimeters()) - ox, float(bb.max_y.as_millimeters()) - oy)


def _disagree(a, b) -> bool:
    """Boxes differ by more than pygerber's usual slack (it bounds rotated macro
    flashes loosely, up to a few mm) would explain."""
    span = max(b[2] - b[0], b[3] - b[1])
    return max(abs(u - v) for u, v in zip(a, b)) > max(5.0, 0.1 * span)


def _fmt_box(box) -> str:
    return "(" + ", ".join(f"{v:.2f}" for v in box) + ")"


def _pygerber_parse(source: str, limit: int):
    """(parsed file, None) or (None, why pygerber is not used)."""
    try:
        size = Path(source).stat().st_size
    except OSError:
        return None, f"{source}: not readable for pygerber"
    if size > limit:
        return None, f"file is {size} bytes, over the pygerber limit of {limit}"
    try:
        with _quiet_pygerber():
            from pygerber.gerberx3.api.v2 import GerberFile
            parsed = GerberFile.from_file(source).parse()
        bb = parsed._command_buffer.get_bounding_box()
        if not bb.width.as_millimeters() > 0 and not bb.height.as_millimeters() > 0:
            return None, "pygerber found nothing to draw"
        return parsed, None
    except Exception as problem:  # pygerber raises many kinds; any means "use ours"
        return None, f"pygerber could not read the file: {type(problem).__name__}: {problem}"


@contextmanager
def _quiet_pygerber():
    """pygerber logs style advice on the root logger and its grammar raises
    pyparsing deprecation warnings; neither is news for the user of a preview."""
    previous = logging.root.manager.disable
    logging.disable(logging.WARNING)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            yield
    finally:
        logging.disable(previous)


def paste_pygerber(canvas: Image.Image, parsed, to_px: PixelFrame, offset_nm) -> None:
    """Render with pygerber (transparent background, ART for dark) and paste it so
    its lower-left corner lands on its bounding box's corner in work mm."""
    from pygerber.common.rgba import RGBA
    from pygerber.gerberx3.api.v2 import ColorScheme
    from pygerber.gerberx3.renderer2.raster import RasterRenderer2, RasterRenderer2Hooks

    dark, none = RGBA.from_rgba(*ART, 255), RGBA.from_rgba(0, 0, 0, 0)
    scheme = ColorScheme(background_color=none, clear_color=none, solid_color=dark,
                         clear_region_color=none, solid_region_color=dark)
    dpmm = max(1, round(to_px.scale))  # pygerber takes whole dots per mm
    with _quiet_pygerber():
        image = RasterRenderer2(RasterRenderer2Hooks(color_scheme=scheme, dpmm=dpmm)) \
            .render(parsed._command_buffer).get_image().convert("RGBA")
    # pygerber's pixel k spans [min + k/dpmm, min + (k+1)/dpmm); the image is
    # flipped so its last row is the bottom edge.
    left, bottom, _, _ = _pygerber_box(parsed, offset_nm)
    top = bottom + image.height / dpmm
    if dpmm != to_px.scale:
        factor = to_px.scale / dpmm
        image = image.resize((max(1, round(image.width * factor)),
                              max(1, round(image.height * factor))), Image.Resampling.BILINEAR)
    col, row = to_px.xy(left, top)
    canvas.paste(image, (round(float(col) + 0.5), round(float(row) + 0.5)), image)


# ---- artwork: our own light rendering ------------------------------------------------

def draw_program(draw: ImageDraw.ImageDraw, program: Program, to_px: PixelFrame,
                  offset_nm: tuple[int, int]) -> None:
    """The Program's drawn paths and flashes with Pillow: lines with the aperture
    width, flashes by shape, regions filled, clear polarity in the background
    colour. One light Python step per op (~0.2 s for 100 000 ops): the ops' starts
    and ends are turned into pixels in numpy, a block of ops at a time (_rows)."""
    table = program.table
    starts = start_points(table)
    ox, oy = offset_nm

    def px(x_nm, y_nm):  # file nm -> Pillow coordinates
        return to_px.xy((np.asarray(x_nm) - ox) / NM_PER_MM, (np.asarray(y_nm) - oy) / NM_PER_MM)

    colour = ART
    contour: list[float] = []       # region outline being collected (flat px coords)
    in_region = False

    def fill_contour():
        if len(contour) >= 6:
            draw.polygon(contour, fill=colour)
        contour.clear()

    for index, row, start_px, end_px in _rows(table, starts, px):
        kind = row[KIND]
        if kind == OpKind.POLARITY:
            colour = ART if row[VALUE] else BACKGROUND
        elif kind == OpKind.REGION_BEGIN:
            in_region = True
        elif kind == OpKind.REGION_END:
            fill_contour()
            in_region = False
        elif kind in (OpKind.LINE, OpKind.ARC_CW, OpKind.ARC_CCW):
            aperture = program.apertures.get(row[TOOL])
            width = 1 if in_region else max(1, round(to_px.length(path_width_mm(aperture))))
            if kind == OpKind.LINE:
                flat = start_px + end_px
            else:
                xs, ys = _arc_points(int(starts[index, 0]), int(starts[index, 1]), row[X], row[Y],
                                     row[I], row[J], kind == OpKind.ARC_CW, to_px.scale, width)
                flat = np.stack(px(xs, ys), axis=1).ravel().tolist()
            if in_region:
                contour.extend(flat if not contour else flat[2:])
                continue
            draw.line(flat, fill=colour, width=width, joint="curve")
            if width >= 3 and (aperture is None or aperture.shape == "circle"):
                r = width / 2  # round caps, as a round aperture (or pen) draws
                for x, y in ((flat[0], flat[1]), (flat[-2], flat[-1])):
                    draw.ellipse((x - r, y - r, x + r, y + r), fill=colour)
        elif kind == OpKind.MOVE and in_region:
            fill_contour()
        elif kind == OpKind.FLASH:
            aperture = program.apertures.get(row[TOOL])
            col, r = end_px
            _draw_flash(draw, aperture, col, r, to_px.scale / NM_PER_MM, colour)
    fill_contour()


def _rows(table: np.ndarray, starts: np.ndarray, px, block: int = 8192):
    """(index, row as a list, start and end in pixels as [col, row]) per op; the
    pixels are computed a block of ops at a time in numpy, and only a block is
    ever held as Python lists."""
    for lo in range(0, len(table), block):
        rows = table[lo:lo + block]
        ends = np.stack(px(rows[:, X], rows[:, Y]), axis=1).tolist()
        begins = np.stack(px(starts[lo:lo + block, 0], starts[lo:lo + block, 1]), axis=1).tolist()
        yield from zip(range(lo, lo + len(rows)), rows.tolist(), begins, ends)


def path_width_mm(aperture: Aperture | None) -> float:
    if aperture is None:
        return _BARE_PATH_MM
    p = aperture.params_nm
    if aperture.shape in ("circle", "polygon") and p:
        return p[0] / NM_PER_MM
    if aperture.shape in ("rectangle", "obround") and len(p) >= 2:
        return min(p[0], p[1]) / NM_PER_MM
    e = aperture.extent_nm
    return min(e[2] - e[0], e[3] - e[1]) / NM_PER_MM


def _arc_points(sx, sy, ex, ey, i, j, clockwise: bool, px_per_mm: float, width_px: int):
    """Points (nm) along an arc; start == end is a circle. Segments are about as
    long as the line is wide (Pillow frays wide lines made of tiny segments) and
    at most 1/16 turn."""
    cx, cy = sx + i, sy + j
    radius = math.hypot(sx - cx, sy - cy)
    a0 = math.atan2(sy - cy, sx - cx)
    a1 = math.atan2(ey - cy, ex - cx)
    sweep = (a0 - a1) if clockwise else (a1 - a0)
    sweep %= 2 * math.pi
    if sweep == 0 and (sx, sy) == (ex, ey):
        sweep = 2 * math.pi
    arc_px = sweep * radius / NM_PER_MM * px_per_mm
    count = int(min(720, max(2, arc_px / max(4, width_px), sweep / (math.pi / 8)))) + 1
    angles = a0 + (-1 if clockwise else 1) * np.linspace(0.0, sweep, count)
    xs, ys = cx + radius * np.cos(angles), cy + radius * np.sin(angles)
    xs[-1], ys[-1] = ex, ey
    return xs, ys


def _draw_flash(draw: ImageDraw.ImageDraw, aperture: Aperture | None, x: float, y: float,
                px_per_nm: float, colour) -> None:
    """One flash at pixel (x, y). Holes are ignored; unknown shapes use their extent."""
    def dot(diameter_px: float, cx: float = x, cy: float = y, fill=colour):
        r = max(0.5, diameter_px / 2)
        draw.ellipse((cx - r, cy - r, cx + r, cy + r), fill=fill)

    if aperture is None:
        dot(3)
        return
    p, shape = aperture.params_nm, aperture.shape
    rotation = aperture.rotation_udeg / 1e6
    if shape == "circle" and p:
        dot(p[0] * px_per_nm)
    elif shape in ("rectangle", "obround") and len(p) >= 2:
        w, h = p[0] * px_per_nm, p[1] * px_per_nm
        if rotation % 180 == 90:
            w, h = h, w
        box = (x - w / 2, y - h / 2, x + w / 2, y + h / 2)
        if shape == "rectangle" and rotation % 90 == 0:
            draw.rectangle(box, fill=colour)
        elif rotation % 90 == 0:
            draw.rounded_rectangle(box, radius=min(w, h) / 2, fill=colour)
        else:  # rotated by an odd angle: its corners (an obround's as a rectangle)
            c, s = math.cos(math.radians(rotation)), math.sin(math.radians(rotation))
            half = ((-w / 2, -h / 2), (w / 2, -h / 2), (w / 2, h / 2), (-w / 2, h / 2))
            corners = [(x + u * c - v * s, y - (u * s + v * c)) for u, v in half]
            draw.polygon(corners, fill=colour)
    elif shape == "polygon" and p and aperture.vertices >= 3:
        draw.regular_polygon((x, y, max(0.5, p[0] * px_per_nm / 2)), aperture.vertices,
                             rotation=rotation, fill=colour)
    elif shape == "macro" and aperture.primitives:
        for primitive in aperture.primitives:
            fill = colour if primitive[1] else BACKGROUND
            if primitive[0] == "circle":
                _, _, cx, cy, diameter = primitive
                dot(diameter * px_per_nm, x + cx * px_per_nm, y - cy * px_per_nm, fill)
            elif primitive[0] == "polygon" and len(primitive[2]) >= 3:
                draw.polygon([(x + u * px_per_nm, y - v * px_per_nm) for u, v in primitive[2]],
                             fill=fill)
    else:
        e = aperture.extent_nm
        draw.rectangle((x + e[0] * px_per_nm, y - e[3] * px_per_nm,
                        x + e[2] * px_per_nm, y - e[1] * px_per_nm), fill=colour)
