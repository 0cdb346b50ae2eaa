"""Aperture definitions (%AD) turned into `Aperture` objects with sizes in nm."""

from __future__ import annotations

import math
import re
from fractions import Fraction

from galileo_cnc.program.ops import Aperture
from galileo_cnc.readers.gerber.macros import MacroError, MacroTemplate, shapes_extent
from galileo_cnc.readers.gerber.numbers import parse_decimal, to_nm
from galileo_cnc.readers.limits import MAX_ROTATION_DEGREES

STANDARD_SHAPES = {"C": "circle", "R": "rectangle", "O": "obround", "P": "polygon"}
# How many size parameters each standard template takes before the hole.
_SIZE_COUNT = {"C": 1, "R": 2, "O": 2, "P": 1}


_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)")


def parse_parameters(text: str) -> tuple[list[Fraction], bool]:
    """The X-separated parameter list of %AD ('0.5X0.25'), exact.

    Numbers are read the way C's strtod would (gerbv's behaviour), so the glued
    '0.03260.326' of old CAD output gives two numbers; the flag says the list was
    irregular (glued numbers or a trailing 'X') so the reader can warn.
    """
    if not text:
        return [], False
    numbers = _NUMBER.findall(text)
    if not numbers or set(_NUMBER.sub("", text)) - {"X"}:
        raise MacroError(f"expected numbers separated by 'X', got {text!r}")
    irregular = len(numbers) != text.count("X") + 1
    return [parse_decimal(n) for n in numbers], irregular


def define_aperture(code: int, template: str, parameters: list[Fraction], units: str,
                    macros: dict[str, MacroTemplate]) -> Aperture:
    """Build the aperture D`code` from a template name and its parameters."""
    if template in STANDARD_SHAPES:
        return _standard(code, template, parameters, units)
    macro = macros.get(template)
    if macro is None:
        raise MacroError(f"aperture template {template!r} is neither C, R, O, P nor a defined macro")
    shapes = macro.evaluate(parameters, units)
    return Aperture(code, "macro", macro=template, primitives=shapes, extent_nm=shapes_extent(shapes))


def _standard(code: int, template: str, parameters: list[Fraction], units: str) -> Aperture:
    shape = STANDARD_SHAPES[template]
    sizes = _SIZE_COUNT[template]
    if template in "RO" and len(parameters) == 1:
        parameters = [parameters[0], parameters[0]]  # old CAD output: 'R,0.035' is a square
    if len(parameters) < sizes:
        raise MacroError(f"aperture {template} needs {sizes} size parameter(s), got {len(parameters)}")
    if any(p < 0 for p in parameters[:sizes]):
        raise MacroError(f"aperture {template} sizes must not be negative")
    if template == "P":
        if len(parameters) < 2:
            raise MacroError("polygon aperture needs a diameter and a vertex count")
        vertices = int(parameters[1])
        if not 3 <= vertices <= 12:
            raise MacroError(f"polygon aperture needs 3 to 12 vertices, got {vertices}")
        rotation = parameters[2] if len(parameters) > 2 else Fraction(0)
        if abs(rotation) > MAX_ROTATION_DEGREES:
            raise MacroError(f"polygon aperture rotated {float(rotation):g} degrees (at most "
                             f"{MAX_ROTATION_DEGREES} either way)")
        diameter = to_nm(parameters[0], units)
        return Aperture(code, shape, (diameter,), _hole(parameters[3:], units),
                        rotation_udeg=round(rotation * 1_000_000), vertices=vertices,
                        extent_nm=polygon_extent(diameter, vertices, float(rotation)))
    size = tuple(to_nm(p, units) for p in parameters[:sizes])
    half_w = (size[0] + 1) // 2
    half_h = (size[-1] + 1) // 2
    return Aperture(code, shape, size, _hole(parameters[sizes:], units),
                    extent_nm=(-half_w, -half_h, half_w, half_h))


def _hole(parameters: list[Fraction], units: str) -> tuple[int, ...]:
    return tuple(to_nm(p, units) for p in parameters[:2])


def polygon_extent(diameter_nm: int, vertices: int, rotation_deg: float):
    r = diameter_nm / 2
    xs, ys = [], []
    for k in range(vertices):
        angle = math.radians(rotation_deg) + 2 * math.pi * k / vertices
        xs.append(round(r * math.cos(angle)))
        ys.append(round(r * math.sin(angle)))
    return (min(xs), min(ys), max(xs), max(ys))
