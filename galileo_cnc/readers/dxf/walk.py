"""Entities to paths: the modelspace walked with every INSERT expanded.

Each drawable entity becomes one or more paths in WCS drawing units (floats), handed
to the emitter (emit.py), which converts every coordinate once to nanometres.
Blocks are expanded here rather than through ezdxf's `virtual_entities()`, so each
piece of geometry keeps its source entity (its line and handle) and its effective
layer, and no entity is ever transformed in place: points go through one affine map
from the entity's own plane (its OCS) to the WCS XY plane, with the INSERT matrices
(ezdxf's `Insert.matrix44()`, MINSERT cells from `multi_insert()`) composed in.

A map that is a similarity (rotation, uniform scale, perhaps a mirror) keeps circles
circles: ARC, CIRCLE and bulge segments stay native arcs, and a mirror (negative
determinant, e.g. the (0,0,-1) extrusion or a negative INSERT scale) turns
counter-clockwise into clockwise. Any other map (non-uniform scale, a tilted plane)
makes them ellipses, fitted like ELLIPSE and SPLINE: arcs and lines within the
tolerance (geometry.fit_curve).
"""

from __future__ import annotations

import math
from collections import Counter
from typing import Callable

from ezdxf.math import OCS, Matrix44, Vec3, arc_angle_span_deg, ellipse_param_span

from galileo_cnc.errors import SourcePos
from galileo_cnc.readers import limits
from galileo_cnc.readers.dxf import geometry as geo
from galileo_cnc.readers.dxf.errors import DxfError
from galileo_cnc.readers.dxf.scan import MODELSPACE, EntityLines, Scan

MAX_BLOCK_DEPTH = 64
_Z = Vec3(0, 0, 1)
TAU = math.tau

# Kinds that have no pen-drawable outline here; counted and skipped with one warning each.
# Anything not drawn and not listed is skipped the same way.
DRAWN = frozenset(["LINE", "ARC", "CIRCLE", "LWPOLYLINE", "POLYLINE", "SPLINE", "HELIX",
                   "ELLIPSE", "POINT"])


