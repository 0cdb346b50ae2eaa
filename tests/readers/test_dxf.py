"""DXF reader: constructed drawings (written with ezdxf into tmp_path), one behaviour at
a time, and the DXF corpus (corpus.py) against ezdxf's own geometry (docs/dxf.md)."""

from __future__ import annotations

import csv
import math
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from corpus import DXF_CORPUS, DXF_CURATED, corpus_file

ezdxf = pytest.importorskip("ezdxf")
import ezdxf.bbox  # noqa: E402, F811
from ezdxf import recover  # noqa: E402

from galileo_cnc.errors import GalileoError  # noqa: E402
from galileo_cnc.program.extents import extents, start_points  # noqa: E402
from galileo_cnc.program.ops import I, J, KIND, LINE, NO_TOOL, X, Y, OpKind  # noqa: E402
from galileo_cnc.readers.dxf import DxfError, looks_like_dxf, read_dxf  # noqa: E402

K = OpKind
MM = 1_000_000
TOL = 5_000  # the reader's default tolerance, nm
CORPUS = DXF_CORPUS


# ---- helpers ----------------------------------------------------------------------

def new_doc(insunits: int | None = 4):
    doc = ezdxf.new("R2010")
    if insunits is None:
        del doc.header["$INSUNITS"]
    else:
        doc.header["$INSUNITS"] = insunits
    return doc


def save(doc, tmp_path: Path, name: str = "t.dxf", fmt: str = "asc") -> Path:
    path = tmp_path / name
    doc.saveas(path, fmt=fmt)
    return path


def rows(program) -> list[tuple]:
    """(kind, x, y, i, j) per row."""
    return [(K(r[0]), *r[1:5]) for r in program.table.tolist()]


def drawn(program) -> list[tuple]:
    return [r for r in rows(program) if r[0] in (K.LINE, K.ARC_CW, K.ARC_CCW)]


def nm(value: float, per_unit: int = MM) -> int:
    """Round half away from zero of the exact float * factor (the reader's rule)."""
    exact = Fraction(value) * per_unit
    whole = math.floor(abs(exact) + Fraction(1, 2))
    return whole if exact >= 0 else -whole


def drawn_length(program) -> float:
    """Total length of LINE and ARC rows in nm (arcs by their true sweep)."""
    table = program.table
    starts = start_points(table)
    total = 0.0
    for r, kind in enumerate(table[:, KIND].tolist()):
        sx, sy = starts[r]
        if kind == K.LINE:
            total += math.hypot(table[r, X] - sx, table[r, Y] - sy)
        elif kind in (K.ARC_CW, K.ARC_CCW):
            cx, cy = sx + table[r, I], sy + table[r, J]
            radius = math.hypot(table[r, I], table[r, J])
            a0 = math.atan2(sy - cy, sx - cx)
            a1 = math.atan2(table[r, Y] - cy, table[r, X] - cx)
            sweep = (a1 - a0) % math.tau
            if kind == K.ARC_CW:
                sweep = (math.tau - sweep) % math.tau
            total += radius * (sweep or math.tau)
    return total


# ---- mapping: lines, arcs, circles, bulges, points --------------------------------

def test_line_is_move_pen_down_line_in_exact_nm(tmp_path):
    doc = new_doc()
    doc.modelspace().add_line((0.1, 0.2), (1.5, -2.25))
    program = read_dxf(save(doc, tmp_path))
    assert program.format == "dxf" and program.units == "mm"
    assert rows(program) == [(K.MOVE, 100_000, 200_000, 0, 0), (K.PEN_DOWN, 0, 0, 0, 0),
                             (K.LINE, 1_500_000, -2_250_000, 0, 0)]
    assert program.table[2].tolist()[5] == NO_TOOL
    assert program.warnings == []


def test_each_coordinate_is_rounded_once_half_away_from_zero(tmp_path):
    doc = new_doc(12)  # nanometres: the float is the nm value
    doc.modelspace().add_line((2.5, -2.5), (0.5, -0.49999999999999994))
    program = read_dxf(save(doc, tmp_path))
    assert rows(program)[0][1:3] == (3, -3)
    assert rows(program)[2][1:3] == (1, 0)


def test_contiguous_entities_are_one_stroke_and_reversed_ones_join(tmp_path):
    doc = new_doc()
    msp = doc.modelspace()
    msp.add_line((0, 0), (10, 0))
    msp.add_line((10, 10), (10, 0))  # drawn backwards to continue the stroke
    msp.add_line((50, 50), (60, 50))  # elsewhere: pen up, travel
    kinds = [r[0] for r in rows(read_dxf(save(doc, tmp_path)))]
    assert kinds == [K.MOVE, K.PEN_DOWN, K.LINE, K.LINE, K.MOVE, K.PEN_DOWN, K.LINE]
    assert rows(read_dxf(save(doc, tmp_path)))[3][1:3] == (10 * MM, 10 * MM)


def test_arc_and_circle_are_native_arcs_with_centre_relative_to_start(tmp_path):
    doc = new_doc()
    msp = doc.modelspace()
    msp.add_arc((10, 0), 5, 0, 90)
    msp.add_circle((100, 100), 2.5)
    program = read_dxf(save(doc, tmp_path))
    assert drawn(program) == [
        (K.ARC_CCW, 10 * MM, 5 * MM, -5 * MM, 0),
        # a full circle: one arc whose end is its start
        (K.ARC_CCW, 102_500_000, 100 * MM, -2_500_000, 0),
    ]
    assert rows(program)[3] == (K.MOVE, 102_500_000, 100 * MM, 0, 0)


