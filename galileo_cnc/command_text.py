"""Machine commands and step counts as a user reads them: mm, steps only in brackets.

A command's coordinates are work coordinates (absolute, or relative for Jog); the
travel is checked in machine coordinates. Every text says which.
"""

from __future__ import annotations

from dataclasses import fields

#: argument name -> how it reads: an axis letter (a length) or a word with its unit
_LENGTHS = {"x_steps": "X", "y_steps": "Y", "z_steps": "Z", "i_steps": "I", "j_steps": "J",
            "dx_steps": "dX", "dy_steps": "dY", "dz_steps": "dZ"}


def mm_text(steps: int, steps_per_mm: float) -> str:
    """`12.500 mm` (3 decimals: finer than a step of any profile)."""
    return f"{steps / steps_per_mm:.3f} mm"


def fixed_text(value: float, places: int) -> str:
    """`12.5000`: exactly `places` decimals, and `0.0000`, never `-0.0000`, for a value
    that rounds to zero from below (an offset of -1 nm)."""
    return f"{round(value, places) + 0.0:.{places}f}"


def number_text(value: float) -> str:
    """`0.03125`, `1000000`: up to 5 decimals, never an exponent."""
    text = f"{value:.5f}".rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text


def feed_text(steps_per_s: int, steps_per_mm: float) -> str:
    """`5 mm/s (300 mm/min) [800 steps/s]`."""
    mm_s = steps_per_s / steps_per_mm
    return (f"{number_text(mm_s)} mm/s ({number_text(mm_s * 60)} mm/min) "
            f"[{steps_per_s} steps/s]")


def field_text(name: str, value: int, steps_per_mm: float) -> str:
    """One argument of a command in the user's units: `X 10.000 mm`, `dwell 200 ms`."""
    if name in _LENGTHS:
        return f"{_LENGTHS[name]} {mm_text(value, steps_per_mm)}"
    if name == "feed_steps_per_s":
        return f"feed {number_text(value / steps_per_mm)} mm/s"
    return f"{name.replace('_ms', '')} {value} ms" if name.endswith("ms") else f"{name} {value}"


def command_text(cmd: object, steps_per_mm: float) -> str:
    """`Rapid to X 10.000 mm Y 5.000 mm (work)`, `Jog by dX 1.000 mm (relative)`."""
    name = type(cmd).__name__
    words = [field_text(f.name, getattr(cmd, f.name), steps_per_mm) for f in fields(cmd)
             if getattr(cmd, f.name) is not None]
    if not words:
        return name
    if name == "Jog":
        return f"Jog by {' '.join(words)} (relative)"
    coordinates = any(f.name in _LENGTHS for f in fields(cmd))
    return f"{name} {'to ' if coordinates else ''}{' '.join(words)}" + \
        (" (work)" if coordinates else "")
