"""The copper of a Gerber Program: every object as its exact dark shape, in integer nm.

`dark_geometry(program)` replays the op table the way a photoplotter exposes film:
each draw, arc, flash and region becomes a polygon (curves within the chord
tolerance, see shapes.py), and the objects are combined in file order: a run of
dark objects (%LPD) is united with the image so far, a run of clear ones (%LPC) is
taken out of it. Inside one run the order does not matter, so a run is built as
one batch and combined with one boolean operation. docs/ink.md describes what
each object becomes.
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass, field

import numpy as np

from galileo_cnc.errors import GalileoError
from galileo_cnc.plan import curves
from galileo_cnc.plan.ink import shapes
from galileo_cnc.plan.ink.backends import make_backend
from galileo_cnc.program.extents import dark_mask, region_mask, start_points
from galileo_cnc.program.ops import (
    KIND,
    TOOL,
    Aperture,
    I,
    J,
    OpKind,
    Program,
    X,
    Y,
)

#: The polygon library the ink uses (docs/ink.md has the measurements behind it).
DEFAULT_BACKEND = "clipper"

_LINE, _ARC_CW, _ARC_CCW = int(OpKind.LINE), int(OpKind.ARC_CW), int(OpKind.ARC_CCW)
_FLASH, _MOVE = int(OpKind.FLASH), int(OpKind.MOVE)
_REGION_BEGIN, _REGION_END = int(OpKind.REGION_BEGIN), int(OpKind.REGION_END)
_STROKES = (_LINE, _ARC_CW, _ARC_CCW)


@dataclass
class DarkImage:
    """The copper of one layer: a polygon set of the backend's own type, integer nm.

    `native` is what the library works with (pyclipper: a list of rings, outer
    counter-clockwise and holes clockwise; shapely: a (Multi)Polygon).
    """

    native: object
    backend: object
    tolerance_nm: int
    stats: dict = field(default_factory=dict)

    def polygons(self) -> list[tuple[np.ndarray, list[np.ndarray]]]:
        """(shell, holes) int64 rings: shells counter-clockwise, holes clockwise."""
        return self.backend.polygons(self.native)

    def area_nm2(self) -> float:
        return self.backend.area(self.native)

    def bounds(self) -> tuple[int, int, int, int] | None:
        """(xmin, ymin, xmax, ymax) in nm, None when nothing is dark."""
        return self.backend.bounds(self.native)

    def vertex_count(self) -> int:
        return self.backend.vertex_count(self.native)

    def to_shapely(self):
        """The image as a shapely MultiPolygon (needs shapely whatever the backend)."""
        return self.backend.to_shapely(self.native)

    @property
    def is_empty(self) -> bool:
        return self.bounds() is None


class InkError(GalileoError):
    """A Program whose objects cannot be turned into copper (an unknown aperture)."""


def dark_geometry(program: Program, tolerance_nm: int = shapes.DEFAULT_TOLERANCE_NM,
                  backend: str | object = DEFAULT_BACKEND) -> DarkImage:
    """The union of the dark objects minus the clear ones, in file order.

    Curves are polygons whose every edge lies within `tolerance_nm` of the true
    outline; all vertices are integer nm. `backend` is a name from
    backends.BACKENDS or a backend object (the bench runs each of them).
    """
    if program.format != "gerber":
        raise InkError(f"{program.source}: only Gerber artwork has copper to ink "
                       f"(this is {program.format})")
    engine = make_backend(backend) if isinstance(backend, str) else backend
    curves.chord_budget(tolerance_nm)  # rejects a tolerance <= 0
    return _Inker(program, tolerance_nm, engine).run()


class _Inker:
    def __init__(self, program: Program, tolerance_nm: int, engine):
        self.program = program
        self.tolerance = tolerance_nm
        self.engine = engine
        self.table = program.table
        self.templates: dict[int, tuple] = {}
        self.stats = {"objects": 0, "runs": 0, "clear_runs": 0,
                      "shapes_s": 0.0, "boolean_s": 0.0}

    # --- driver ---------------------------------------------------------------------

    def run(self) -> DarkImage:
        table = self.table
        engine = self.engine
        image = engine.empty()
        if not len(table):
            return DarkImage(image, engine, self.tolerance, self.stats)
        kind = table[:, KIND]
        self.starts = start_points(table)
        inside = region_mask(table)
        dark = dark_mask(table)
        objects = np.flatnonzero(((np.isin(kind, _STROKES) | (kind == _FLASH)) & ~inside)
                                 | (kind == _REGION_BEGIN))
        self.region_end = dict(zip(np.flatnonzero(kind == _REGION_BEGIN).tolist(),
                                   np.flatnonzero(kind == _REGION_END).tolist()))
        self.stats["objects"] = len(objects)
        if not len(objects):
            return DarkImage(image, engine, self.tolerance, self.stats)
        polarity = dark[objects]
        cuts = np.flatnonzero(np.diff(polarity.astype(np.int8))) + 1
        for run in np.split(objects, cuts):
            clock = time.perf_counter()
            batch = self._batch(run)
            built = time.perf_counter()
            if dark[run[0]]:
                image = engine.unite(image, batch)
            else:
                image = engine.subtract(image, batch)
                self.stats["clear_runs"] += 1
            self.stats["runs"] += 1
            self.stats["shapes_s"] += built - clock
            self.stats["boolean_s"] += time.perf_counter() - built
        clock = time.perf_counter()
        image = engine.finish(image)
        self.stats["boolean_s"] += time.perf_counter() - clock
        return DarkImage(image, engine, self.tolerance, self.stats)

    def _batch(self, rows: np.ndarray) -> list:
        """Every object of one polarity run, added to one backend batch."""
        table, engine = self.table, self.engine
        batch = engine.new_batch()
        kind = table[rows, KIND]
        tool = table[rows, TOOL]
        for code in np.unique(tool[kind == _FLASH]).tolist():
            self._flashes(batch, rows[(kind == _FLASH) & (tool == code)], code)
        lines = kind == _LINE
        for code in np.unique(tool[lines]).tolist():
            self._lines(batch, rows[lines & (tool == code)], code)
        for row in rows[(kind == _ARC_CW) | (kind == _ARC_CCW)].tolist():
            self._arc(batch, row)
        for row in rows[kind == _REGION_BEGIN].tolist():
            self._region(batch, row)
        return batch

    # --- apertures -------------------------------------------------------------------

    def _aperture(self, code: int) -> Aperture:
        aperture = self.program.apertures.get(code)
        if aperture is None:
            raise InkError(f"{self.program.source}: aperture D{code} is used but not defined")
        return aperture

    def _template(self, code: int) -> tuple:
        """What aperture `code` looks like, centred on the flash point, cached:

        ("circle", ring, diameter): the regular polygon standing for a round aperture;
        ("convex", ring): any other convex outline (rectangle, obround, polygon);
        ("general", polygons): (shell, holes) polygons (holes, macros);
        ("empty",): nothing dark (zero size, an all-clear macro, an %AB block).
        """
        cached = self.templates.get(code)
        if cached is not None:
            return cached
        aperture = self._aperture(code)
        tolerance = self.tolerance
        p = aperture.params_nm
        if aperture.shape == "circle":
            outline = shapes.circle_template(p[0], tolerance) if p[0] > 0 else None
            template = ("circle", outline, p[0]) if outline is not None else ("empty",)
        elif aperture.shape == "rectangle":
            template = ("convex", shapes.rectangle(p[0], p[1])) if p[0] > 0 and p[1] > 0 \
                else ("empty",)
        elif aperture.shape == "obround":
            template = ("convex", shapes.obround(p[0], p[1], tolerance)) \
                if p[0] > 0 and p[1] > 0 else ("empty",)
        elif aperture.shape == "polygon":
            phase = math.radians(aperture.rotation_udeg / 1e6)
            template = ("convex", shapes.regular_polygon(p[0] / 2, aperture.vertices, phase)) \
                if p[0] > 0 else ("empty",)
        elif aperture.shape == "macro":
            template = self._macro(aperture)
        else:  # "block": flashes of %AB blocks are replayed as rows by the reader
            template = ("empty",)
        if aperture.hole_nm and template[0] in ("circle", "convex"):
            template = self._with_hole(template[1], aperture.hole_nm)
        self.templates[code] = template
        return template

    def _with_hole(self, outline: np.ndarray, hole_nm: tuple[int, ...]) -> tuple:
        """The outline minus its hole (round, or rectangular for two sizes): the hole is
        clear in the aperture only, it never clears what lies under the flash."""
        engine = self.engine
        if len(hole_nm) >= 2:
            hole = shapes.rectangle(hole_nm[0], hole_nm[1]) if min(hole_nm[:2]) > 0 else None
        else:
            hole = shapes.circle_template(hole_nm[0], self.tolerance) if hole_nm[0] > 0 else None
        shape = engine.new_batch()
        engine.add_polygons(shape, [(outline, [])])
        image = engine.unite(engine.empty(), shape)
        if hole is not None:
            cut = engine.new_batch()
            engine.add_polygons(cut, [(hole, [])])
            image = engine.subtract(image, cut)
        polygons = engine.polygons(image)
        return ("general", polygons) if polygons else ("empty",)

    def _macro(self, aperture: Aperture) -> tuple:
        """A macro's primitives exposed in order, clear ones cutting only the macro."""
        engine = self.engine
        image = engine.empty()
        primitives = [p for p in aperture.primitives if p[0] in ("circle", "polygon")]
        k = 0
        while k < len(primitives):
            dark = bool(primitives[k][1])
            batch = engine.new_batch()
            while k < len(primitives) and bool(primitives[k][1]) == dark:
                primitive = primitives[k]
                if primitive[0] == "circle":
                    _, _, x, y, diameter = primitive
                    if diameter > 0:
                        ring = shapes.circle_template(diameter, self.tolerance) + (x, y)
                        engine.add_rings(batch, ring[None])
                else:
                    ring = np.array(primitive[2], dtype=np.int64).reshape(-1, 2)
                    if len(ring) > 1 and (ring[0] == ring[-1]).all():
                        ring = ring[:-1]
                    engine.add_contour(batch, ring)
                k += 1
            image = engine.unite(image, batch) if dark else engine.subtract(image, batch)
        polygons = engine.polygons(image)
        return ("general", polygons) if polygons else ("empty",)

    # --- objects -----------------------------------------------------------------------

    def _flashes(self, batch: list, rows: np.ndarray, code: int) -> None:
        template = self._template(code)
        if template[0] == "empty":
            return
        engine = self.engine
        points = self.table[rows][:, [X, Y]]
        if template[0] in ("circle", "convex"):
            engine.add_rings(batch, template[1][None, :, :] + points[:, None, :])
            return
        polygons = template[1]
        engine.add_polygons(batch, [(shell + p, [h + p for h in holes])
                                    for p in points for shell, holes in polygons])

    def _lines(self, batch: list, rows: np.ndarray, code: int) -> None:
        template = self._template(code)
        if template[0] == "empty":
            return
        engine = self.engine
        ends = self.table[rows][:, [X, Y]]
        starts = self.starts[rows]
        if template[0] == "circle":
            for chunk in range(0, len(rows), 8192):
                engine.add_rings(batch, shapes.capsules(template[1], starts[chunk:chunk + 8192],
                                                        ends[chunk:chunk + 8192]))
            return
        for start, end in zip(starts, ends):
            self._segment(batch, template, start, end)

    def _segment(self, batch: list, template: tuple, start: np.ndarray, end: np.ndarray) -> None:
        """A straight draw with a non-round aperture: the exact Minkowski sum."""
        engine = self.engine
        if template[0] == "convex":
            engine.add_polygons(batch, [(shapes.convex_sweep(template[1], start, end), [])])
            return
        polygons = template[1]
        pieces = [(shell + start, [h + start for h in holes]) for shell, holes in polygons]
        if (start != end).any():
            pieces += [(shell + end, [h + end for h in holes]) for shell, holes in polygons]
            rings = [ring for shell, holes in polygons for ring in [shell, *holes]]
            pieces += [(quad, []) for quad in shapes.edge_sweeps(rings, start, end)]
        engine.add_polygons(batch, pieces)

    def _arc(self, batch: list, row: int) -> None:
        template = self._template(int(self.table[row, TOOL]))
        if template[0] == "empty":
            return
        t = self.table[row].tolist()
        sx, sy = self.starts[row].tolist()
        ex, ey, i, j = t[X], t[Y], t[I], t[J]
        clockwise = t[KIND] == _ARC_CW
        engine = self.engine
        if template[0] == "circle":
            ring, diameter = template[1], template[2]
            if i == 0 and j == 0:  # no radius: the disc, or a draw to the end point
                self._lines_between(batch, ring, (sx, sy), (ex, ey))
                return
            engine.add_polygons(batch, shapes.arc_band(sx, sy, ex, ey, i, j, clockwise,
                                                       diameter / 2, self.tolerance))
            engine.add_rings(batch, np.stack([ring + (sx, sy), ring + (ex, ey)]))
            return
        # Rectangles (deprecated for arcs) and the rest: the aperture swept along each
        # chord of the centre line, which stays within tolerance of the arc.
        if i == 0 and j == 0:
            points = np.array([[sx, sy], [ex, ey]], dtype=np.int64)
        else:
            points = curves.arc_points(sx, sy, ex, ey, i, j, clockwise, self.tolerance)
        for start, end in itertools.pairwise(points):
            self._segment(batch, template, start, end)

    def _lines_between(self, batch, ring, start, end) -> None:
        self.engine.add_rings(batch, shapes.capsules(ring, np.array([start], dtype=np.int64),
                                                     np.array([end], dtype=np.int64)))

    def _region(self, batch: list, begin: int) -> None:
        """A G36/G37 region: each contour (a D02 starts the next) filled by itself, by
        the even-odd rule, so cut-ins and holes traced either way come out as holes."""
        end = self.region_end.get(begin, len(self.table))
        rows = np.arange(begin + 1, end)
        if not len(rows):
            return
        kind = self.table[rows, KIND]
        contour_id = np.cumsum(kind == _MOVE)
        # comparisons, not np.isin: a pour has hundreds of regions, np.isin costs 0.1 ms a call
        arc = (kind == _ARC_CW) | (kind == _ARC_CCW)
        drawn = arc | (kind == _LINE)
        for contour in np.unique(contour_id[drawn]).tolist():
            mine = drawn & (contour_id == contour)
            self.engine.add_contour(batch, self._contour(rows[mine], bool(arc[mine].any())))

    def _contour(self, rows: np.ndarray, arcs: bool) -> np.ndarray:
        """The contour's points: its start, then each draw's end (an arc's chords)."""
        table = self.table
        first = self.starts[rows[0]][None, :]
        if not arcs:
            points = np.concatenate([first, table[rows][:, [X, Y]]])
        else:
            parts = [first]
            for row in rows.tolist():
                t = table[row].tolist()
                if t[KIND] == _LINE or (t[I] == 0 and t[J] == 0):
                    parts.append(np.array([[t[X], t[Y]]], dtype=np.int64))
                    continue
                sx, sy = self.starts[row].tolist()
                parts.append(curves.arc_points(sx, sy, t[X], t[Y], t[I], t[J],
                                               t[KIND] == _ARC_CW, self.tolerance)[1:])
            points = np.concatenate(parts)
        # Closed by its last point (the spec) or implicitly (lenient): one copy only.
        if len(points) > 1 and (points[0] == points[-1]).all():
            points = points[:-1]
        # Repeated points (zero-length draws) add nothing.
        keep = np.ones(len(points), dtype=bool)
        keep[1:] = (np.diff(points, axis=0) != 0).any(axis=1)
        return points[keep]
