"""Scale, rotate and fit a drawing to the machine, exactly in nm, before the offset.

What vpype users do with `scale`/`scaleto`, `rotate` and `layout --fit-to-margins`,
for every front end (`--scale F`, `--rotate 90|180|270`, `--fit`; the console's getg
takes the same options and offers the fit when a drawing is too big):

- the scale is a Fraction read from the decimal the user typed (`0.8` is 4/5, not
  the float 0.8000000000000000444), and each coordinate is multiplied by it and
  rounded once, half away from zero: exact in integer nm;
- the rotation is a quarter turn clockwise as seen on the paper (vpype's `rotate`
  turns clockwise), about the file's origin: (x, y) -> (y, -x) for 90, exact; arcs
  keep their direction (no mirror), centres turn with their points;
- `--fit` is the largest scale (rounded down to 6 decimals, so the user can type it
  again) at which everything the machine visits, apertures included, fits the
  travel with the margin on every side, keeping the aspect: up or down, as vpype's
  layout does.

`mirrored` turns a board's bottom side over about an axis (plan/sides.py), as exact.

Apertures turn and scale with the drawing (readers/gerber/transformed.py makes their
images, exactly at quarter turns). The offset is worked out afterwards, on the
transformed drawing, as for any other.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from fractions import Fraction

from galileo_cnc.errors import GalileoError
from galileo_cnc.program.extents import extents
from galileo_cnc.program.ops import NM_PER_MM, X, Y, Aperture, Program
from galileo_cnc.readers.gerber.load import LoadTransform
from galileo_cnc.readers.gerber.numbers import parse_decimal
from galileo_cnc.readers.gerber.transformed import transform_aperture
from galileo_cnc.readers.limits import MAX_SCALE

#: quarter turns, clockwise on the paper
ROTATIONS = (0, 90, 180, 270)
#: the fit's scale is rounded down to this many decimals (a scale the user can type)
FIT_DECIMALS = 6


class TransformError(GalileoError):
    """A scale or rotation the user gave cannot be used."""


@dataclass(frozen=True)
class Transform:
    """`scale` (exact), `rotate_deg` clockwise; `fit`: the scale is to be worked out
    (asked), or was (resolved by apply_transform, the scale it found)."""

    scale: Fraction = Fraction(1)
    rotate_deg: int = 0
    fit: bool = False

    def __post_init__(self) -> None:
        if self.rotate_deg not in ROTATIONS:
            raise TransformError(f"--rotate: expected 90, 180 or 270 (degrees clockwise), "
                                 f"got {self.rotate_deg}")
        if not 0 < self.scale <= MAX_SCALE:
            raise TransformError(f"--scale: expected a factor above 0 and at most "
                                 f"{MAX_SCALE}, got {scale_text(self.scale)}")

    @classmethod
    def asked(cls, scale: str | None = None, rotate: str | int | None = None,
              fit: bool = False) -> "Transform":
        """From the options' texts; TransformError names the option."""
        if fit and scale is not None:
            raise TransformError("--fit and --scale both set the size: give one")
        return cls(parse_scale(scale) if scale is not None else Fraction(1),
                   parse_rotation(str(rotate)) if rotate is not None else 0, fit)

    @property
    def is_identity(self) -> bool:
        return self.scale == 1 and self.rotate_deg == 0 and not self.fit

    def describe(self) -> str:
        """'scaled x0.8 to fit the travel, rotated 90 degrees clockwise' ('' for none)."""
        parts = []
        if self.scale != 1 or self.fit:
            parts.append(f"scaled x{scale_text(self.scale)}"
                         + (" to fit the travel" if self.fit else ""))
        if self.rotate_deg:
            parts.append(f"rotated {self.rotate_deg} degrees clockwise")
        return ", ".join(parts)


NO_TRANSFORM = Transform()


def parse_scale(text: str) -> Fraction:
    """--scale: a positive decimal ('0.8', '2', '1.25', '125%') as an exact Fraction."""
    body = text.strip()
    percent = body.endswith("%")
    try:
        value = parse_decimal(body[:-1] if percent else body)
    except (ValueError, ArithmeticError):
        raise TransformError(f"--scale: expected a factor such as 0.8 or 80%, got {text!r}") \
            from None
    value = value / 100 if percent else value
    if not 0 < value <= MAX_SCALE:
        raise TransformError(f"--scale: expected a factor above 0 and at most {MAX_SCALE}, "
                             f"got {text!r}")
    return value


def parse_rotation(text: str) -> int:
    """--rotate: 90, 180 or 270 degrees clockwise (0 too; -90, -180, -270 turn
    counter-clockwise, as 270, 180, 90)."""
    try:
        degrees = int(text)
    except ValueError:
        degrees = -1
    if degrees % 90 or not -270 <= degrees <= 270:
        raise TransformError(f"--rotate: expected 90, 180 or 270 (degrees clockwise), "
                             f"got {text!r}")
    return degrees % 360


def scale_text(scale: Fraction) -> str:
    """A scale as the decimal a user types: every digit of a finite decimal (up to
    12), else 9 significant digits."""
    for digits in range(13):
        if (scale * 10 ** digits).denominator == 1:
            whole, frac = divmod(scale.numerator * 10 ** digits // scale.denominator,
                                 10 ** digits)
            return f"{whole}.{frac:0{digits}d}".rstrip("0").rstrip(".") if digits \
                else str(whole)
    return f"{float(scale):.9g}"