class Walker:
    def __init__(self, doc, scan: Scan, emitter, tol_units: float, selection: set[str] | None,
                 points: bool, source: str):
        self.doc = doc
        self.scan = scan
        self.out = emitter
        self.tol = tol_units
        self.selection = selection
        self.points = points
        self.source = source
        self.layer_counts: Counter[str] = Counter()
        self.drawn: Counter[str] = Counter()
        self.skipped: Counter[str] = Counter()
        self.invalid: Counter[str] = Counter()
        self.first_skipped: dict[str, int] = {}
        self.notes: dict[str, int] = {}  # one-off warnings: message -> line
        self._layout_cache: dict[str, list[EntityLines]] = {}
        self.current: EntityLines | None = None
        self.visits = 0  # entities visited inside blocks (each copy counted)
        self.max_visits = limits.max_block_entities()
        self._expansion: dict[str, int] = {}  # block name -> entities one INSERT of it visits
        self._expanding: set[str] = set()
        handlers: dict[str, Callable] = {
            "LINE": self._line, "POINT": self._point, "CIRCLE": self._circle,
            "ARC": self._arc, "LWPOLYLINE": self._lwpolyline, "POLYLINE": self._polyline,
            "ELLIPSE": self._ellipse, "SPLINE": self._spline, "HELIX": self._spline,
        }
        self.handlers = handlers

    # ---- traversal ------------------------------------------------------------

    def run(self) -> None:
        self.walk(list(self.doc.modelspace()), None, None, 0, MODELSPACE)

    def _layout_lines(self, key: str) -> list[EntityLines]:
        cached = self._layout_cache.get(key)
        if cached is None:
            listed = self.scan.layouts.get(key, [])
            if key == MODELSPACE:
                listed = [e for e in listed if not e.paperspace]
            cached = self._layout_cache[key] = listed
        return cached

    def _find(self, entity, dxftype: str, listed: list[EntityLines], index: int,
              aligned: bool) -> EntityLines | None:
        """Where the entity is in the file: by its handle, else by its place in its
        section or block (files without handles, or handles ezdxf had to renumber
        because the file repeats them), when that place holds the same kind."""
        handle = attribute(entity, "handle", None)
        if handle:
            found = self.scan.handles.get(handle.upper())
            if found is not None and found.dxftype == dxftype:
                return found
        if index < len(listed):
            candidate = listed[index]
            if candidate.dxftype == dxftype and (aligned or candidate.handle is None):
                return candidate
        return None

    def walk(self, entities: list, matrix: Matrix44 | None, layer0: str | None, depth: int,
             key: str) -> None:
        listed = self._layout_lines(key)
        aligned = len(listed) == len(entities)
        if depth:
            self.visits += len(entities)
        for index, entity in enumerate(entities):
            dxftype = entity.dxftype()
            info = self._find(entity, dxftype, listed, index, aligned)
            if attribute(entity, "invisible", 0):
                continue
            layer = attribute(entity, "layer", "0")
            if layer == "0" and layer0 is not None:
                layer = layer0
            if dxftype == "INSERT":
                self._insert(entity, matrix, layer, depth, info)
                continue
            self.layer_counts[layer] += 1
            if self.selection is not None and layer.casefold() not in self.selection:
                continue
            handler = self.handlers.get(dxftype)
            if handler is None or (dxftype == "POINT" and not self.points):
                self._skip(dxftype, info)
                continue
            self.current = info
            self.out.entity(info, attribute(entity, "handle", None))
            try:
                drawn = handler(entity, matrix)
            except DxfError:
                raise
            except (ValueError, ZeroDivisionError, ArithmeticError, IndexError, TypeError,
                    AttributeError) as problem:
                self.invalid[dxftype] += 1
                self.note(info, f"{dxftype} cannot be drawn ({problem}); skipped")
                continue
            if drawn is not False:
                self.drawn[dxftype] += 1

    def _insert(self, insert, matrix: Matrix44 | None, layer: str, depth: int,
                info: EntityLines | None) -> None:
        for _ in insert.attribs:
            self.layer_counts[layer] += 1
            self._skip("ATTRIB", info)
        block = insert.block()
        name = insert.dxf.get("name", "?")
        if block is None:
            self.note(info, f"INSERT of block '{name}', which is not defined; skipped")
            return
        if block.block is not None and block.block.get_flag_state(4 | 8, name="flags"):
            self.note(info, f"block '{name}' is an external reference (xref); not drawn")
            return
        if depth >= MAX_BLOCK_DEPTH:
            line = info.line if info else 0
            raise DxfError(SourcePos(self.source, max(line, 1), 1),
                           f"blocks nested more than {MAX_BLOCK_DEPTH} deep: does block "
                           f"'{name}' insert itself?")
        entities = list(block)
        key = block.name.upper()
        count = insert.mcount if insert.mcount > 1 else 1
        cost = count * self._expanded(block.name)
        if self.visits + cost > self.max_visits:
            line = info.line if info else 0
            copies = f"{count:,} copies" if count > 1 else "one copy"
            raise DxfError(SourcePos(self.source, max(line, 1), 1), limits.ops_message(
                self.max_visits, f"INSERT of block '{name}' ({copies}, nested blocks expanded) "
                "would draw", "entities through block references",
                f"set {limits.MAX_BLOCK_ENTITIES_ENV}=<count>"))
        copies = insert.multi_insert() if count > 1 else (insert,)
        for copy in copies:
            inner = copy.matrix44()
            self.walk(entities, inner if matrix is None else inner @ matrix, layer, depth + 1, key)

    def _expanded(self, name: str, depth: int = 0) -> int:
        """Entities that walking block `name` once visits, nested INSERTs (and MINSERT
        cells) expanded, counted without walking them; capped just above the limit (a
        block that inserts itself counts as beyond it)."""
        key = name.upper()
        known = self._expansion.get(key)
        if known is not None:
            return known
        if depth > MAX_BLOCK_DEPTH:
            return 0  # walking stops there with its own error
        cap = self.max_visits + 1
        if key in self._expanding:
            return cap
        self._expanding.add(key)
        total = 0
        for entity in self.doc.blocks.get(name) or ():
            total += 1
            if entity.dxftype() == "INSERT":
                try:
                    copies = max(1, int(entity.mcount))
                except Exception:  # a broken MINSERT: walking it reports the problem
                    copies = 1
                total += copies * self._expanded(attribute(entity, "name", ""), depth + 1)
            if total >= cap:
                total = cap
                break
        self._expanding.discard(key)
        self._expansion[key] = total
        return total

    def _skip(self, dxftype: str, info: EntityLines | None) -> None:
        self.skipped[dxftype] += 1
        if dxftype not in self.first_skipped:
            self.first_skipped[dxftype] = info.line if info else 0

    def note(self, info: EntityLines | None, message: str) -> None:
        if message not in self.notes:
            self.notes[message] = info.line if info else 0

    # ---- coordinates ----------------------------------------------------------

    @staticmethod
    def _wcs(matrix: Matrix44 | None, point) -> geo.Point:
        if matrix is None:
            return (point[0], point[1])
        p = matrix.transform(point)
        return (p.x, p.y)

    @staticmethod
    def _plane(entity, z: float, matrix: Matrix44 | None) -> geo.Affine:
        """The affine map from the entity's OCS plane at elevation z to WCS XY."""
        extrusion = Vec3(entity.dxf.get("extrusion", _Z))
        if matrix is None and extrusion == _Z:
            return geo.IDENTITY
        ocs = OCS(extrusion)
        ux, uy, origin = ocs.ux, ocs.uy, ocs.uz * z
        if matrix is not None:
            origin = matrix.transform(origin)
            ux = matrix.transform_direction(ux)
            uy = matrix.transform_direction(uy)
        return (ux.x, uy.x, ux.y, uy.y, origin.x, origin.y)

    # ---- entities -------------------------------------------------------------

    def _line(self, entity, matrix) -> None:
        start = self._wcs(matrix, entity.dxf.start)
        end = self._wcs(matrix, entity.dxf.end)
        self.out.path(start, [(geo.LINE, end[0], end[1], 0.0, 0.0, -1)])

    def _point(self, entity, matrix) -> None:
        at = self._wcs(matrix, entity.dxf.location)
        self.out.path(at, [(geo.LINE, at[0], at[1], 0.0, 0.0, -1)], dot=True)

    def _circle(self, entity, matrix) -> None:
        centre = entity.dxf.center
        radius = entity.dxf.radius
        if not radius > 0:
            raise ValueError(f"radius {radius}")
        plane = self._plane(entity, centre.z, matrix)
        self._circular(plane, centre.x, centre.y, radius, 0.0, TAU)

    def _arc(self, entity, matrix) -> None:
        centre = entity.dxf.center
        radius = entity.dxf.radius
        if not radius > 0:
            raise ValueError(f"radius {radius}")
        span = arc_angle_span_deg(entity.dxf.start_angle, entity.dxf.end_angle)
        if span == 0:
            return
        plane = self._plane(entity, centre.z, matrix)
        start = math.radians(entity.dxf.start_angle)
        self._circular(plane, centre.x, centre.y, radius, start,
                       TAU if span >= 360.0 else math.radians(span))

    def _circular(self, plane: geo.Affine, cx: float, cy: float, r: float, start: float,
                  sweep: float, vertex: int = -1) -> None:
        """A counter-clockwise arc (in its OCS) from angle `start` through `sweep`; a
        sweep of 2 pi is a full circle."""
        full = sweep >= TAU
        p0 = geo.apply(plane, cx + r * math.cos(start), cy + r * math.sin(start))
        segments = self._arc_segments(plane, cx, cy, r, start, sweep, p0, full, vertex)
        self.out.path(p0, segments)

    def _arc_segments(self, plane, cx, cy, r, start, sweep, p0, full, vertex) -> list:
        scale = geo.similarity_scale(plane)
        if scale is not None:
            kind = geo.CCW if geo.determinant(plane) > 0 else geo.CW
            c = geo.apply(plane, cx, cy)
            if full:
                return [(kind | geo.FULL, p0[0], p0[1], c[0], c[1], vertex)]
            end = start + sweep
            p1 = geo.apply(plane, cx + r * math.cos(end), cy + r * math.sin(end))
            return [(kind, p1[0], p1[1], c[0], c[1], vertex)]
        return self._fitted_arc(plane, cx, cy, r, start, sweep, p0, full, vertex)

    def _fitted_arc(self, plane, cx, cy, r, start, sweep, p0, full, vertex) -> list:
        def at(ts):
            return [geo.apply(plane, cx + r * math.cos(start + t), cy + r * math.sin(start + t))
                    for t in ts]

        return self._fit(at, 0.0, sweep, p0, p0 if full else None, vertex)

    def _fit(self, at, t0: float, t1: float, p0, p1, vertex: int = -1,
             breaks: list[float] | None = None) -> list:
        """Fit the curve `at` from t0 to t1 (at most a quarter of the way per first
        piece, and split at `breaks`), p1 given for a closed curve's exact end."""
        cuts = sorted(set([t0, t1] + [b for b in (breaks or []) if t0 < b < t1]))
        pieces = []
        for a, b in zip(cuts, cuts[1:]):
            n = max(1, math.ceil(abs(b - a) / (math.pi / 2))) if breaks is None else 1
            pieces += [a + (b - a) * k / n for k in range(n)]
        pieces.append(t1)
        points = at(pieces)
        points[0] = p0
        if p1 is not None:
            points[-1] = p1
        out: list = []
        for k in range(len(pieces) - 1):
            geo.fit_curve(at, pieces[k], pieces[k + 1], points[k], points[k + 1], self.tol,
                          out, vertex)
        return out

    def _bulged(self, plane: geo.Affine, vertices: list[tuple[float, float, float]],
                indices: list[int], closed: bool, start_vertex_line: int) -> None:
        """A 2D polyline in its OCS: vertices (x, y, bulge), each segment taking the
        bulge of its start vertex; `indices` are the vertex numbers in the file."""
        if len(vertices) < 2:
            return  # nothing to draw
        mapped = [geo.apply(plane, x, y) for x, y, _ in vertices]
        count = len(vertices)
        segments: list = []
        similar = geo.similarity_scale(plane) is not None
        ccw = geo.determinant(plane) > 0
        for k in range(count if closed else count - 1):
            n = (k + 1) % count
            x0, y0, bulge = vertices[k]
            x1, y1, _ = vertices[n]
            end = mapped[n]
            vertex = indices[n]
            # a bulge whose arc strays less than a thousandth of the tolerance from its
            # chord (CAD writes 1e-12) is the chord: its centre may be beyond any range
            if (x0 == x1 and y0 == y1) or \
                    abs(bulge) * math.hypot(x1 - x0, y1 - y0) / 2 <= self.tol / 1000:
                segments.append((geo.LINE, end[0], end[1], 0.0, 0.0, vertex))
                continue
            c = geo.bulge_centre(x0, y0, x1, y1, bulge)
            if similar:
                centre = geo.apply(plane, *c)
                kind = geo.CCW if (bulge > 0) == ccw else geo.CW
                segments.append((kind, end[0], end[1], centre[0], centre[1], vertex))
            else:
                r = math.hypot(x0 - c[0], y0 - c[1])
                start = math.atan2(y0 - c[1], x0 - c[0])
                segments += self._fitted_arc(plane, c[0], c[1], r, start,
                                             4 * math.atan(bulge), mapped[k], False, vertex)
                last = segments[-1]
                segments[-1] = (last[0], end[0], end[1], last[3], last[4], vertex)
        self.out.path(mapped[0], segments, start_vertex=indices[0])

    def _lwpolyline(self, entity, matrix) -> None:
        points = list(entity.get_points("xyseb"))
        if any(s or e for _, _, s, e, _ in points) or entity.dxf.get("const_width", 0):
            self.out.note_widths()
        plane = self._plane(entity, entity.dxf.get("elevation", 0.0), matrix)
        self._bulged(plane, [(x, y, b) for x, y, _, _, b in points], list(range(len(points))),
                     entity.closed, 0)

    def _polyline(self, entity, matrix) -> None:
        mode = entity.get_mode()
        if mode in ("AcDbPolyFaceMesh", "AcDbPolygonMesh"):
            self._skip("POLYLINE (mesh)", self.current)
            return False
        kept = [(index, v) for index, v in enumerate(entity.vertices)
                if not v.dxf.get("flags", 0) & 16]  # spline frame control points are not drawn
        closed = entity.is_closed
        if mode == "AcDb3dPolyline":
            if len(kept) < 2:
                return
            points = [self._wcs(matrix, v.dxf.location) for _, v in kept]
            segments = [(geo.LINE, x, y, 0.0, 0.0, kept[k][0])
                        for k, (x, y) in enumerate(points) if k]
            if closed:
                segments.append((geo.LINE, points[0][0], points[0][1], 0.0, 0.0, kept[0][0]))
            self.out.path(points[0], segments, start_vertex=kept[0][0])
            return
        if any(v.dxf.get("start_width", 0) or v.dxf.get("end_width", 0) for _, v in kept) or \
                entity.dxf.get("default_start_width", 0) or entity.dxf.get("default_end_width", 0):
            self.out.note_widths()
        elevation = entity.dxf.get("elevation", Vec3())
        plane = self._plane(entity, Vec3(elevation).z, matrix)
        vertices = [(v.dxf.location.x, v.dxf.location.y, v.dxf.get("bulge", 0.0)) for _, v in kept]
        self._bulged(plane, vertices, [index for index, _ in kept], closed, 0)

    def _ellipse(self, entity, matrix) -> None:
        centre = Vec3(entity.dxf.center)
        major = Vec3(entity.dxf.major_axis)
        minor = entity.minor_axis
        if matrix is not None:
            centre = matrix.transform(centre)
            major = matrix.transform_direction(major)
            minor = matrix.transform_direction(minor)
        c, u, v = (centre.x, centre.y), (major.x, major.y), (minor.x, minor.y)
        t0 = entity.dxf.get("start_param", 0.0)
        span = ellipse_param_span(t0, entity.dxf.get("end_param", TAU))
        if span == 0:
            return
        full = math.isclose(span, TAU)
        plane = (u[0], v[0], u[1], v[1], c[0], c[1])  # the unit circle -> this ellipse
        p0 = geo.apply(plane, math.cos(t0), math.sin(t0))
        if full:
            span = TAU
        self.out.path(p0, self._arc_segments(plane, 0.0, 0.0, 1.0, t0, span, p0, full, -1))

    def _spline(self, entity, matrix) -> None:
        curve = _bspline(entity)
        if matrix is not None:
            curve = curve.transform(matrix)
        knots = list(curve.knots())
        low, high = knots[curve.order - 1], knots[curve.count]
        if not high > low:
            raise ValueError("an empty knot span")
        if curve.degree == 1:
            points = [(p.x, p.y) for p in curve.control_points]
            self.out.path(points[0], [(geo.LINE, x, y, 0.0, 0.0, -1) for x, y in points[1:]])
            return
        evaluator = curve.evaluator

        def at(ts):
            return [(p.x, p.y) for p in evaluator.points(ts)]

        p0, p1 = at([low, high])
        closed_exactly = p0 == p1
        breaks = sorted(set(k for k in knots if low < k < high))
        self.out.path(p0, self._fit(at, low, high, p0, p0 if closed_exactly else p1,
                                    breaks=breaks))


