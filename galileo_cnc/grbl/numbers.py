"""GRBL's own number arithmetic, mirrored exactly, and the mm text we send it.

GRBL 1.1h on an AVR parses a number with `read_float` (nuts_bolts.c: the digits
as a uint32, at most 8 of them, then scaled by 0.01 and 0.1 in 32-bit float)
and turns mm into steps with `lround(mm * steps_per_mm)` in 32-bit float
(planner.c). `mm_text` picks the shortest decimal text that lands on the
wanted step under that arithmetic, so a job's integer steps survive the trip
through mm exactly.
"""

from __future__ import annotations

import math

import numpy as np

from galileo_cnc.errors import GalileoError

F32 = np.float32
MAX_INT_DIGITS = 8          # nuts_bolts.h
MIN_DECIMALS = 3            # GRBL reports 3; fewer would read oddly in a file
MAX_DECIMALS = 6


class GrblNumberError(GalileoError):
    """No decimal text reaches the wanted step under GRBL's arithmetic."""


def read_float(text: str) -> np.float32:
    """GRBL's read_float on `text` (a plain decimal like "-12.34500")."""
    negative = text.startswith("-")
    digits = text.lstrip("+-")
    intval = 0
    exp = 0
    ndigit = 0
    decimal = False
    for ch in digits:
        if ch == ".":
            if decimal:
                break
            decimal = True
            continue
        if not ch.isdigit():
            break
        ndigit += 1
        if ndigit <= MAX_INT_DIGITS:
            if decimal:
                exp -= 1
            intval = intval * 10 + int(ch)
        elif not decimal:
            exp += 1
    if not ndigit:
        raise ValueError(f"not a number: {text!r}")
    value = F32(intval)
    if value != 0:
        while exp <= -2:
            value = F32(value * F32(0.01))
            exp += 2
        if exp < 0:
            value = F32(value * F32(0.1))
        while exp > 0:
            value = F32(value * F32(10.0))
            exp -= 1
    return F32(-value) if negative else value


def lround_f32(value: np.float32) -> int:
    """avr-libc lround: nearest integer, halves away from zero."""
    magnitude = math.floor(abs(float(value)) + 0.5)
    return -magnitude if value < 0 else magnitude


def grbl_steps(mm_text: str, steps_per_mm: np.float32) -> int:
    """The step GRBL's planner targets for the coordinate `mm_text`."""
    return lround_f32(F32(read_float(mm_text) * steps_per_mm))


def steps_per_mm_f32(setting_text: str) -> np.float32:
    """A `$100=` value as GRBL holds it (it parsed the same text)."""
    return read_float(setting_text)


def mm_text(steps: int, steps_per_mm: np.float32) -> str:
    """The shortest decimal mm text (up to 6 decimals) that GRBL turns into `steps`."""
    mm = steps / float(steps_per_mm)
    for decimals in range(MIN_DECIMALS, MAX_DECIMALS + 1):
        text = _fixed(mm, decimals)
        if _fits(text) and grbl_steps(text, steps_per_mm) == steps:
            # trailing zeros cost wire time; keep them off only if GRBL agrees
            short = text.rstrip("0").rstrip(".") or "0"
            return short if grbl_steps(short, steps_per_mm) == steps else text
    raise GrblNumberError(
        f"step {steps} at {float(steps_per_mm):g} steps/mm has no decimal text GRBL "
        f"reads back as that step (8 significant digits at most)")


def _fixed(value: float, decimals: int) -> str:
    text = f"{value:.{decimals}f}"
    return "0" + text[2:] if text.startswith("-") and float(text) == 0 else text


def _fits(text: str) -> bool:
    """GRBL keeps 8 significant digits; more are dropped, not rounded."""
    return len(text.lstrip("-").replace(".", "").lstrip("0")) <= MAX_INT_DIGITS


def decimal_text_to_nm(text: str) -> int:
    """A reported mm value ("-12.345") as exact integer nanometres."""
    text = text.strip()
    negative = text.startswith("-")
    whole, _, frac = text.lstrip("+-").partition(".")
    if not (whole or frac) or not (whole + frac).isdigit() or len(frac) > 6:
        raise ValueError(f"not a mm value: {text!r}")
    nm = int(whole or "0") * 1_000_000 + int((frac + "000000")[:6])  # 6 decimals of mm = nm
    return -nm if negative else nm