def test_bulge_polyline_gives_lines_and_arcs_with_the_bulge_direction(tmp_path):
    doc = new_doc()
    # bulge 1: half circle counter-clockwise; -0.5: clockwise, 4*atan(0.5) = 106.26 deg
    doc.modelspace().add_lwpolyline([(0, 0, 1), (10, 0, 0), (10, 10, -0.5), (0, 10, 0)],
                                    format="xyb", close=True)
    program = read_dxf(save(doc, tmp_path))
    got = drawn(program)
    assert [g[0] for g in got] == [K.ARC_CCW, K.LINE, K.ARC_CW, K.LINE]
    assert got[0] == (K.ARC_CCW, 10 * MM, 0, 5 * MM, 0)
    # bulge -0.5 from (10,10) to (0,10): the centre is (1-b^2)/(4b) = -0.375 chords along
    # the chord's left normal (0,-1), i.e. at (5, 13.75); clockwise, the minor arc dips
    # to (5, 7.5), inside the square
    assert got[2] == (K.ARC_CW, 0, 10 * MM, -5 * MM, 3_750_000)
    assert got[3] == (K.LINE, 0, 0, 0, 0)  # closed
    assert extents(program) == (0, -5 * MM, 10 * MM, 10 * MM)  # the half circle dips below


def test_polyline_2d_bulges_and_spline_frame_is_not_drawn(tmp_path):
    doc = new_doc()
    poly = doc.modelspace().add_polyline2d([(0, 0), (10, 0), (10, 10)])
    poly.vertices[0].dxf.bulge = 1.0
    program = read_dxf(save(doc, tmp_path))
    assert drawn(program) == [(K.ARC_CCW, 10 * MM, 0, 5 * MM, 0), (K.LINE, 10 * MM, 10 * MM, 0, 0)]


def test_points_only_with_points_true_as_a_zero_length_pen_down(tmp_path):
    doc = new_doc()
    doc.modelspace().add_point((3, 4))
    path = save(doc, tmp_path)
    quiet = read_dxf(path)
    assert len(quiet) == 0 and quiet.metadata["skipped"] == {"POINT": 1}
    assert any("POINT" in w.message and "points=True" in w.message for w in quiet.warnings)
    dots = read_dxf(path, points=True)
    assert rows(dots) == [(K.MOVE, 3 * MM, 4 * MM, 0, 0), (K.PEN_DOWN, 0, 0, 0, 0),
                          (K.LINE, 3 * MM, 4 * MM, 0, 0)]


def test_the_planner_draws_a_dxf_program(tmp_path):
    from galileo_cnc.job import ArcTo, LineTo, PenDown, Rapid
    from galileo_cnc.plan.planner import plan_program

    doc = new_doc()
    msp = doc.modelspace()
    msp.add_line((1, 1), (5, 1))
    msp.add_arc((5, 3), 2, 270, 90)
    msp.add_circle((20, 20), 3)
    msp.add_point((30, 30))
    job = plan_program(read_dxf(save(doc, tmp_path), points=True))
    kinds = [type(c).__name__ for c in job.commands]
    assert kinds[:5] == ["Rapid", "PenDown", "LineTo", "ArcTo", "Rapid"]
    assert kinds.count("PenDown") == 3  # the line+arc stroke, the circle, the dot
    circle = [c for c in job.commands if isinstance(c, ArcTo)][-1]
    assert circle.cw is False
    assert isinstance(job.commands[0], Rapid) and isinstance(job.commands[1], PenDown)
    assert any(isinstance(c, LineTo) for c in job.commands)


# ---- blocks -----------------------------------------------------------------------

def _virtual_reference(doc):
    """ezdxf's own expansion: (kind, start, end, centre, ccw) of each LINE/ARC in WCS."""
    out = []

    def walk(entities):
        for e in entities:
            if e.dxftype() == "INSERT":
                walk(e.multi_insert() if e.mcount > 1 else e.virtual_entities())
            elif e.dxftype() == "LINE":
                out.append(("LINE", tuple(e.dxf.start)[:2], tuple(e.dxf.end)[:2], None, None))
            elif e.dxftype() == "ARC":
                ocs = e.ocs()
                centre = ocs.to_wcs(e.dxf.center)
                ccw = e.dxf.extrusion.z > 0
                start, end = e.start_point, e.end_point
                out.append(("ARC", (start.x, start.y), (end.x, end.y), (centre.x, centre.y), ccw))

    walk(doc.modelspace())
    return out


def _as_rows(program):
    """The same tuples from the program, in nm."""
    table = program.table
    starts = start_points(table)
    out = []
    for r, kind in enumerate(table[:, KIND].tolist()):
        if kind == K.LINE:
            out.append(("LINE", tuple(starts[r]), (table[r, X], table[r, Y]), None, None))
        elif kind in (K.ARC_CW, K.ARC_CCW):
            sx, sy = starts[r]
            out.append(("ARC", (sx, sy), (table[r, X], table[r, Y]),
                        (sx + table[r, I], sy + table[r, J]), kind == K.ARC_CCW))
    return out


def _canonical(segment):
    """A segment with its ends in a fixed order (a reversed arc turns the other way)."""
    kind, start, end, centre, ccw = segment
    key = lambda p: (round(float(p[0]) / 10_000), round(float(p[1]) / 10_000))  # noqa: E731
    if key(end) < key(start):
        start, end, ccw = end, start, (None if ccw is None else not ccw)
    return kind, start, end, centre, ccw


def _same_as_ezdxf(program, doc):
    """Every LINE/ARC of ezdxf's expansion is drawn, within 2 nm, in one direction or the
    other (the reader draws a path backwards to continue a stroke)."""
    scaled = [(k, tuple(v * MM for v in s), tuple(v * MM for v in e),
               None if c is None else tuple(v * MM for v in c), ccw)
              for k, s, e, c, ccw in _virtual_reference(doc)]
    key = lambda seg: (seg[0], round(float(seg[1][0]) / 10_000), round(float(seg[1][1]) / 10_000))  # noqa: E731
    mine = sorted((_canonical(s) for s in _as_rows(program)), key=key)
    theirs = sorted((_canonical(s) for s in scaled), key=key)
    assert len(mine) == len(theirs)
    for got, want in zip(mine, theirs):
        assert got[0] == want[0] and got[4] == want[4], (got, want)
        for a, b in ((got[1], want[1]), (got[2], want[2]), (got[3], want[3])):
            assert a is None and b is None or max(abs(p - q) for p, q in zip(a, b)) <= 2, \
                (got, want)


