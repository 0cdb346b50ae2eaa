"""Apertures under a load transform (%LM/%LR/%LS), as apertures of their own.

A flash, draw or arc made while a load transform is in force uses the aperture's
image mirrored, rotated and scaled about its origin. The reader registers that
image as a derived aperture, under a key of its own, and puts the key in the op
rows; everything downstream (ink geometry, preview, extents) reads it like any
other aperture.

A derived aperture stays a standard one where the shape allows it, exactly: a
circle under any transform is a circle of the scaled diameter, a rectangle or an
obround under quarter turns swaps its sides, a regular polygon adds the turn to its
own rotation (a mirror reflects its phase). Anything else (a rectangle at 30°, every
macro) becomes a macro aperture: "circle" and "polygon" primitives with integer nm
points, as macros.py makes them. Holes turn with their aperture.

Keys: derived key k of file aperture Dn is (k << 32) | n, k = 1, 2, ... in order of
first use, so `source_code(key)` is the D code the file wrote (file codes are below
2**31), and the numbering is the same however the file is read.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from galileo_cnc.program.ops import NO_TOOL, TOOL, Aperture, Program
from galileo_cnc.readers.gerber.apertures import polygon_extent
from galileo_cnc.readers.gerber.load import LoadTransform
from galileo_cnc.readers.gerber.macros import shapes_extent
from galileo_cnc.readers.gerber.numbers import checked_nm

SOURCE_BITS = 32
_SOURCE_MASK = (1 << SOURCE_BITS) - 1
_UDEG_PER_TURN = 360_000_000
_UDEG_HALF_TURN = 180_000_000


def derived_key(index: int, source: int) -> int:
    """The key of the `index`-th derived aperture (from 1), made from file code `source`."""
    return (index << SOURCE_BITS) | source_code(source)


def source_code(key: int) -> int:
    """The file's D code behind an aperture key (the key itself for file apertures)."""
    return key & _SOURCE_MASK if key != NO_TOOL else key


def aperture_label(program: Program, key: int) -> str:
    """How messages name an aperture: 'D10', or 'D10 under %LR30' for a derived one."""
    derived = program.metadata.get("derived_apertures", {}).get(key)
    if derived is None:
        return f"D{key}"
    source, transform = derived
    return f"D{source} under {transform}"


def with_source_apertures(program: Program) -> Program:
    """The program with every derived aperture replaced by its file aperture: what the
    centre-line mode draws (a centre line or a dot is the same under any transform,
    and one pen per aperture means one per D code of the file)."""
    derived = program.metadata.get("derived_apertures", {})
    if not derived:
        return program
    table = program.table.copy()
    tools = table[:, TOOL]
    mapped = np.flatnonzero(np.isin(tools, list(derived)))
    tools[mapped] = [derived[int(t)][0] for t in tools[mapped].tolist()]
    apertures = {k: a for k, a in program.apertures.items() if k not in derived}
    return dataclasses.replace(program, table=table, apertures=apertures)


def transform_aperture(aperture: Aperture, load: LoadTransform, key: int) -> Aperture:
    """`aperture` as `load` makes it, under `key`; ValueError if a size leaves the range."""
    describe = load.describe()
    turns = load.quarter_turns()
    shape = aperture.shape
    hole = _hole(aperture.hole_nm, load, turns)
    if shape == "macro":
        primitives = tuple(_primitive(p, load) for p in aperture.primitives)
        return _macro(key, f"{aperture.macro} {describe}", primitives)
    if hole is not None:
        p = aperture.params_nm
        if shape == "circle":
            d = _length(p[0], load)
            return Aperture(key, "circle", (d,), hole, extent_nm=_box(d, d))
        if shape in ("rectangle", "obround") and turns is not None:
            w, h = (p[1], p[0]) if turns % 2 else (p[0], p[1])
            w, h = _length(w, load), _length(h, load)
            return Aperture(key, shape, (w, h), hole, extent_nm=_box(w, h))
        if shape == "polygon":
            d = _length(p[0], load)
            rotation = _polygon_phase(aperture.rotation_udeg, load)
            return Aperture(key, "polygon", (d,), hole, rotation_udeg=rotation,
                            vertices=aperture.vertices,
                            extent_nm=polygon_extent(d, aperture.vertices, rotation / 1e6))
    # A rectangle or obround at another angle, or a rectangular hole that turns with it.
    primitives = tuple(_primitive(p, load) for p in _as_primitives(aperture))
    return _macro(key, f"{aperture.describe()} {describe}", primitives)


def _macro(key: int, name: str, primitives: tuple) -> Aperture:
    return Aperture(key, "macro", macro=name, primitives=primitives,
                    extent_nm=shapes_extent(primitives))