def attribute(entity, name: str, default):
    """A DXF attribute, or `default` where the entity has no such attribute (ezdxf keeps
    unknown kinds such as R10's 3DLINE as bare tag storage)."""
    try:
        return entity.dxf.get(name, default)
    except Exception:  # ezdxf's DXFAttributeError for attributes the kind lacks
        return default


def _bspline(entity):
    """ezdxf's B-spline of a SPLINE entity; a closed periodic spline (AutoCAD writes
    count + 1 knots for it) is unrolled into the equivalent open one."""
    try:
        return entity.construction_tool()
    except ValueError:
        periodic = _periodic(entity)
        if periodic is None:
            raise
        return periodic


def _periodic(entity):
    from ezdxf.math import BSpline

    control = [Vec3(p) for p in entity.control_points]
    knots = [float(k) for k in entity.knots]
    degree = entity.dxf.degree
    weights = [float(w) for w in entity.weights] if len(entity.weights) else None
    n = len(control)
    if not (entity.closed and n > degree and len(knots) == n + 1):
        return None
    # A periodic spline of n control points: the points wrap around by `degree`, and the
    # knot spacing repeats with period knots[n] - knots[0].
    control += control[:degree]
    if weights:
        weights += weights[:degree]
    spans = [knots[k + 1] - knots[k] for k in range(n)]
    count = len(control) + degree + 1
    full = [knots[0] - sum(spans[n - degree:])]
    for k in range(count - 1):
        full.append(full[-1] + spans[(k - degree) % n])
    return BSpline(control, order=degree + 1, knots=full, weights=weights)