def test_mirrored_insert_keeps_the_arc_on_its_path_and_turns_it_clockwise(tmp_path):
    doc = new_doc()
    block = doc.blocks.new("B")
    block.add_arc((10, 0), 5, 0, 90)
    doc.modelspace().add_blockref("B", (0, 0), dxfattribs={"xscale": -1})
    program = read_dxf(save(doc, tmp_path))
    # (15,0)..(10,5) about (10,0) counter-clockwise, mirrored: (-15,0)..(-10,5) clockwise
    assert rows(program)[0] == (K.MOVE, -15 * MM, 0, 0, 0)
    assert drawn(program) == [(K.ARC_CW, -10 * MM, 5 * MM, 5 * MM, 0)]
    _same_as_ezdxf(program, doc)


def test_arc_with_negative_extrusion_is_mirrored_not_reversed(tmp_path):
    doc = new_doc()
    # OCS with extrusion (0,0,-1): x is -X. Centre (10,0) is WCS (-10,0), angle 0 is WCS 180.
    doc.modelspace().add_arc((10, 0), 5, 0, 90, dxfattribs={"extrusion": (0, 0, -1)})
    program = read_dxf(save(doc, tmp_path))
    assert rows(program)[0] == (K.MOVE, -15 * MM, 0, 0, 0)
    assert drawn(program) == [(K.ARC_CW, -10 * MM, 5 * MM, 5 * MM, 0)]
    _same_as_ezdxf(program, doc)


def test_nested_blocks_with_scale_and_rotation(tmp_path):
    doc = new_doc()
    inner = doc.blocks.new("INNER")
    inner.add_line((0, 0), (1, 0))
    inner.add_arc((0, 0), 1, 0, 90)
    outer = doc.blocks.new("OUTER", base_point=(0.5, 0))
    outer.add_blockref("INNER", (1, 0), dxfattribs={"xscale": 2, "yscale": 2, "rotation": 90})
    doc.modelspace().add_blockref("OUTER", (10, 10), dxfattribs={
        "xscale": 3, "yscale": 3, "rotation": 90})
    program = read_dxf(save(doc, tmp_path))
    _same_as_ezdxf(program, doc)
    # by hand: inner line (0,0)-(1,0) -> x2, 90 deg, +(1,0) -> (1,0)-(1,2); - base (0.5,0)
    # -> (0.5,0)-(0.5,2); x3, 90 deg -> (0,1.5)-(-6,1.5); +(10,10) -> (10,11.5)-(4,11.5)
    assert _as_rows(program)[0][1:3] == ((10 * MM, 11_500_000), (4 * MM, 11_500_000))


def test_mirrored_nested_and_negative_extrusion_insert(tmp_path):
    doc = new_doc()
    inner = doc.blocks.new("INNER")
    inner.add_arc((2, 1), 1.5, 30, 250)
    inner.add_lwpolyline([(0, 0, 0.4), (3, 0, -0.7), (3, 3, 0)], format="xyb")
    outer = doc.blocks.new("OUTER")
    outer.add_blockref("INNER", (1, 2), dxfattribs={"xscale": -1.5, "yscale": 1.5,
                                                     "rotation": 30})
    doc.modelspace().add_blockref("OUTER", (5, 5), dxfattribs={
        "xscale": 2, "yscale": -2, "rotation": -60, "extrusion": (0, 0, -1)})
    program = read_dxf(save(doc, tmp_path))
    # ezdxf explodes the polyline into LINE/ARC virtual entities the same way
    ref = ezdxf.new("R2010")
    copy = []

    def walk(entities):
        for e in entities:
            if e.dxftype() == "INSERT":
                walk(e.virtual_entities())
            elif e.dxftype() == "LWPOLYLINE":
                walk(e.virtual_entities())
            else:
                copy.append(e)

    walk(doc.modelspace())
    for e in copy:
        ref.modelspace().add_foreign_entity(e)
    _same_as_ezdxf(program, ref)


def test_minsert_draws_every_cell(tmp_path):
    doc = new_doc()
    doc.blocks.new("C").add_circle((0, 0), 1)
    ref = doc.modelspace().add_blockref("C", (0, 0))
    ref.grid(size=(2, 3), spacing=(10, 20))  # 2 rows, 3 columns
    program = read_dxf(save(doc, tmp_path))
    moves = sorted(r[1:3] for r in rows(program) if r[0] == K.MOVE)
    assert moves == sorted((MM + 20 * MM * c, 10 * MM * r) for r in range(2) for c in range(3))


def _segments_distance(points, a, b):
    """Distance of each point to the nearest of the segments a[k]-b[k] (arrays (n, 2))."""
    best = np.full(len(points), np.inf)
    d = b - a
    length2 = np.maximum((d * d).sum(1), 1e-300)
    step = 500
    for start in range(0, len(a), step):
        aa, dd, ll = a[start:start + step], d[start:start + step], length2[start:start + step]
        rel = points[:, None, :] - aa[None, :, :]
        t = np.clip((rel * dd[None]).sum(2) / ll[None], 0, 1)
        gap = rel - t[..., None] * dd[None]
        best = np.minimum(best, np.sqrt((gap * gap).sum(2)).min(1))
    return best