def _length(nm: int, load: LoadTransform) -> int:
    return checked_nm(load.scale_length(nm))


def _box(width_nm: int, height_nm: int) -> tuple[int, int, int, int]:
    half_w, half_h = (width_nm + 1) // 2, (height_nm + 1) // 2
    return (-half_w, -half_h, half_w, half_h)


def _hole(hole_nm: tuple[int, ...], load: LoadTransform, turns: int | None):
    """The hole under `load`, or None when a rectangular hole turns off the axes."""
    if len(hole_nm) < 2:
        return tuple(_length(h, load) for h in hole_nm)
    if turns is None:
        return None
    w, h = (hole_nm[1], hole_nm[0]) if turns % 2 else (hole_nm[0], hole_nm[1])
    return (_length(w, load), _length(h, load))


def _polygon_phase(rotation_udeg: int, load: LoadTransform) -> int:
    """The first vertex's angle after the transform. A mirror reflects the vertex angles
    (X: 180° - a, Y: -a, both: a + 180°), which for a regular polygon is the same polygon
    with the reflected phase; then the rotation adds (rounded to the micro-degree)."""
    phase = {"N": rotation_udeg, "X": _UDEG_HALF_TURN - rotation_udeg, "Y": -rotation_udeg,
             "XY": rotation_udeg + _UDEG_HALF_TURN}[load.mirror]
    return (phase + round(load.rotation_deg * 1_000_000)) % _UDEG_PER_TURN


def _primitive(primitive: tuple, load: LoadTransform) -> tuple:
    """A primitive under `load`: a macro's (integer nm, exact at quarter turns) or a
    standard shape's (float nm corners, rounded once); sizes are integer nm."""
    if primitive[0] == "circle":
        _, dark, x, y, diameter = primitive
        (tx,), (ty,) = load.transform_xy(np.array([x]), np.array([y]))
        return ("circle", dark, _coordinate(tx), _coordinate(ty), _length(diameter, load))
    _, dark, points = primitive
    return ("polygon", dark, _points(np.array(points).reshape(-1, 2), load))


def _points(ring: np.ndarray, load: LoadTransform) -> tuple[tuple[int, int], ...]:
    x, y = load.transform_xy(ring[:, 0], ring[:, 1])
    pairs = [(_coordinate(a), _coordinate(b)) for a, b in zip(x.tolist(), y.tolist())]
    if load.mirrors_once:  # keep the orientation the outline was written in
        pairs.reverse()
    return tuple(pairs)


def _coordinate(nm) -> int:
    return checked_nm(int(nm))


def _as_primitives(aperture: Aperture) -> list[tuple]:
    """A standard aperture as macro primitives centred on its origin, points in float nm
    (half-nm corners stay exact until the one rounding of the transform)."""
    p = aperture.params_nm
    if aperture.shape == "circle":
        shapes = [("circle", True, 0.0, 0.0, p[0])]
    elif aperture.shape == "rectangle":
        shapes = [("polygon", True, _rectangle(p[0], p[1]))]
    elif aperture.shape == "obround":
        shapes = _obround(p[0], p[1])
    else:  # polygon
        r = p[0] / 2
        phase = math.radians(aperture.rotation_udeg / 1e6)
        n = aperture.vertices
        shapes = [("polygon", True, [(r * math.cos(phase + 2 * math.pi * k / n),
                                      r * math.sin(phase + 2 * math.pi * k / n))
                                     for k in range(n)])]
    hole = aperture.hole_nm
    if len(hole) >= 2:
        shapes.append(("polygon", False, _rectangle(hole[0], hole[1])))
    elif hole and hole[0] > 0:
        shapes.append(("circle", False, 0.0, 0.0, hole[0]))
    return shapes


def _rectangle(width_nm: int, height_nm: int) -> list[tuple[float, float]]:
    w, h = width_nm / 2, height_nm / 2
    return [(-w, -h), (w, -h), (w, h), (-w, h)]


def _obround(width_nm: int, height_nm: int) -> list[tuple]:
    """A stadium: the rectangle between the two end circles, and the circles."""
    if width_nm == height_nm:
        return [("circle", True, 0.0, 0.0, width_nm)]
    if width_nm > height_nm:
        reach, d = (width_nm - height_nm) / 2, height_nm
        return [("polygon", True, _rectangle(width_nm - height_nm, height_nm)),
                ("circle", True, -reach, 0.0, d), ("circle", True, reach, 0.0, d)]
    reach, d = (height_nm - width_nm) / 2, width_nm
    return [("polygon", True, _rectangle(width_nm, height_nm - width_nm)),
            ("circle", True, 0.0, -reach, d), ("circle", True, 0.0, reach, d)]