def _load(scale: Fraction, rotate_deg: int) -> LoadTransform:
    # Gerber's %LR turns counter-clockwise: a clockwise quarter turn is its 360 - a
    return LoadTransform("N", Fraction((-rotate_deg) % 360), scale)


def transformed(program: Program, scale: Fraction = Fraction(1), rotate_deg: int = 0
                ) -> Program:
    """`program` scaled by `scale` and turned `rotate_deg` clockwise about its origin:
    coordinates, arc centres and apertures; everything else as it was."""
    if scale == 1 and rotate_deg == 0:
        return program
    load = _load(scale, rotate_deg)
    try:
        table = load.transform_rows(program.table)
        apertures = {key: _aperture(aperture, load, key)
                     for key, aperture in program.apertures.items()}
    except (ValueError, OverflowError) as problem:
        raise TransformError(f"{program.source}: {Transform(scale, rotate_deg).describe()}: "
                             f"{problem}") from None
    return dataclasses.replace(program, table=table, apertures=apertures)


def _aperture(aperture: Aperture, load: LoadTransform, key: int) -> Aperture:
    if aperture.shape != "block":
        return transform_aperture(aperture, load, key)
    # a %AB block's rows are in the table already; only its box turns and scales
    x0, y0, x1, y1 = aperture.extent_nm
    xs, ys = load.transform_xy([x0, x1, x0, x1], [y0, y0, y1, y1])
    box = (int(xs.min()), int(ys.min()), int(xs.max()), int(ys.max()))
    return dataclasses.replace(aperture, extent_nm=box)


def reach_box(program: Program) -> tuple[int, int, int, int] | None:
    """Everything the machine visits (moves too) and the apertures' images around it."""
    visited = extents(program, visited=True)
    inked = extents(program, with_apertures=True) if program.apertures else None
    if visited is None or inked is None:
        return visited or inked
    return (min(visited[0], inked[0]), min(visited[1], inked[1]),
            max(visited[2], inked[2]), max(visited[3], inked[3]))


def fit_scale(box: tuple[int, int, int, int] | None, travel_nm: tuple[int, int],
              margin_nm: int) -> Fraction:
    """The largest scale (FIT_DECIMALS decimals, rounded down) that puts `box` inside
    the travel with `margin_nm` on every side; 1 for nothing drawn."""
    if box is None:
        return Fraction(1)
    room = [travel - 2 * margin_nm for travel in travel_nm]
    if min(room) <= 0:
        raise TransformError(f"--fit: the margin of {margin_nm / NM_PER_MM:g} mm leaves no "
                             f"room on the travel")
    sizes = (box[2] - box[0], box[3] - box[1])
    # each end is rounded once after scaling, so the box may grow by 1 nm: into the
    # margin, or without one, it is kept 1 nm short of the travel
    slack = 0 if margin_nm > 0 else 1
    ratios = [Fraction(space - slack, size) for space, size in zip(room, sizes) if size > 0]
    if not ratios:                  # a single point: any scale fits
        return Fraction(1)
    best = min(min(ratios), Fraction(MAX_SCALE))
    unit = 10 ** FIT_DECIMALS
    scale = Fraction(math.floor(best * unit), unit)
    if scale <= 0:
        raise TransformError(f"--fit: the drawing is too large to fit by a scale of "
                             f"{FIT_DECIMALS} decimals")
    return scale


def apply_transform(program: Program, transform: Transform, travel_nm: tuple[int, int],
                    margin_nm: int) -> tuple[Program, Transform]:
    """The program as `transform` asks, and the transform applied (a fit resolved to
    the scale it found, `fit` still set so front ends can say where it came from)."""
    if transform.is_identity:
        return program, transform
    turned = transformed(program, Fraction(1), transform.rotate_deg)
    scale = fit_scale(reach_box(turned), travel_nm, margin_nm) if transform.fit \
        else transform.scale
    done = dataclasses.replace(transform, scale=scale)
    result = transformed(turned, scale, 0)
    # said where the file's own drawing is compared (a preview's pygerber picture)
    return dataclasses.replace(result, metadata={**result.metadata,
                                                 "transform": done.describe()}), done


def mirrored(program: Program, axis: str, twice_nm: int) -> Program:
    """`program` mirrored about the line `axis` = twice_nm / 2 ("x": the vertical line
    at that x, "y": the horizontal one), exactly in nm: x -> twice_nm - x (an axis
    between two nm is exact too), arc centres' offsets and directions turned, every
    aperture's image mirrored with it (the bottom side of a board, plan/sides.py)."""
    if axis not in ("x", "y"):
        raise TransformError(f"--mirror-axis: expected x=MM or y=MM, got {axis!r}")
    load = LoadTransform("X" if axis == "x" else "Y")
    try:
        table = load.transform_rows(program.table)
        apertures = {key: _aperture(aperture, load, key)
                     for key, aperture in program.apertures.items()}
    except (ValueError, OverflowError) as problem:
        raise TransformError(f"{program.source}: mirrored: {problem}") from None
    column = X if axis == "x" else Y
    # transform_rows negated the coordinate; the axis moves it back: 2a - x
    table[:, column] += twice_nm
    return dataclasses.replace(program, table=table, apertures=apertures)