def _drawing_distance(points, program):
    """Distance of each point to the drawn rows: lines exactly, arcs by their circle where
    the point's angle is within the sweep, else the nearer end."""
    table = program.table
    starts = start_points(table)
    best = np.full(len(points), np.inf)
    for r, kind in enumerate(table[:, KIND].tolist()):
        sx, sy = starts[r]
        ex, ey = table[r, X], table[r, Y]
        if kind == K.LINE:
            best = np.minimum(best, _segments_distance(points, np.array([[sx, sy]], float),
                                                       np.array([[ex, ey]], float)))
        elif kind in (K.ARC_CW, K.ARC_CCW):
            cx, cy = sx + table[r, I], sy + table[r, J]
            radius = math.hypot(table[r, I], table[r, J])
            a0 = math.atan2(sy - cy, sx - cx)
            sweep = (math.atan2(ey - cy, ex - cx) - a0) % math.tau or math.tau
            angles = np.arctan2(points[:, 1] - cy, points[:, 0] - cx)
            if kind == K.ARC_CCW:
                inside = (angles - a0) % math.tau <= sweep
            else:
                inside = (a0 - angles) % math.tau <= math.tau - sweep
            to_circle = np.abs(np.hypot(points[:, 0] - cx, points[:, 1] - cy) - radius)
            to_ends = np.minimum(np.hypot(points[:, 0] - sx, points[:, 1] - sy),
                                 np.hypot(points[:, 0] - ex, points[:, 1] - ey))
            best = np.minimum(best, np.where(inside, to_circle, to_ends))
    return best


def _within_tolerance_of(program, curve_nm, tol_nm):
    """The drawing and the curve (an (n, 2) polyline in nm, dense) are within tol of each
    other both ways: the curve's points from the drawing, the drawing's from the curve."""
    assert _drawing_distance(curve_nm, program).max() <= tol_nm + 1000
    ends = program.table[np.isin(program.table[:, KIND], [K.LINE, K.ARC_CW, K.ARC_CCW])][:, [X, Y]]
    middles = _dense(program)
    for points in (ends.astype(float), middles):
        assert _segments_distance(points, curve_nm[:-1], curve_nm[1:]).max() <= tol_nm + 1000


def _ellipse_nm(a, b, angle, samples=4000):
    t = np.linspace(0, math.tau, samples)
    x, y = a * np.cos(t), b * np.sin(t)
    return np.stack([x * math.cos(angle) - y * math.sin(angle),
                     x * math.sin(angle) + y * math.cos(angle)], 1) * MM


def test_non_uniform_scale_turns_a_circle_into_fitted_arcs_within_tolerance(tmp_path):
    doc = new_doc()
    doc.blocks.new("C").add_circle((0, 0), 10)
    doc.modelspace().add_blockref("C", (0, 0), dxfattribs={"xscale": 2, "yscale": 1})
    program = read_dxf(save(doc, tmp_path))
    _within_tolerance_of(program, _ellipse_nm(20, 10, 0.0), TOL)
    assert len(drawn(program)) < 40  # arcs, not hundreds of short lines


def test_ellipse_and_spline_are_fitted_within_the_tolerance(tmp_path):
    doc = new_doc()
    msp = doc.modelspace()
    msp.add_ellipse((0, 0), major_axis=(30, 10), ratio=0.4)
    program = read_dxf(save(doc, tmp_path))
    a = math.hypot(30, 10)
    ellipse = _ellipse_nm(a, 0.4 * a, math.atan2(10, 30))
    _within_tolerance_of(program, ellipse, TOL)
    coarse = read_dxf(save(doc, tmp_path), tolerance_nm=50_000)
    assert len(coarse) < len(program)
    _within_tolerance_of(coarse, ellipse, 50_000)


def test_spline_follows_ezdxf_evaluation(tmp_path):
    doc = new_doc()
    spline = doc.modelspace().add_spline(degree=3)
    spline.control_points = [(0, 0), (10, 30), (40, -20), (60, 10), (80, 0)]
    spline.knots = [0, 0, 0, 0, 0.5, 1, 1, 1, 1]
    program = read_dxf(save(doc, tmp_path))
    curve = spline.construction_tool()
    reference = np.array([(p.x, p.y) for p in curve.points(np.linspace(0, 1, 4000))]) * MM
    _within_tolerance_of(program, reference, TOL)
    assert drawn(program)[-1][1:3] == (80 * MM, 0)


def _dense(program):
    table = program.table
    starts = start_points(table)
    pts = []
    for r, kind in enumerate(table[:, KIND].tolist()):
        sx, sy = starts[r]
        if kind == K.LINE:
            pts += [(sx + (table[r, X] - sx) * f, sy + (table[r, Y] - sy) * f)
                    for f in np.linspace(0, 1, 30)]
        elif kind in (K.ARC_CW, K.ARC_CCW):
            cx, cy = sx + table[r, I], sy + table[r, J]
            radius = math.hypot(table[r, I], table[r, J])
            a0 = math.atan2(sy - cy, sx - cx)
            a1 = math.atan2(table[r, Y] - cy, table[r, X] - cx)
            sweep = (a1 - a0) % math.tau or math.tau
            if kind == K.ARC_CW:
                sweep -= math.tau
            pts += [(cx + radius * math.cos(a0 + sweep * f), cy + radius * math.sin(a0 + sweep * f))
                    for f in np.linspace(0, 1, 100)]
    return np.array(pts)


# ---- units, layers, skipped kinds, positions --------------------------------------

def test_inch_file_gives_25_4_mm_exactly(tmp_path):
    doc = new_doc(1)
    doc.modelspace().add_line((0, 0), (1, 0.1))
    program = read_dxf(save(doc, tmp_path))
    assert program.units == "in" and program.metadata["units"] == "in"
    assert drawn(program) == [(K.LINE, 25_400_000, 2_540_000, 0, 0)]
    assert program.warnings == []


@pytest.mark.parametrize("code, per_unit", [(4, MM), (5, 10 * MM), (6, 1000 * MM), (13, 1000),
                                            (2, 304_800_000), (9, 25_400)])
