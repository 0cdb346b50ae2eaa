"""Aperture macros (%AM): templates parsed once, evaluated per %AD into shapes in nm.

Arithmetic on parameters and variables is exact (Fractions). Rotations need
trigonometry, so rotated points are computed in float and rounded to the
nanometre: that is the one place the reader leaves integer arithmetic, and the
error is at most half a nanometre per coordinate.

An evaluated macro is a tuple of primitives:
    ("circle", dark, cx_nm, cy_nm, diameter_nm)
    ("polygon", dark, ((x_nm, y_nm), ...))
Thermal and moire primitives are approximated by polygons and circles, which is
all a pen can draw anyway.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from fractions import Fraction

from galileo_cnc.readers.gerber.numbers import MAX_NM, parse_decimal, to_nm
from galileo_cnc.readers.limits import (MAX_EXPRESSION_DEPTH, MAX_MACRO_VALUE_BITS,
                                        MAX_ROTATION_DEGREES)

_TOKEN = re.compile(r"\s*(?:(\d+\.?\d*(?:[eE][+-]?\d+)?|\.\d+(?:[eE][+-]?\d+)?)|\$(\d+)|([-+xX/()]))")
ARC_SEGMENTS_PER_QUARTER = 8
MAX_MOIRE_RINGS = 100


class MacroError(ValueError):
    """A macro that cannot be parsed or evaluated; the reader adds the position."""


_PLAIN_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)$")


@dataclass(frozen=True, slots=True)
class MacroStatement:
    """One block of a macro body: either `$n=expr` or a primitive with expressions.

    Expressions that are plain numbers (most of them: outlines list hundreds of
    coordinates) are parsed once, as Fractions; the rest stay text.
    """

    assign_to: int | None
    code: int | None
    expressions: tuple[str | Fraction, ...]


def _compile(expression: str) -> str | Fraction:
    if _PLAIN_NUMBER.match(expression):
        return parse_decimal(expression)
    _check_expression(expression)
    return expression


@dataclass(frozen=True, slots=True)
class MacroTemplate:
    name: str
    statements: tuple[MacroStatement, ...]

    @classmethod
    def parse(cls, name: str, blocks: list[str]) -> "MacroTemplate":
        statements = []
        for block in blocks:
            block = "".join(block.split())
            if not block or block.startswith("0"):
                continue  # primitive 0 is a comment
            if block.startswith("$"):
                target, sep, expression = block[1:].partition("=")
                if not sep or not target.isdigit():
                    raise MacroError(f"expected '$n=expression' in macro {name}, got {block!r}")
                statements.append(MacroStatement(int(target), None, (_compile(expression),)))
                continue
            code_text, *expressions = block.split(",")
            if not code_text.isdigit():
                raise MacroError(f"expected a primitive code in macro {name}, got {block!r}")
            statements.append(MacroStatement(None, int(code_text), tuple(_compile(e) for e in expressions)))
        return cls(name, tuple(statements))

    def evaluate(self, parameters: list[Fraction], units: str) -> tuple:
        variables = {index + 1: value for index, value in enumerate(parameters)}
        shapes: list[tuple] = []
        for statement in self.statements:
            if statement.assign_to is not None:
                variables[statement.assign_to] = evaluate_expression(statement.expressions[0], variables)
                continue
            values = [evaluate_expression(e, variables) for e in statement.expressions]
            builder, minimum = _PRIMITIVES.get(statement.code, (None, 0))
            if builder is None:
                raise MacroError(f"unknown primitive code {statement.code} in macro {self.name}")
            if statement.code == 4 and len(values) >= 2 and int(values[1]) < 1:
                # the vertex count sizes the coordinate list: never negative or zero
                raise MacroError(f"outline primitive in macro {self.name} needs 1 or more "
                                 f"vertices, got {values[1]}")
            if len(values) < minimum or (statement.code == 4 and len(values) < 2 * int(values[1]) + 4):
                raise MacroError(f"primitive {statement.code} in macro {self.name} has too few "
                                 f"parameters ({len(values)})")
            try:
                shapes.extend(builder(values, units))
            except (OverflowError, ZeroDivisionError):
                raise MacroError(f"primitive {statement.code} in macro {self.name}: "
                                 "a parameter is out of range") from None
        return tuple(shapes)


def _check_expression(text: str) -> None:
    # Parse with all variables = 1 so syntax errors surface at %AM, not at %AD.
    evaluate_expression(text, {}, default=Fraction(1))


def evaluate_expression(text: str | Fraction, variables: dict[int, Fraction],
                        default: Fraction = Fraction(0)) -> Fraction:
    """Evaluate +, -, x (or X), /, parentheses, numbers and $n exactly.

    Undefined variables are 0 (what older CAD output relies on).
    """
    if isinstance(text, Fraction):
        return text
    tokens: list[tuple[str, object]] = []
    position = 0
    text = text.strip()
    while position < len(text):
        m = _TOKEN.match(text, position)
        if not m:
            raise MacroError(f"bad character in expression {text!r} at {position + 1}")
        number, variable, operator = m.groups()
        if number is not None:
            tokens.append(("num", parse_decimal(number)))
        elif variable is not None:
            tokens.append(("num", variables.get(int(variable), default)))
        else:
            tokens.append(("op", operator.lower()))
        position = m.end()
    if not tokens:
        raise MacroError("empty expression")
    parser = _ExpressionParser(tokens, text)
    value = parser.sum()
    if parser.index != len(tokens):
        raise MacroError(f"unexpected {tokens[parser.index][1]!r} in expression {text!r}")
    return value


class _ExpressionParser:
    def __init__(self, tokens, text):
        self.tokens, self.text, self.index = tokens, text, 0

    def _peek(self):
        return self.tokens[self.index] if self.index < len(self.tokens) else ("end", None)

    def _bounded(self, value: Fraction) -> Fraction:
        if max(value.numerator.bit_length(), value.denominator.bit_length()) > MAX_MACRO_VALUE_BITS:
            raise MacroError(f"a value in expression {self.text[:40]!r} grows beyond "
                             f"{MAX_MACRO_VALUE_BITS} bits (about {MAX_MACRO_VALUE_BITS * 3 // 10} "
                             "digits): a macro that multiplies a value again and again?")
        return value

    def sum(self, depth: int = 0) -> Fraction:
        value = self.product(depth)
        while self._peek() in (("op", "+"), ("op", "-")):
            operator = self.tokens[self.index][1]
            self.index += 1
            right = self.product(depth)
            value = self._bounded(value + right if operator == "+" else value - right)
        return value

    def product(self, depth: int = 0) -> Fraction:
        value = self.unary(depth)
        while self._peek() in (("op", "x"), ("op", "/")):
            operator = self.tokens[self.index][1]
            self.index += 1
            right = self.unary(depth)
            if operator == "x":
                value = self._bounded(value * right)
            elif right == 0:
                raise MacroError(f"division by zero in expression {self.text!r}")
            else:
                value = self._bounded(value / right)
        return value

    def unary(self, depth: int = 0) -> Fraction:
        if depth > MAX_EXPRESSION_DEPTH:
            raise MacroError(f"expression nested more than {MAX_EXPRESSION_DEPTH} deep "
                             f"(parentheses and signs) in {self.text[:40]!r}...")
        kind, value = self._peek()
        if (kind, value) in (("op", "-"), ("op", "+")):
            self.index += 1
            operand = self.unary(depth + 1)
            return -operand if value == "-" else operand
        if (kind, value) == ("op", "("):
            self.index += 1
            inner = self.sum(depth + 1)
            if self._peek() != ("op", ")"):
                raise MacroError(f"missing ')' in expression {self.text!r}")
            self.index += 1
            return inner
        if kind == "num":
            self.index += 1
            return value
        raise MacroError(f"expected a number in expression {self.text!r}")


# --- primitives ------------------------------------------------------------------

def _dark(exposure: Fraction) -> bool:
    return exposure != 0


def _place(points, rotation_deg: Fraction, units: str) -> tuple[tuple[int, int], ...]:
    """Rotate points (in file units) about the macro origin and convert to nm.

    Unrotated Fraction points convert exactly; computed (float) points round.
    """
    if abs(rotation_deg) > MAX_ROTATION_DEGREES:
        raise MacroError(f"rotation of {float(rotation_deg):g} degrees (at most "
                         f"{MAX_ROTATION_DEGREES} either way)")
    if rotation_deg % 360 == 0 and all(isinstance(v, Fraction) for p in points for v in p):
        return tuple((to_nm(x, units), to_nm(y, units)) for x, y in points)
    angle = math.radians(float(rotation_deg))
    c, s = math.cos(angle), math.sin(angle)
    scale = to_nm(Fraction(1), units)
    placed = []
    for x, y in points:
        fx, fy = float(x), float(y)
        px, py = (fx * c - fy * s) * scale, (fx * s + fy * c) * scale
        if not (abs(px) <= MAX_NM and abs(py) <= MAX_NM):  # also catches inf and nan
            raise MacroError(f"macro point ({fx:g}, {fy:g}) is out of range")
        placed.append((round(px), round(py)))
    return tuple(placed)


def _circle(v, units):
    exposure, diameter, cx, cy = v[0], v[1], v[2], v[3]
    rotation = v[4] if len(v) > 4 else Fraction(0)
    ((x, y),) = _place([(cx, cy)], rotation, units)
    return [("circle", _dark(exposure), x, y, to_nm(diameter, units))]


def _rectangle(dark, x0, y0, x1, y1, rotation, units):
    return ("polygon", dark, _place([(x0, y0), (x1, y0), (x1, y1), (x0, y1)], rotation, units))


def _vector_line(v, units):
    exposure, width, xs, ys, xe, ye, rotation = v[:7]
    length_sq = (xe - xs) ** 2 + (ye - ys) ** 2
    if length_sq == 0:
        return []
    length = math.sqrt(float(length_sq))
    # Unit normal scaled to half the width; corners in float, rounded by _place.
    nx = -float(ye - ys) / length * float(width) / 2
    ny = float(xe - xs) / length * float(width) / 2
    corners = [(float(xs) + nx, float(ys) + ny), (float(xe) + nx, float(ye) + ny),
               (float(xe) - nx, float(ye) - ny), (float(xs) - nx, float(ys) - ny)]
    return [("polygon", _dark(exposure), _place(corners, rotation, units))]


def _center_line(v, units):
    exposure, width, height, cx, cy = v[:5]
    rotation = v[5] if len(v) > 5 else Fraction(0)
    return [_rectangle(_dark(exposure), cx - width / 2, cy - height / 2,
                       cx + width / 2, cy + height / 2, rotation, units)]


def _lower_left_line(v, units):
    exposure, width, height, x, y = v[:5]
    rotation = v[5] if len(v) > 5 else Fraction(0)
    return [_rectangle(_dark(exposure), x, y, x + width, y + height, rotation, units)]


def _outline(v, units):
    exposure, count = v[0], int(v[1])
    coordinates = v[2:2 + 2 * (count + 1)]
    rotation = v[2 + 2 * (count + 1)] if len(v) > 2 + 2 * (count + 1) else Fraction(0)
    points = list(zip(coordinates[0::2], coordinates[1::2]))
    return [("polygon", _dark(exposure), _place(points, rotation, units))]


def _regular_polygon(v, units):
    exposure, vertices, cx, cy, diameter = v[:5]
    rotation = v[5] if len(v) > 5 else Fraction(0)
    n = int(vertices)
    if not 3 <= n <= 12:
        raise MacroError(f"polygon primitive needs 3 to 12 vertices, got {n}")
    r = float(diameter) / 2
    points = [(float(cx) + r * math.cos(2 * math.pi * k / n),
               float(cy) + r * math.sin(2 * math.pi * k / n)) for k in range(n)]
    return [("polygon", _dark(exposure), _place(points, rotation, units))]


def _ring_sector(cx, cy, r_out, r_in, start, end):
    """Points of an annular sector (floats, file units), angles in radians."""
    steps = max(2, int(ARC_SEGMENTS_PER_QUARTER * (end - start) / (math.pi / 2)))
    outer = [(cx + r_out * math.cos(start + (end - start) * k / steps),
              cy + r_out * math.sin(start + (end - start) * k / steps)) for k in range(steps + 1)]
    inner = [(cx + r_in * math.cos(end - (end - start) * k / steps),
              cy + r_in * math.sin(end - (end - start) * k / steps)) for k in range(steps + 1)]
    return outer + inner


def _thermal(v, units):
    cx, cy, outer, inner, gap = (float(x) for x in v[:5])
    rotation = v[5] if len(v) > 5 else Fraction(0)
    r_out, r_in = outer / 2, inner / 2
    if r_out <= 0:
        return []
    # Half the gap as an angle at the outer and inner radius; use the larger so the
    # gap is never narrower than asked.
    half_gap = math.asin(min(1.0, gap / 2 / max(r_in, 1e-12))) if r_in > 0 else 0.0
    half_gap = max(half_gap, math.asin(min(1.0, gap / 2 / r_out)))
    shapes = []
    for quarter in range(4):
        start = quarter * math.pi / 2 + half_gap
        end = (quarter + 1) * math.pi / 2 - half_gap
        if end > start:
            shapes.append(("polygon", True, _place(_ring_sector(cx, cy, r_out, r_in, start, end),
                                                   rotation, units)))
    return shapes


def _moire(v, units):
    cx, cy, outer, thickness, gap, rings, cross_thickness, cross_length = v[:8]
    rotation = v[8] if len(v) > 8 else Fraction(0)
    shapes = []
    diameter = outer
    if not 0 <= rings <= MAX_MOIRE_RINGS:
        raise MacroError(f"moire primitive with {rings} rings (at most {MAX_MOIRE_RINGS})")
    for _ in range(int(rings)):
        if diameter <= 0:
            break
        ((x, y),) = _place([(cx, cy)], rotation, units)
        shapes.append(("circle", True, x, y, to_nm(diameter, units)))
        inner = diameter - 2 * thickness
        if inner > 0:
            shapes.append(("circle", False, x, y, to_nm(inner, units)))
        diameter = inner - 2 * gap
    half_t, half_l = cross_thickness / 2, cross_length / 2
    shapes.append(_rectangle(True, cx - half_l, cy - half_t, cx + half_l, cy + half_t, rotation, units))
    shapes.append(_rectangle(True, cx - half_t, cy - half_l, cx + half_t, cy + half_l, rotation, units))
    return shapes


# Primitive code -> (builder, fewest parameters it needs).
_PRIMITIVES = {
    1: (_circle, 4), 2: (_vector_line, 7), 20: (_vector_line, 7), 21: (_center_line, 5),
    22: (_lower_left_line, 5), 4: (_outline, 2), 5: (_regular_polygon, 5), 6: (_moire, 8),
    7: (_thermal, 5),
}


def shapes_extent(shapes) -> tuple[int, int, int, int]:
    """Bounding box (nm) of the dark shapes; (0, 0, 0, 0) if none is dark."""
    xs: list[int] = []
    ys: list[int] = []
    for shape in shapes:
        if not shape[1]:
            continue
        if shape[0] == "circle":
            _, _, x, y, d = shape
            r = (d + 1) // 2
            xs += [x - r, x + r]
            ys += [y - r, y + r]
        else:
            xs += [p[0] for p in shape[2]]
            ys += [p[1] for p in shape[2]]
    if not xs:
        return (0, 0, 0, 0)
    return (min(xs), min(ys), max(xs), max(ys))
