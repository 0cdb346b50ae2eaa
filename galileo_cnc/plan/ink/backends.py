"""Polygon libraries behind one small interface: collect a batch, unite or subtract it.

`geometry.dark_geometry` hands a backend the objects of one polarity run as a
*batch*; the backend turns them into its own objects as they come and, at the end
of the run, unites them with the image so far (dark) or takes them out of it
(clear). Two backends, measured against each other by bench/bench_ink_union.py
(docs/ink.md):

- `clipper`: pyclipper (Angus Johnson's Clipper 1, integer coordinates). A polygon
  set is a list of rings ([[x, y], ...] lists or int64 arrays), outer rings
  counter-clockwise and holes clockwise, filled by the positive winding rule.
  Intersections are rounded to the integer grid: everything stays integer nm.
  Region contours are read with Clipper's even-odd fill rule.
- `shapely`: shapely 2 (GEOS OverlayNG). A polygon set is a (Multi)Polygon in
  float64, which holds integer nm exactly; `grid_size=1` snaps every result to the
  nanometre grid (snap rounding). `shapely-float` is the same without the grid,
  for the bench only (its results are not integers). GEOS has no fill rules: a
  self-intersecting region contour is repaired with make_valid's 'linework' method,
  which is even-odd except where the outline runs over itself (docs/ink.md).

The libraries are imported when a backend is made, so only the chosen one has to be
installed.
"""

from __future__ import annotations

import numpy as np

from galileo_cnc.plan.ink import clip as clip_ops
from galileo_cnc.plan.ink.shapes import signed_area2

Polygon = tuple  # (shell ring, [hole rings]), int64 (n, 2) arrays


class ClipperBackend:
    name = "clipper"

    def __init__(self):
        import pyclipper

        self.pc = pyclipper

    # --- batches -------------------------------------------------------------------

    def new_batch(self) -> list:
        return []

    def add_rings(self, batch: list, rings: np.ndarray) -> None:
        """(L, m, 2) CCW rings with no holes (capsules, flashes)."""
        batch.extend(rings)  # pyclipper reads numpy rows directly (faster than lists)

    def add_polygons(self, batch: list, polygons) -> None:
        """(shell, holes) polygons; shells of either orientation, holes inside them."""
        for shell, holes in polygons:
            if signed_area2(shell) < 0:
                shell = shell[::-1]
            batch.append(shell)
            for hole in holes:
                batch.append(hole if signed_area2(hole) < 0 else hole[::-1])

    def add_contour(self, batch: list, ring: np.ndarray) -> None:
        """A region contour, self-intersections and cut-ins read by the even-odd rule."""
        if len(ring) < 3:
            return
        # A union of the contour alone under the even-odd rule. Not SimplifyPolygon:
        # that runs Clipper in strict mode, which spins for minutes on some real pours
        # (80101_0125_F200_L02.gdo); finish() makes the end result strictly simple.
        pc = self.pc
        clipper = pc.Pyclipper()
        try:
            clipper.AddPath(ring, pc.PT_SUBJECT, True)
        except pc.ClipperException:  # no area
            return
        batch.extend(clipper.Execute(pc.CT_UNION, pc.PFT_EVENODD, pc.PFT_EVENODD))

    # --- boolean operations -----------------------------------------------------------

    def empty(self) -> list:
        return []

    def _execute(self, operation, subject: list, clip: list) -> list:
        return clip_ops.boolean(operation, subject, clip)

    def unite(self, image: list, batch: list) -> list:
        if not batch:
            return image
        return self._execute(self.pc.CT_UNION, image + batch, [])

    def finish(self, image: list) -> list:
        """One last pass with StrictlySimple: no ring touches itself or another at a
        vertex, so the rings are valid OGC polygons too. (Strict mode during the big
        unions can take minutes on a pour: hellboard.back.gbr never finished; on the
        finished image it takes milliseconds.)"""
        if not image:
            return image
        clipper = self.pc.Pyclipper()
        clipper.StrictlySimple = True
        clipper.AddPaths(image, self.pc.PT_SUBJECT, True)
        return clipper.Execute(self.pc.CT_UNION, self.pc.PFT_POSITIVE, self.pc.PFT_POSITIVE)

    def subtract(self, image: list, batch: list) -> list:
        if not image or not batch:
            return image
        return self._execute(self.pc.CT_DIFFERENCE, image, batch)

    # --- reading the result -------------------------------------------------------

    def polygons(self, image: list) -> list[Polygon]:
        """(shell, holes) polygons, shells CCW and holes CW, as int64 arrays."""
        # strict as finish(): cheap on an image already united
        return clip_ops.components(image, strict=True)

    def area(self, image: list) -> float:
        return float(sum(self.pc.Area(path) for path in image))

    def bounds(self, image: list):
        if not image:
            return None
        points = np.concatenate([np.asarray(path, dtype=np.int64) for path in image])
        return (int(points[:, 0].min()), int(points[:, 1].min()),
                int(points[:, 0].max()), int(points[:, 1].max()))

    def vertex_count(self, image: list) -> int:
        return sum(len(path) for path in image)

    def to_shapely(self, image: list):
        import shapely

        return shapely.MultiPolygon([shapely.Polygon(shell, holes)
                                     for shell, holes in self.polygons(image)])


