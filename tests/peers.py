"""Peer Gerber readers (gerbonara, pygerber) reduced to one comparable summary.

Test helper, not part of the package. Each `*_summary` function reads one Gerber
file and returns a `PeerSummary` in integer nanometres, so our reader's Program and
two readers nobody here wrote can be compared number for number.

What a summary holds (the same definitions on every side):

- flashes / draws / arcs per aperture, keyed by D-code. Both peers keep the D-code
  the file used (gerbonara: `Aperture.original_number`; pygerber: `Aperture2.identifier`
  "D10"), neither renumbers or dedups on read, so no canonical shape key is needed.
  Only objects outside regions count; region contours are counted separately.
- bbox_nm: (xmin, ymin, xmax, ymax) of stroke centre lines (both end points),
  arc extremes (an arc reaches cx +- r / cy +- r where it crosses an axis direction)
  and flash points, outside regions. Aperture size is NOT included. None if nothing.
- region_bbox_nm: the same for region contours (segment end points and arc extremes).
- region_count: G36..G37 blocks. None where the peer cannot tell (gerbonara stores one
  Region object per contour and forgets which G36 it came from).
- contour_count: non-empty region contours (a D02 inside a region starts a new one).
  None where the peer cannot tell (pygerber does not record region D02s).
- region_segments: lines + arcs inside regions.

Arc geometry rule (applied identically to all sides): radius = |start - centre|;
start == end (after rounding to nm) is a full circle; clockwise sweeps from start
angle downwards.

Units: gerbonara keeps each object in the file's unit (`obj.unit`, MM or Inch; it does
not convert on read), so we scale by `unit.this_in_mm` * 1e6. pygerber converts every
coordinate to millimetres (Decimal) while parsing, so we scale by 1e6.
"""

from __future__ import annotations

import math
import warnings
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from corpus import CORPUS, manifest

NM_PER_MM = 1_000_000
TWO_PI = 2.0 * math.pi

# --------------------------------------------------------------------------- corpus


def corpus_dir() -> Path:
    """The Gerber corpus in use: $GALILEO_CORPUS, ../shared or the curated one (corpus.py)."""
    return CORPUS


@dataclass(frozen=True, slots=True)
class CorpusFile:
    path: str  # relative to corpus_dir()
    bytes: int
    lines: int
    source: str  # repo@commit:path, "(derived from X)" for derived files
    generator: str
    units: str
    fs_format: str
    features: str
    kind: str


READABLE_KINDS = ("real", "synthetic", "derived")


def corpus_files(kinds: tuple[str, ...] = READABLE_KINDS) -> list[CorpusFile]:
    """Rows of MANIFEST.tsv whose kind is in `kinds`, in manifest order."""
    if not (CORPUS / "MANIFEST.tsv").is_file():
        return []
    return [CorpusFile(row["path"], int(row["bytes"]), int(row["lines"]), row["source"],
                       row["generator"], row["units"], row["fs_format"], row["features"], row["kind"])
            for row in manifest() if row["kind"] in kinds]


# --------------------------------------------------------------------------- summary


@dataclass(slots=True)
class PeerSummary:
    """What one reader saw in one file, in integer nanometres (see module doc)."""

    flashes_by_aperture: dict[int, int] = field(default_factory=dict)
    draws_by_aperture: dict[int, int] = field(default_factory=dict)
    arcs_by_aperture: dict[int, int] = field(default_factory=dict)
    bbox_nm: tuple[int, int, int, int] | None = None
    region_count: int | None = 0
    contour_count: int | None = 0
    region_segments: int = 0
    region_bbox_nm: tuple[int, int, int, int] | None = None

    @property
    def flashes(self) -> int:
        return sum(self.flashes_by_aperture.values())

    @property
    def draws(self) -> int:
        return sum(self.draws_by_aperture.values())

    @property
    def arcs(self) -> int:
        return sum(self.arcs_by_aperture.values())