def test_insunits_factors_are_exact(tmp_path, code, per_unit):
    doc = new_doc(code)
    doc.modelspace().add_line((0, 0), (3, 0.25))
    program = read_dxf(save(doc, tmp_path))
    assert drawn(program) == [(K.LINE, 3 * per_unit, per_unit // 4, 0, 0)]


def test_a_file_without_insunits_is_read_as_mm_with_a_warning(tmp_path):
    doc = new_doc(None)
    doc.modelspace().add_line((0, 0), (1, 0))
    path = save(doc, tmp_path)
    program = read_dxf(path)
    assert drawn(program) == [(K.LINE, MM, 0, 0, 0)]
    assert [w.message for w in program.warnings if "INSUNITS" in w.message]
    assert program.metadata["insunits"] is None
    inches = read_dxf(path, units="in")
    assert drawn(inches) == [(K.LINE, 25_400_000, 0, 0, 0)] and inches.warnings == []
    assert drawn(read_dxf(save(new_doc(1), tmp_path, "i.dxf"), units="mm")) == []
    with pytest.raises(DxfError, match="unknown unit"):
        read_dxf(path, units="furlong")


# A 40 x 25 mm rectangle as four LINEs, the way OpenSCAD exports a part: no HEADER, so
# no $INSUNITS. ezdxf gives such a file its default header ($INSUNITS 6, metres).
PART_LINES = [((0, 0), (40, 0)), ((40, 0), (40, 25)), ((40, 25), (0, 25)), ((0, 25), (0, 0))]


def headerless_ascii(path: Path) -> Path:
    pairs = [(999, "DXF from OpenSCAD"), (0, "SECTION"), (2, "ENTITIES")]
    for (x0, y0), (x1, y1) in PART_LINES:
        pairs += [(0, "LINE"), (8, "0"), (10, x0), (20, y0), (11, x1), (21, y1)]
    pairs += [(0, "ENDSEC"), (0, "EOF")]
    path.write_text("".join(f"{code}\n{value}\n" for code, value in pairs))
    return path


def headerless_binary_r12(path: Path) -> Path:
    """The same part as a binary R12 DXF (one-byte group codes) with only ENTITIES."""
    import struct

    def tag(code, value):
        if isinstance(value, str):
            return bytes([code]) + value.encode("ascii") + b"\0"
        return bytes([code]) + struct.pack("<d", value)

    data = b"AutoCAD Binary DXF\r\n\x1a\x00" + tag(0, "SECTION") + tag(2, "ENTITIES")
    for (x0, y0), (x1, y1) in PART_LINES:
        data += tag(0, "LINE") + tag(8, "0") + tag(10, float(x0)) + tag(20, float(y0)) \
            + tag(11, float(x1)) + tag(21, float(y1))
    path.write_bytes(data + tag(0, "ENDSEC") + tag(0, "EOF"))
    return path


@pytest.mark.parametrize("make", [headerless_ascii, headerless_binary_r12])
def test_a_headerless_drawing_is_millimetres_with_a_warning_not_metres(tmp_path, make):
    program = read_dxf(make(tmp_path / "part.dxf"))
    assert extents(program) == (0, 0, 40 * MM, 25 * MM)  # 40 mm wide, not 40 m
    assert program.metadata["insunits"] is None and program.metadata["units"] == "mm"
    assert program.metadata["binary"] is (make is headerless_binary_r12)
    assert program.metadata["layers"] == {"0": 4}  # not ezdxf's default table's Defpoints
    assert [w.message for w in program.warnings] == [
        "the drawing has no $INSUNITS: read as millimetres (--units in reads it as inches)"]
    # about the whole file: named without a line and column that do not exist
    assert str(program.warnings[0]).startswith(f"{program.source}: warning: the drawing")


@pytest.mark.parametrize("version, fmt", [("R12", "asc"), ("R12", "bin"), ("R2000", "asc"),
                                          ("R2000", "bin")])
def test_every_version_and_encoding_keeps_its_units(tmp_path, version, fmt):
    """ezdxf writes no $INSUNITS into R12 files (mm with a warning); R2000+ keep theirs."""
    doc = ezdxf.new(version)
    doc.units = 1  # inches
    doc.modelspace().add_line((0, 0), (2, 0))
    program = read_dxf(save(doc, tmp_path, fmt=fmt))
    r12 = version == "R12"
    assert drawn(program) == [(K.LINE, 2 * (MM if r12 else 25_400_000), 0, 0, 0)]
    assert any("no $INSUNITS" in w.message for w in program.warnings) is r12


def test_units_override_beats_the_header(tmp_path):
    doc = new_doc(1)
    doc.modelspace().add_line((0, 0), (2, 0))
    assert drawn(read_dxf(save(doc, tmp_path), units="mm")) == [(K.LINE, 2 * MM, 0, 0, 0)]


def test_layer_selection_and_counts(tmp_path):
    doc = new_doc()
    doc.layers.add("Outline")
    doc.layers.add("Holes")
    msp = doc.modelspace()
    msp.add_line((0, 0), (1, 0), dxfattribs={"layer": "Outline"})
    msp.add_circle((5, 5), 1, dxfattribs={"layer": "Holes"})
    msp.add_circle((9, 9), 1, dxfattribs={"layer": "Holes"})
    block = doc.blocks.new("B")
    block.add_line((0, 0), (0, 1))  # on layer 0: takes the INSERT's layer
    msp.add_blockref("B", (20, 0), dxfattribs={"layer": "Outline"})
    path = save(doc, tmp_path)
    everything = read_dxf(path)
    assert everything.metadata["layers"]["Outline"] == 2
    assert everything.metadata["layers"]["Holes"] == 2
    assert everything.metadata["layers"]["0"] == 0
    outline = read_dxf(path, layers=["outline"])  # case-insensitive, as in CAD
    assert [r[0] for r in drawn(outline)] == [K.LINE, K.LINE]
    holes = read_dxf(path, layers="Holes")
    assert [r[0] for r in drawn(holes)] == [K.ARC_CCW, K.ARC_CCW]
    with pytest.raises(DxfError) as info:
        read_dxf(path, layers=["Outline", "Silk"])
    assert "'Silk'" in info.value.message and "Holes, Outline" in info.value.message


def test_skipped_kinds_warn_once_each_and_are_counted(tmp_path):
    doc = new_doc()
    msp = doc.modelspace()
    for k in range(3):
        msp.add_text(f"label {k}", dxfattribs={"insert": (k, 0)})
    msp.add_mtext("notes")
    msp.add_solid([(0, 0), (1, 0), (0, 1)])
    msp.add_line((0, 0), (1, 1))
    program = read_dxf(save(doc, tmp_path))
    assert program.metadata["skipped"] == {"TEXT": 3, "MTEXT": 1, "SOLID": 1}
    text = [w for w in program.warnings if "TEXT" in w.message and "MTEXT" not in w.message]
    assert len(text) == 1 and text[0].message.startswith("3 TEXT entities")
    assert text[0].pos.line > 0
    assert len([w for w in program.warnings if "SOLID" in w.message]) == 1
    assert program.metadata["entities"] == {"LINE": 1}


def test_rows_carry_the_line_of_their_entity_and_vertex(tmp_path):
    doc = new_doc()
    msp = doc.modelspace()
    line = msp.add_line((0, 0), (1, 0))
    poly = msp.add_lwpolyline([(5, 5), (6, 5), (6, 6)])
    path = save(doc, tmp_path)
    text = path.read_text().splitlines()
    program = read_dxf(path)
    lines = program.table[:, LINE].tolist()

    def code_line_of(handle):  # the line of the entity's "0" group code
        index = next(i for i in range(len(text) - 1)
                     if text[i].strip() == "5" and text[i + 1].strip() == handle)
        while text[index].strip() != "0":
            index -= 2
        return index + 1

    assert lines[:3] == [code_line_of(line.dxf.handle)] * 3
    start = code_line_of(poly.dxf.handle)
    vertex_lines = [start + 1 + i for i in range(start, len(text)) if False]  # noqa: F841
    tens = [i + 1 for i in range(start, len(text) - 1) if text[i].strip() == "10"][:3]
    assert lines[3:] == [tens[0], tens[0], tens[1], tens[2]]
    assert program.metadata["handles"][0] == line.dxf.handle.upper()


def test_binary_dxf_reads_the_same_rows_and_maps_handles(tmp_path):
    doc = new_doc()
    msp = doc.modelspace()
    msp.add_line((0, 0), (1, 0))
    msp.add_arc((5, 5), 2, 10, 200)
    ascii_program = read_dxf(save(doc, tmp_path))
    binary = read_dxf(save(doc, tmp_path, "b.dxf", fmt="bin"))
    assert binary.metadata["binary"] is True
    assert rows(binary) == rows(ascii_program)
    assert set(binary.table[:, LINE].tolist()) == {0}
    assert sorted(binary.metadata["handles"].values()) == sorted(
        ascii_program.metadata["handles"].values())


# ---- bad input --------------------------------------------------------------------

def test_bad_input_is_a_positioned_dxf_error(tmp_path):
    good = new_doc()
    good.modelspace().add_line((0, 0), (1, 0))
    text = save(good, tmp_path).read_text()
    lines = text.splitlines()
    where = lines.index("LINE") + 1
    cases = {
        "code": (lines[:where + 2] + ["1O"] + lines[where + 3:], where + 3),
        "comma": ([*lines[:where], *[("1,5" if i == where + 13 else v)
                                      for i, v in enumerate(lines[where:], where)]], None),
        "truncated": (lines[:where + 6], None),
    }
    for name, (content, line) in cases.items():
        path = tmp_path / f"{name}.dxf"
        path.write_text("\n".join(content) + "\n")
        with pytest.raises(DxfError) as info:
            read_dxf(path)
        assert info.value.pos.line >= 1 and info.value.pos.file == str(path), name
        if line is not None:
            assert info.value.pos.line == line, (name, info.value)
    with pytest.raises(DxfError) as info:
        read_dxf(tmp_path / "missing.dxf")
    assert "cannot read" in info.value.message
    assert issubclass(DxfError, GalileoError)


def test_garbage_never_escapes_as_anything_but_dxf_error(tmp_path):
    head, tail = b"  0\nSECTION\n  2\nENTITIES\n", b"  0\nENDSEC\n  0\nEOF\n"
    samples = [b"", b"0\n", b"0\nSECTION\n", b"\x00\x01\x02garbage",
               b"AutoCAD Binary DXF\r\n\x1a\x00",
               head + b"  0\nLINE\n 10\nnan\n 20\n0\n 11\n1\n 21\n1\n" + tail,
               head + b"  0\nARC\n 10\n0\n 20\n0\n 40\n-1\n 50\n0\n 51\n90\n" + tail,
               head + b"  0\nLINE\n 10\n1e300\n 20\n0\n 11\n1\n 21\n1\n" + tail]
    for k, data in enumerate(samples):
        path = tmp_path / f"g{k}.dxf"
        path.write_bytes(data)
        try:
            read_dxf(path)
        except DxfError:
            pass


def test_sniffing():
    assert looks_like_dxf("999\ncomment\n  0\nSECTION\n  2\nHEADER\n")
    assert looks_like_dxf("0\r\nSECTION\r\n2\r\nENTITIES\r\n")
    assert looks_like_dxf("AutoCAD Binary DXF\r\n\x1a\x00")
    assert not looks_like_dxf("G21\nG0 X1 Y1\n")
    assert not looks_like_dxf("%FSLAX26Y26*%\n%MOMM*%\n")
    assert not looks_like_dxf("")


# ---- the corpus -------------------------------------------------------------------

def _corpus_rows() -> list[dict]:
    manifest = CORPUS / "MANIFEST.tsv"
    if not manifest.exists():
        pytest.skip(f"DXF corpus not found at {CORPUS}")
    with open(manifest, newline="") as handle:
        return list(csv.DictReader(handle, delimiter="\t"))


def _corpus(kind: str) -> list[str]:
    manifest = CORPUS / "MANIFEST.tsv"
    if not manifest.exists():
        return ["(missing corpus)"]
    with open(manifest, newline="") as handle:
        return [row["path"] for row in csv.DictReader(handle, delimiter="\t")
                if (row["kind"] == "invalid") == (kind == "invalid")]


_READ: dict[str, object] = {}
#: the drawing ezdxf parsed for the reader, until the comparison with ezdxf's own
#: geometry takes it: each corpus file is parsed once (the parse is most of the time)
_PARSED: dict[str, object] = {}


def _read(relative: str):
    if relative not in _READ:
        from galileo_cnc.readers.dxf import load as dxf_load

        def keep(path):
            parsed = dxf_load_file(path)
            _PARSED[relative] = parsed[0]
            return parsed

        dxf_load_file = dxf_load.load
        dxf_load.load = keep
        try:
            _READ[relative] = read_dxf(corpus_file(relative, CORPUS))
        finally:
            dxf_load.load = dxf_load_file
    return _READ[relative]


# Where each invalid file breaks (the line the error names).
INVALID_LINES = {
    "invalid/bad-group-code-voron-250_Back_Panel.DXF": 273,  # '1O' for the group code 10
    "invalid/ezdxf-recover01.dxf": 1161,  # a second ENTITIES section
    "invalid/openscad-nothing-decimal-comma-separated.dxf": 10,  # '-6,63671875'
    "invalid/truncated-librecad-gear.dxf": 10763,  # the last, cut line
    "invalid/truncated-binary-ezdxf-bin_dxf_r12.dxf": 1,  # binary: the byte in the message
}


@pytest.mark.parametrize("relative", _corpus("invalid"))
def test_invalid_corpus_files_raise_a_positioned_dxf_error(relative):
    _corpus_rows()
    with pytest.raises(DxfError) as info:
        read_dxf(CORPUS / relative)
    assert info.value.pos.line >= 1
    assert info.value.pos.line == INVALID_LINES.get(relative, info.value.pos.line), info.value
    if "binary" in relative:
        assert "byte" in info.value.message


CURVES = {"ARC", "CIRCLE", "ELLIPSE", "SPLINE", "HELIX"}


def _primitives(entities):
    """ezdxf's own expansion: INSERT (MINSERT) and polylines through virtual_entities,
    down to LINE and curve entities; spline frame vertices dropped as the reader does."""
    for e in entities:
        dxftype = e.dxftype()
        try:
            if e.dxf.get("invisible", 0):
                continue
        except Exception:
            continue
        if dxftype == "INSERT":
            yield from _primitives(e.multi_insert() if e.mcount > 1 else e.virtual_entities())
        elif dxftype == "LWPOLYLINE" or (dxftype == "POLYLINE" and not (
                e.is_poly_face_mesh or e.is_polygon_mesh)):
            if dxftype == "POLYLINE":
                e.vertices[:] = [v for v in e.vertices if not v.dxf.flags & 16]
            yield from _primitives(e.virtual_entities())
        elif dxftype == "LINE" or dxftype in CURVES:
            yield e


def _reference(path: Path, per_unit: float, doc=None):
    """Extents (nm) and length (nm) of the drawing by ezdxf: lines exact, arcs and
    ellipses by their flattening (50 nm sagitta), splines by their evaluation over the
    spline's domain; None if ezdxf cannot expand or evaluate some entity. `doc`: the
    file as ezdxf parsed it (readfile, else recover mode), if it is at hand."""
    if doc is None:
        try:
            doc = ezdxf.readfile(path)
        except Exception:
            doc, _ = recover.readfile(path)
    for e in doc.entitydb.values():
        if e.dxftype() == "INSERT" and e.dxf.get("zscale", 1) == 0:
            e.dxf.zscale = 1  # ezdxf cannot expand a flat INSERT; z does not matter here
    sagitta = 50 / per_unit
    total, points = 0.0, []
    try:
        for e in _primitives(doc.modelspace()):
            dxftype = e.dxftype()
            if dxftype == "LINE":
                vertices = [e.dxf.start, e.dxf.end]
            elif dxftype in ("ARC", "CIRCLE"):
                vertices = list(e.flattening(sagitta))
            elif dxftype == "ELLIPSE":
                vertices = list(e.flattening(sagitta, segments=8))
            else:
                curve = e.construction_tool()
                vertices = list(curve.points(curve.params(2000)))
            xy = np.array([(v.x, v.y) for v in vertices])
            total += float(np.hypot(*np.diff(xy, axis=0).T).sum())
            points.append(xy)
    except Exception:
        return None
    if not points:
        return (None, 0.0)
    allxy = np.concatenate(points) * per_unit
    return (tuple(allxy.min(0)) + tuple(allxy.max(0)), total * per_unit)


def test_every_corpus_file_reads_and_agrees_with_ezdxf():
    """All real files read; extents within 1 um + the tolerance of ezdxf's, and the drawn
    length within (1 um + tolerance) per drawn path (docs/dxf.md has the figures)."""
    entries = _corpus_rows()
    compared = 0
    worst_box = worst_length = 0.0
    for row in entries:
        if row["kind"] == "invalid":
            continue
        program = _read(row["path"])
        assert program.format == "dxf"
        if not program.metadata["binary"]:  # every row names its line
            assert (program.table[:, LINE] > 0).all(), row["path"]
        per_unit = float(Fraction(program.metadata["nm_per_unit"]))
        reference = _reference(CORPUS / row["path"], per_unit, _PARSED.pop(row["path"], None))
        if reference is None:  # ezdxf cannot expand or evaluate it (see docs/dxf.md)
            assert row["path"] in ("autocad/cadquery-rational_spline.dxf",
                                   "librecad/librecad-Complete-Lib-E.dxf"), row["path"]
            continue
        box, length = reference
        mine = extents(program)
        if box is None:
            assert mine is None, row["path"]
            continue
        off = max(abs(mine[k] - box[k]) for k in range(4))
        assert off <= 1000 + TOL, (row["path"], off)
        paths = max(program.metadata["paths"], 1)
        length_off = abs(drawn_length(program) - length)
        assert length_off <= (1000 + TOL) * paths, (row["path"], length_off)
        compared += 1
        worst_box = max(worst_box, off)
        worst_length = max(worst_length, length_off / paths)
    assert compared >= (49 if DXF_CURATED else 60)  # of 52 curated, 67 in the full corpus


def test_corpus_details():
    _corpus_rows()
    # recover mode: read, with a warning that says so
    tux = _read("dxflib2/librecad-tux.dxf")
    assert any("recover" in w.message for w in tux.warnings)
    assert tux.metadata["recovered"] is True
    old = _read("autocad/ezdxf-AC1003_LINE_Example.dxf")
    assert old.metadata["entities"] == {"LINE": 13, "ARC": 9}
    # a closed periodic spline ezdxf cannot build: drawn as a closed curve
    periodic = _read("autocad/cadquery-rational_spline.dxf")
    assert periodic.metadata["entities"] == {"SPLINE": 1}
    table = periodic.table
    assert table[0, KIND] == K.MOVE and tuple(table[-1, [X, Y]]) == tuple(table[0, [X, Y]])
    # the synthetic feature file: inch, blocks, MINSERT, mirrored arcs
    features = _read("synthetic/ezdxf-features-r2010-inch.dxf")
    assert features.units == "in" and features.metadata["skipped"] == {"HATCH": 1, "TEXT": 1}
    # binary files: no lines, handles instead
    binary = _read("binary/netdxf-sample-binary.dxf")
    assert set(binary.table[:, LINE].tolist()) == {0} and binary.metadata["handles"]
    assert rows(binary) == rows(_read("netdxf/netdxf-sample.dxf"))


def test_every_corpus_flavour_reads_in_the_units_its_file_names():
    """Headerless, binary, R12 and R2000+ files: the unit is the file's own $INSUNITS
    (the manifest's column); none, 0 (unitless) or a code that is no length is mm with a
    warning, never the metres of ezdxf's default header."""
    from galileo_cnc.readers.dxf.units import INSUNITS

    flavours = set()
    for row in _corpus_rows():
        if row["kind"] == "invalid":
            continue
        program = _read(row["path"])
        version = row["dxf_version"]
        flavours.add("headerless" if version == "none" else "R12-" if version <= "AC1009"
                     else "R2000+")
        if program.metadata["binary"]:
            flavours.add("binary")
        warned = [w for w in program.warnings if "$INSUNITS" in w.message]
        code = None if row["insunits"] == "none" else int(row["insunits"])
        if code in INSUNITS:
            assert program.metadata["insunits"] == code, row["path"]
            assert Fraction(program.metadata["nm_per_unit"]) == INSUNITS[code][1], row["path"]
            assert not warned, row["path"]
        else:
            assert program.metadata["nm_per_unit"] == str(MM), row["path"]
            assert len(warned) == 1 and "read as millimetres" in warned[0].message, row["path"]
    assert flavours == {"headerless", "binary", "R12-", "R2000+"}


def test_no_other_reader_claims_a_dxf_file_and_every_dxf_file_sniffs():
    from galileo_cnc.readers.gcode import looks_like_gcode
    from galileo_cnc.readers.gerber import looks_like_gerber

    for row in _corpus_rows():
        text = (CORPUS / row["path"]).read_bytes().decode("utf-8", errors="replace")
        assert not looks_like_gcode(text) and not looks_like_gerber(text), row["path"]
        assert looks_like_dxf(text), row["path"]


def survey() -> None:
    """The figures in docs/dxf.md: `python3 tests/readers/test_dxf.py`."""
    import time

    entries = _corpus_rows()
    read = failed = compared = 0
    worst_box = worst_length = worst_ezdxf_box = 0.0
    seconds = 0.0
    for row in entries:
        path = CORPUS / row["path"]
        started = time.perf_counter()
        try:
            program = read_dxf(path)
        except DxfError as problem:
            seconds += time.perf_counter() - started
            failed += 1
            print(f"{row['path']}: DxfError {problem.pos}: {problem.message[:70]}")
            continue
        took = time.perf_counter() - started
        seconds += took
        read += 1
        per_unit = float(Fraction(program.metadata["nm_per_unit"]))
        reference = _reference(path, per_unit)
        mine = extents(program)
        line = (f"{row['path']}: {took * 1000:.0f} ms, {len(program)} rows, "
                f"{program.metadata['paths']} paths")
        if reference is None or reference[0] is None:
            print(line + ", no ezdxf reference")
            continue
        box, length = reference
        off = max(abs(mine[k] - box[k]) for k in range(4))
        per_path = abs(drawn_length(program) - length) / max(program.metadata["paths"], 1)
        try:
            doc = ezdxf.readfile(path)
        except Exception:
            doc, _ = recover.readfile(path)
        for e in doc.entitydb.values():
            if e.dxftype() == "INSERT" and e.dxf.get("zscale", 1) == 0:
                e.dxf.zscale = 1
        try:
            bb = ezdxf.bbox.extents(list(_primitives(doc.modelspace())), fast=False)
            ez = (bb.extmin.x, bb.extmin.y, bb.extmax.x, bb.extmax.y)
            ez_off = max(abs(mine[k] - ez[k] * per_unit) for k in range(4))
        except Exception:
            ez_off = float("nan")
        compared += 1
        worst_box, worst_length = max(worst_box, off), max(worst_length, per_path)
        worst_ezdxf_box = max(worst_ezdxf_box, ez_off) if ez_off == ez_off else worst_ezdxf_box
        print(f"{line}, extents off {off:.0f} nm (ezdxf.bbox {ez_off:.0f} nm), "
              f"length off {per_path:.0f} nm per path")
    print(f"\n{read} files read, {failed} refused, {compared} compared; worst extents "
          f"{worst_box:.0f} nm (ezdxf.bbox: {worst_ezdxf_box:.0f} nm), worst length "
          f"{worst_length:.0f} nm per path; reading took {seconds:.2f} s")


if __name__ == "__main__":
    survey()