class ShapelyBackend:
    name = "shapely"

    def __init__(self, grid_size: float | None = 1.0):
        import shapely

        self.shapely = shapely
        self.grid_size = grid_size
        if grid_size is None:
            self.name = "shapely-float"

    def new_batch(self) -> list:
        return []

    def add_rings(self, batch: list, rings: np.ndarray) -> None:
        if len(rings):
            batch.append(self.shapely.polygons(rings.astype(np.float64)))

    def add_polygons(self, batch: list, polygons) -> None:
        make = self.shapely.Polygon
        batch.append(np.array([make(shell, holes) for shell, holes in polygons], dtype=object))

    def add_contour(self, batch: list, ring: np.ndarray) -> None:
        if len(ring) < 3:
            return
        polygon = self.shapely.Polygon(ring)
        if not polygon.is_valid:
            # GEOS's 'linework' repair: faces of the noded outline, alternately
            # filled and empty (the even-odd rule), cut-in lines dropped.
            polygon = self._polygonal(self.shapely.make_valid(polygon, method="linework"))
        batch.append(np.array([polygon], dtype=object).ravel())

    def empty(self):
        return self.shapely.Polygon()

    def _pieces(self, batch: list) -> np.ndarray:
        shapely = self.shapely
        pieces = np.concatenate(batch) if batch else np.array([], dtype=object)
        invalid = ~shapely.is_valid(pieces)
        if invalid.any():
            # Self-overlapping arc bands, zero-area sweeps and the like: repaired, and
            # only their polygonal parts kept (a collapsed sweep repairs to a line).
            pieces = np.concatenate([pieces[~invalid],
                                     self._polygonal(shapely.make_valid(pieces[invalid]))])
        return pieces

    def _polygonal(self, geometries) -> np.ndarray:
        """The polygons among (collections of) geometries: repairs can leave lines."""
        shapely = self.shapely
        parts = shapely.get_parts(shapely.get_parts(geometries))
        return parts[shapely.get_type_id(parts) == 3]

    def unite(self, image, batch: list):
        if not batch:
            return image
        pieces = self._pieces(batch)
        return self.shapely.union_all(np.concatenate([[image], pieces]), grid_size=self.grid_size)

    def subtract(self, image, batch: list):
        if image.is_empty or not batch:
            return image
        cut = self.shapely.union_all(self._pieces(batch), grid_size=self.grid_size)
        return self.shapely.difference(image, cut, grid_size=self.grid_size)

    def finish(self, image):
        return image

    def _parts(self, image) -> list:
        shapely = self.shapely
        polygons = shapely.get_parts(shapely.get_parts(image))  # collections flattened
        return [p for p in polygons if shapely.get_type_id(p) == 3 and not p.is_empty]

    def polygons(self, image) -> list[Polygon]:
        found = []
        for part in self._parts(image):
            part = self.shapely.orient_polygons(part) if hasattr(self.shapely, "orient_polygons") \
                else self.shapely.geometry.polygon.orient(part)
            shell = np.rint(np.asarray(part.exterior.coords)[:-1]).astype(np.int64)
            holes = [np.rint(np.asarray(h.coords)[:-1]).astype(np.int64) for h in part.interiors]
            found.append((shell, holes))
        return found

    def area(self, image) -> float:
        return float(image.area)

    def bounds(self, image):
        if image.is_empty:
            return None
        return tuple(round(v) for v in image.bounds)

    def vertex_count(self, image) -> int:
        return int(self.shapely.get_num_coordinates(image))

    def to_shapely(self, image):
        return image


BACKENDS = {
    "clipper": ClipperBackend,
    "shapely": ShapelyBackend,
    "shapely-float": lambda: ShapelyBackend(grid_size=None),
}


def make_backend(name: str):
    try:
        return BACKENDS[name]()
    except KeyError:
        raise ValueError(f"unknown polygon backend {name!r} "
                         f"(one of {', '.join(BACKENDS)})") from None