class _Box:
    """Running float bounding box, rounded to integer nm at the end."""

    __slots__ = ("x0", "y0", "x1", "y1")

    def __init__(self):
        self.x0 = self.y0 = math.inf
        self.x1 = self.y1 = -math.inf

    def point(self, x: float, y: float) -> None:
        if x < self.x0:
            self.x0 = x
        if x > self.x1:
            self.x1 = x
        if y < self.y0:
            self.y0 = y
        if y > self.y1:
            self.y1 = y

    def arc(self, sx, sy, ex, ey, cx, cy, clockwise: bool) -> None:
        """Add an arc's end points and every axis extreme its sweep passes."""
        self.point(sx, sy)
        self.point(ex, ey)
        r = math.hypot(sx - cx, sy - cy)
        if r == 0.0:
            return
        if round(sx) == round(ex) and round(sy) == round(ey):
            sweep = TWO_PI
        else:
            a0 = math.atan2(sy - cy, sx - cx)
            a1 = math.atan2(ey - cy, ex - cx)
            sweep = ((a0 - a1) if clockwise else (a1 - a0)) % TWO_PI
        a0 = math.atan2(sy - cy, sx - cx)
        for quarter, (dx, dy) in enumerate(((1, 0), (0, 1), (-1, 0), (0, -1))):
            axis = quarter * math.pi / 2
            # angle travelled from start to reach this axis direction
            dist = ((a0 - axis) if clockwise else (axis - a0)) % TWO_PI
            if dist <= sweep:
                self.point(cx + dx * r, cy + dy * r)

    def result(self) -> tuple[int, int, int, int] | None:
        if self.x0 > self.x1:
            return None
        return (round(self.x0), round(self.y0), round(self.x1), round(self.y1))


def bbox_close(a, b, tol_nm: int = 1000) -> bool:
    """Both None, or every edge within tol_nm."""
    if a is None or b is None:
        return a is None and b is None
    return all(abs(p - q) <= tol_nm for p, q in zip(a, b))


def union_bbox(*boxes):
    boxes = [b for b in boxes if b is not None]
    if not boxes:
        return None
    return (min(b[0] for b in boxes), min(b[1] for b in boxes),
            max(b[2] for b in boxes), max(b[3] for b in boxes))


# --------------------------------------------------------------------------- ours


def ours_summary(program) -> PeerSummary:
    """Summary of a galileo_cnc Program, straight from its int64 table.

    LINE rows are draws, ARC_CW/ARC_CCW arcs, FLASH flashes, counted per `tool`
    outside regions. Rows between REGION_BEGIN and REGION_END are region contour;
    a MOVE there starts a new contour. A segment starts where the previous
    positioned row (MOVE/LINE/ARC/FLASH) ended, (0, 0) before the first one.
    """
    from galileo_cnc.program.ops import KIND, X, Y, I, J, TOOL, OpKind

    t = program.table
    kind = t[:, KIND]
    begin = kind == OpKind.REGION_BEGIN
    end = kind == OpKind.REGION_END
    in_region = (np.cumsum(begin) - np.cumsum(end)) > 0
    in_region &= ~begin

    positioned = np.isin(kind, [OpKind.MOVE, OpKind.LINE, OpKind.ARC_CW, OpKind.ARC_CCW,
                                OpKind.FLASH])
    pos_idx = np.flatnonzero(positioned)
    # start point of each positioned row = end point of the previous positioned row
    start_x = np.zeros(len(t), dtype=np.int64)
    start_y = np.zeros(len(t), dtype=np.int64)
    if len(pos_idx) > 1:
        start_x[pos_idx[1:]] = t[pos_idx[:-1], X]
        start_y[pos_idx[1:]] = t[pos_idx[:-1], Y]

    is_line = kind == OpKind.LINE
    is_arc = (kind == OpKind.ARC_CW) | (kind == OpKind.ARC_CCW)
    is_flash = kind == OpKind.FLASH

    def per_tool(mask) -> dict[int, int]:
        codes, counts = np.unique(t[mask, TOOL], return_counts=True)
        return {int(c): int(n) for c, n in zip(codes, counts)}

    def box_of(line_mask, arc_mask, flash_mask):
        box = _Box()
        parts_x = [t[line_mask, X], start_x[line_mask], t[flash_mask, X],
                   t[arc_mask, X], start_x[arc_mask]]
        parts_y = [t[line_mask, Y], start_y[line_mask], t[flash_mask, Y],
                   t[arc_mask, Y], start_y[arc_mask]]
        xs = np.concatenate(parts_x)
        ys = np.concatenate(parts_y)
        if len(xs):
            box.point(float(xs.min()), float(ys.min()))
            box.point(float(xs.max()), float(ys.max()))
        for r in np.flatnonzero(arc_mask):
            sx, sy = float(start_x[r]), float(start_y[r])
            box.arc(sx, sy, float(t[r, X]), float(t[r, Y]),
                    sx + float(t[r, I]), sy + float(t[r, J]),
                    kind[r] == OpKind.ARC_CW)
        return box.result()

    outside = ~in_region & ~begin & ~end
    s = PeerSummary(
        flashes_by_aperture=per_tool(is_flash & outside),
        draws_by_aperture=per_tool(is_line & outside),
        arcs_by_aperture=per_tool(is_arc & outside),
        bbox_nm=box_of(is_line & outside, is_arc & outside, is_flash & outside),
        region_count=int(begin.sum()),
        region_segments=int(((is_line | is_arc) & in_region).sum()),
        region_bbox_nm=box_of(is_line & in_region, is_arc & in_region,
                              np.zeros(len(t), dtype=bool)),
    )
    # contours: inside regions, runs of segments separated by MOVE or a region start
    contours = 0
    drawing = False
    region_kinds = kind[in_region | begin]
    for k in region_kinds.tolist():
        if k == OpKind.REGION_BEGIN or k == OpKind.MOVE:
            drawing = False
        elif k in (OpKind.LINE, OpKind.ARC_CW, OpKind.ARC_CCW) and not drawing:
            drawing = True
            contours += 1
    s.contour_count = contours
    return s


# --------------------------------------------------------------------------- gerbonara


def gerbonara_read(path):
    """gerbonara.GerberFile for `path`, its warnings silenced (they are many)."""
    from gerbonara.rs274x import GerberFile

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return GerberFile.open(path)


def gerbonara_summary(path) -> PeerSummary:
    """Summary of gerbonara's reading.

    Object model: GerberFile.objects is a flat list of Flash(x, y, aperture),
    Line(x1, y1, x2, y2, aperture), Arc(x1, y1, x2, y2, cx, cy, clockwise, aperture;
    cx/cy relative to the start) and Region(outline points, arc_centers: None for a
    straight segment or (clockwise, (cx, cy)) absolute). Coordinates stay in the
    file's unit; deprecated IR/MI/SF/OF are already applied. One Region per contour.
    """
    return gerbonara_summary_of(gerbonara_read(path))


def gerbonara_summary_of(gf) -> PeerSummary:
    from gerbonara import graphic_objects as go

    flashes, draws, arcs = Counter(), Counter(), Counter()
    box, rbox = _Box(), _Box()
    contours = segments = 0
    for obj in gf.objects:
        k = obj.unit.this_in_mm * NM_PER_MM
        cls = type(obj)
        if cls is go.Flash:
            flashes[_gerbonara_code(obj.aperture)] += 1
            box.point(obj.x * k, obj.y * k)
        elif cls is go.Line:
            draws[_gerbonara_code(obj.aperture)] += 1
            box.point(obj.x1 * k, obj.y1 * k)
            box.point(obj.x2 * k, obj.y2 * k)
        elif cls is go.Arc:
            arcs[_gerbonara_code(obj.aperture)] += 1
            box.arc(obj.x1 * k, obj.y1 * k, obj.x2 * k, obj.y2 * k,
                    (obj.x1 + obj.cx) * k, (obj.y1 + obj.cy) * k, obj.clockwise)
        elif cls is go.Region:
            if not obj.outline:
                continue
            contours += 1
            pts = obj.outline
            segments += len(obj.arc_centers)
            for n, arc in enumerate(obj.arc_centers):
                (sx, sy), (ex, ey) = pts[n], pts[n + 1]
                if arc:
                    clockwise, (cx, cy) = arc
                    rbox.arc(sx * k, sy * k, ex * k, ey * k, cx * k, cy * k, clockwise)
                else:
                    rbox.point(sx * k, sy * k)
                    rbox.point(ex * k, ey * k)
        else:
            raise TypeError(f"unexpected gerbonara object {cls.__name__}")
    return PeerSummary(dict(flashes), dict(draws), dict(arcs), box.result(),
                       region_count=None, contour_count=contours,
                       region_segments=segments, region_bbox_nm=rbox.result())


def _gerbonara_code(aperture) -> int:
    return -1 if aperture is None else int(aperture.original_number)


# --------------------------------------------------------------------------- pygerber


_PYGERBER_TOKENIZER = None


def pygerber_parse(path_or_text, *, is_text: bool = False):
    """pygerber 2.4 command buffer for a file, raising on any error.

    The same steps as `pygerber.gerberx3.api.v2.GerberFile.parse(on_parser_error=
    OnParserErrorEnum.Raise)` (Tokenizer().tokenize, then Parser2 with
    Parser2OnErrorAction.Raise), minus the bounding box the API computes for
    `get_info()`, and with one Tokenizer (its grammar takes a while to build) reused.
    The tokenizer's grammar must reach M02 or M00, so text it does not know raises
    pyparsing.ParseException; text after M02 is ignored, as the spec allows.
    """
    global _PYGERBER_TOKENIZER
    from pygerber.gerberx3.parser2.parser2 import (Parser2, Parser2OnErrorAction,
                                                    Parser2Options)
    from pygerber.gerberx3.tokenizer.tokenizer import Tokenizer

    text = path_or_text if is_text else Path(path_or_text).read_text(encoding="utf-8")
    if _PYGERBER_TOKENIZER is None:
        _PYGERBER_TOKENIZER = Tokenizer()
    ast = _PYGERBER_TOKENIZER.tokenize(text)
    parser = Parser2(Parser2Options(
        on_update_drawing_state_error=Parser2OnErrorAction.Raise))
    return parser.parse(ast)


def pygerber_summary(path) -> PeerSummary:
    """Summary of pygerber's reading.

    Object model: a flat ReadonlyCommandBuffer2 of Flash2(flash_point, aperture),
    Line2(start_point, end_point, aperture), Arc2 (clockwise) / CCArc2 (counter-
    clockwise) (start_point, end_point, center_point absolute), Region2 (its own
    command_buffer of Line2/Arc2 with a NoCircle2 aperture) and BufferCommand2, which
    holds the copies of a step-and-repeat block and each flash of a block aperture
    (%AB) already translated. Points are Vector2D of Offset in millimetres (Decimal).
    """
    return pygerber_summary_of(pygerber_parse(path))


def pygerber_summary_of(buffer) -> PeerSummary:
    from pygerber.gerberx3.parser2.commands2.arc2 import Arc2, CCArc2
    from pygerber.gerberx3.parser2.commands2.buffer_command2 import BufferCommand2
    from pygerber.gerberx3.parser2.commands2.flash2 import Flash2
    from pygerber.gerberx3.parser2.commands2.line2 import Line2
    from pygerber.gerberx3.parser2.commands2.region2 import Region2

    flashes, draws, arcs = Counter(), Counter(), Counter()
    box, rbox = _Box(), _Box()
    regions = segments = 0

    def nm(v) -> float:
        return float(v.value) * NM_PER_MM

    def pt(p):
        return nm(p.x), nm(p.y)

    def code(aperture) -> int:
        return int(str(aperture.identifier).lstrip("Dd"))

    def walk(commands, in_region: bool):
        nonlocal regions, segments
        for c in commands:
            cls = type(c)
            if cls is Flash2:
                flashes[code(c.aperture)] += 1
                box.point(*pt(c.flash_point))
            elif cls is Line2:
                b = rbox if in_region else box
                b.point(*pt(c.start_point))
                b.point(*pt(c.end_point))
                if in_region:
                    segments += 1
                else:
                    draws[code(c.aperture)] += 1
            elif cls is Arc2 or cls is CCArc2:
                b = rbox if in_region else box
                b.arc(*pt(c.start_point), *pt(c.end_point), *pt(c.center_point),
                      cls is Arc2)
                if in_region:
                    segments += 1
                else:
                    arcs[code(c.aperture)] += 1
            elif cls is Region2:
                regions += 1
                walk(c.command_buffer, True)
            elif cls is BufferCommand2:
                walk(c.command_buffer, in_region)
            else:
                raise TypeError(f"unexpected pygerber command {cls.__name__}")

    walk(buffer, False)
    return PeerSummary(dict(flashes), dict(draws), dict(arcs), box.result(),
                       region_count=regions, contour_count=None,
                       region_segments=segments, region_bbox_nm=rbox.result())


PEERS = {"gerbonara": gerbonara_summary, "pygerber": pygerber_summary}


# --------------------------------------------------------------------------- comparison

BBOX_TOLERANCE_NM = 1000


def differences(ours: PeerSummary, peer: PeerSummary) -> list[str]:
    """Every way `peer` disagrees with `ours`, one line each (empty: they agree).

    Fields a peer cannot know (None) are not compared.
    """
    out = []
    for name in ("flashes_by_aperture", "draws_by_aperture", "arcs_by_aperture"):
        a, b = getattr(ours, name), getattr(peer, name)
        for code in sorted(set(a) | set(b)):
            if a.get(code, 0) != b.get(code, 0):
                out.append(f"{name.split('_')[0]} D{code}: ours {a.get(code, 0)}, "
                           f"peer {b.get(code, 0)}")
    for name in ("bbox_nm", "region_bbox_nm"):
        a, b = getattr(ours, name), getattr(peer, name)
        if not bbox_close(a, b, BBOX_TOLERANCE_NM):
            out.append(f"{name}: ours {a}, peer {b}")
    for name in ("region_count", "contour_count", "region_segments"):
        a, b = getattr(ours, name), getattr(peer, name)
        if a is not None and b is not None and a != b:
            out.append(f"{name}: ours {a}, peer {b}")
    return out
