"""Vectorised reading of runs of plain coordinate blocks.

Most of a real Gerber file is long runs of `X…Y…D01*` / `D02*` / `D03*` with one
aperture and linear interpolation. Two things make those runs fast:

1. `scan_words` parses all word statements of a stretch of text at once with numpy:
   it finds the letters G X Y I J D, the signed integers after them, and marks the
   statements that are exactly what the reader's `_DATA` pattern accepts (optional
   leading blanks, then G, X, Y, I, J, D in that order, G and D in 1..3). Everything
   else ("other": comments, aperture selects, G36, M02, blanks inside a statement)
   stays with the statement-by-statement path.
2. `read_run` computes the graphics state of a run in one go: the interpolation
   mode, the D code (repeated where omitted) and X/Y are forward fills (X/Y a
   cumulative sum in incremental notation), trailing-zero digits are padded, and a
   PEN_DOWN row precedes every D01 that follows a move or a flash.

Runs it cannot do exactly (single-quadrant arcs, coordinates before any D code,
flashes in regions or of block apertures, scales that need rounding) are left to
the statement-by-statement path, which this module must match row for row: a test
compares both on the whole corpus and on fuzzed files.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from galileo_cnc.program.ops import COLUMNS, NO_TOOL, OpKind
from galileo_cnc.readers.limits import MAX_GERBER_COORD_NM

MIN_RUN = 32  # shorter runs are cheaper statement by statement
CHUNK_STATEMENTS = 8192  # statements scanned at once: bounds the per-character arrays
LETTERS = "GXYIJD"  # the order _DATA accepts
G, X, Y, I, J, D = range(len(LETTERS))
MAX_DIGITS = 12  # a 6.6 format has 12 digits; 12 digits times any nm scale fit int64
ARC_CW, ARC_CCW = int(OpKind.ARC_CW), int(OpKind.ARC_CCW)
_KIND_OF_OPERATION = np.array([0, int(OpKind.LINE), int(OpKind.MOVE), int(OpKind.FLASH)], dtype=np.int64)

# Character classes for code points below 128; everything else is "other".
_CLASS = np.full(128, 0, dtype=np.int8)  # 0 other, 1 digit, 2 sign, 3 letter, 4 blank
_CLASS[ord("0"):ord("9") + 1] = 1
_CLASS[[ord("+"), ord("-")]] = 2
_CLASS[[ord(c) for c in LETTERS]] = 3
_CLASS[[9, 10, 11, 12, 13, 32]] = 4
_RANK = np.full(128, -1, dtype=np.int64)
_RANK[[ord(c) for c in LETTERS]] = np.arange(len(LETTERS))
OTHER, DIGIT, SIGN, LETTER, BLANK = range(5)


@dataclass(slots=True)
class Words:
    """Per statement: is it a plain coordinate block, its letters and their values."""

    plain: np.ndarray    # bool (n,)
    present: np.ndarray  # bool (n, 6), columns in LETTERS order
    value: np.ndarray    # int64 (n, 6), signed integers as written (0 when absent)
    digits: np.ndarray   # int64 (n, 6), how many digits were written (for trailing-zero formats)
    leading_blanks: np.ndarray  # int64 (n,): blanks before each statement's first character


def scan_words(pieces_text: str, count: int) -> Words:
    """Scan `count` statements: the text of pieces joined by '*' (each piece ends at one)."""
    # One byte per character; anything beyond Latin-1 becomes '?', "other" either way.
    codes = np.frombuffer(pieces_text.encode("latin-1", errors="replace"), dtype=np.uint8)
    stars = codes == ord("*")
    statement = np.cumsum(stars, dtype=np.int32) - stars  # the statement of each character
    kind = _CLASS[np.minimum(codes, 127)]
    kind[codes > 127] = OTHER
    kind[stars] = BLANK  # the terminator itself is harmless
    bad = np.zeros(count + 1, dtype=bool)

    # Characters outside the alphabet, and blanks after the statement has begun.
    first_seen = _first_per_statement((kind != BLANK) & ~stars, statement, count)
    blank_inside = (kind == BLANK) & ~stars & (np.arange(len(codes), dtype=np.int32) > first_seen[statement])
    np.logical_or.at(bad, statement[(kind == OTHER) | blank_inside], True)

    letters = np.flatnonzero(kind == LETTER)
    after = np.append(kind, BLANK)[letters + 1]
    signed = after == SIGN
    digit_start = letters + 1 + signed
    # Each letter needs a digit right after it (after the sign, if any) ...
    ok = np.append(kind, BLANK)[np.minimum(digit_start, len(codes))] == DIGIT
    ok &= ~(signed & np.isin(_RANK[codes[letters]], (G, D)))  # G and D take no sign
    np.logical_or.at(bad, statement[letters[~ok]], True)
    # ... and signs only stand right after a letter.
    signs = np.flatnonzero(kind == SIGN)
    before_sign = kind[np.maximum(signs - 1, 0)]
    np.logical_or.at(bad, statement[signs[(before_sign != LETTER) | (signs == 0)]], True)

    # ... and digits only follow a letter, a sign or another digit.
    digit_positions = np.flatnonzero(kind == DIGIT)
    before_digit = np.where(digit_positions > 0, kind[np.maximum(digit_positions - 1, 0)], BLANK)
    np.logical_or.at(bad, statement[digit_positions[~np.isin(before_digit, (LETTER, SIGN, DIGIT))]], True)

    # Digits of token k run from digit_start[k] to the next non-digit.
    not_digit = np.flatnonzero(np.append(kind, OTHER) != DIGIT)
    digit_end = not_digit[np.searchsorted(not_digit, digit_start)]  # exclusive
    lengths = digit_end - digit_start
    too_long = lengths > MAX_DIGITS
    np.logical_or.at(bad, statement[letters[too_long | (lengths <= 0)]], True)
    values = _token_values(codes, digit_start, np.where(too_long | (lengths <= 0), digit_start, digit_end))
    values = np.where(signed & (codes[np.minimum(letters + 1, len(codes) - 1)] == ord("-")), -values, values)

    # Letters in order G X Y I J D, each at most once, in one statement.
    rank = _RANK[codes[letters]]
    owner = statement[letters]
    same = owner[1:] == owner[:-1]
    np.logical_or.at(bad, owner[1:][same & (rank[1:] <= rank[:-1])], True)

    present = np.zeros((count + 1, len(LETTERS)), dtype=bool)
    value = np.zeros((count + 1, len(LETTERS)), dtype=np.int64)
    digits = np.zeros((count + 1, len(LETTERS)), dtype=np.int64)
    present[owner, rank] = True
    value[owner, rank] = values
    digits[owner, rank] = lengths
    # _DATA takes G and D only as 1, 2 or 3: G36, D10 and the like are other statements.
    for column in (G, D):
        out_of_range = present[:, column] & ((value[:, column] < 1) | (value[:, column] > 3))
        bad |= out_of_range
    plain = ~bad & present.any(axis=1)
    statement_start = np.concatenate(([0], np.flatnonzero(stars)[:-1] + 1))[:count]
    leading = np.where(first_seen[:count] < len(codes), first_seen[:count] - statement_start, 0)
    return Words(plain[:count], present[:count], value[:count], digits[:count], leading)


def _first_per_statement(mask: np.ndarray, statement: np.ndarray, count: int) -> np.ndarray:
    """Position of the first True of `mask` in each statement (huge if none)."""
    first = np.full(count + 1, np.iinfo(np.int64).max, dtype=np.int64)
    positions = np.flatnonzero(mask)
    np.minimum.at(first, statement[positions], positions)
    return first


def _token_values(codes: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Integer value of the digit strings codes[starts[k]:ends[k]] (0 when empty)."""
    lengths = ends - starts
    total = int(lengths.sum())
    if total == 0:
        return np.zeros(len(starts), dtype=np.int64)
    owner = np.repeat(np.arange(len(starts)), lengths)
    offset_in_token = np.arange(total) - np.repeat(np.cumsum(lengths) - lengths, lengths)
    positions = np.repeat(starts, lengths) + offset_in_token
    exponent = np.repeat(lengths, lengths) - 1 - offset_in_token
    digits = codes[positions].astype(np.int64) - ord("0")
    values = np.zeros(len(starts), dtype=np.int64)
    np.add.at(values, owner, digits * 10 ** exponent)
    return values


def read_run(reader, words: Words, first: int, stop: int, starts: np.ndarray) -> bool:
    """Emit the rows of statements first..stop-1 (all plain); False if not possible."""
    fmt_x, fmt_y = reader.fmt_x, reader.fmt_y
    if fmt_x is None:
        return False
    present, value = words.present[first:stop], words.value[first:stop]
    digits = words.digits[first:stop]
    everywhere = np.arange(stop - first)
    # Interpolation mode in force at each statement (G01/G02/G03 are modal).
    last_g = np.maximum.accumulate(np.where(present[:, G], everywhere, -1))
    mode = np.where(last_g >= 0, value[np.maximum(last_g, 0), G], reader.interpolation)
    # A bare G0n statement only sets the mode; the others make one operation each.
    active = np.flatnonzero(present[:, X:].any(axis=1))
    if not len(active):
        return False
    present, value, digits, mode, starts = present[active], value[active], digits[active], \
        mode[active], starts[active]
    if _too_big(value, digits, fmt_x, fmt_y):
        return False  # near or beyond the coordinate bound: the one-by-one path names it
    implicit = ~present[:, D]
    if implicit[0] and not reader.dcode:
        return False  # coordinates before any D code: the one-by-one path warns
    # Coordinates without a D code repeat the last one (deprecated, counted).
    last_d = np.maximum.accumulate(np.where(present[:, D], np.arange(len(value)), -1))
    operations = np.where(last_d >= 0, value[np.maximum(last_d, 0), D], int(reader.dcode or 0))
    if not reader.in_region and ((operations == 2) & ~present[:, X] & ~present[:, Y]).any():
        return False  # a D02 naming no coordinate makes no row: the one-by-one path
    draws = operations == 1
    arcs = draws & (mode != 1)
    if arcs.any() and reader.quadrant is None:
        return False  # arcs before G74/G75: the one-by-one path warns
    flashes = operations == 3
    if reader.in_region:
        if flashes.any():
            return False
        tool = NO_TOOL
    else:
        if reader.aperture == NO_TOOL and (operations != 2).any():
            return False
        if reader.aperture in reader.blocks and flashes.any():
            return False
        tool = reader.tool

    x = _modal(present[:, X], _scaled(value[:, X], digits[:, X], fmt_x), reader.x, reader.incremental)
    y = _modal(present[:, Y], _scaled(value[:, Y], digits[:, Y], fmt_y), reader.y, reader.incremental)
    if reader.incremental and max(np.abs(x).max(), np.abs(y).max()) > MAX_GERBER_COORD_NM:
        return False  # the sums leave the bound: the one-by-one path names the statement
    # The pen is down before a D01 only if the previous operation was a D01 too.
    was_drawing = np.concatenate(([reader.pen_down], draws[:-1]))
    pen_down_first = draws & ~was_drawing
    previous_x = np.concatenate(([reader.x], x[:-1]))
    previous_y = np.concatenate(([reader.y], y[:-1]))

    count = len(operations)
    main = np.arange(count) + np.cumsum(pen_down_first)  # row of each statement's own op
    rows = np.zeros((count + int(pen_down_first.sum()), len(COLUMNS)), dtype=np.int64)
    i = np.where(arcs, _scaled(value[:, I], digits[:, I], fmt_x), 0)
    j = np.where(arcs, _scaled(value[:, J], digits[:, J], fmt_y), 0)
    kinds = np.where(arcs, np.where(mode == 2, ARC_CW, ARC_CCW), _KIND_OF_OPERATION[operations])
    if arcs.any() and reader.quadrant == 74:
        if not _single_quadrant(kinds, i, j, arcs, previous_x, previous_y, x, y):
            return False
    if tool is None:
        # The aperture's image under %LM/%LR/%LS, made at the first draw or flash (where
        # the one-by-one path makes it, so an error names that statement).
        drawing = operations != 2
        reader.offset = int(starts[np.argmax(drawing)])
        tool = reader.drawing_tool() if drawing.any() else NO_TOOL
    rows[main, 0] = kinds
    rows[main, 1] = x
    rows[main, 2] = y
    rows[main, 3] = i
    rows[main, 4] = j
    rows[main, 5] = np.where(operations == 2, NO_TOOL, tool)
    rows[main, 7] = starts
    pen_rows = main[pen_down_first] - 1
    rows[pen_rows, 0] = int(OpKind.PEN_DOWN)
    rows[pen_rows, 1] = previous_x[pen_down_first]
    rows[pen_rows, 2] = previous_y[pen_down_first]
    rows[pen_rows, 5] = NO_TOOL
    rows[pen_rows, 7] = starts[pen_down_first]
    reader.rows.frombytes(rows.tobytes())
    if implicit.any():
        reader.offset = int(starts[np.argmax(implicit)])
        reader.warn_many("implicit-D", int(implicit.sum()),
                         "coordinates without a D code repeat the last D code (deprecated)")

    reader.offset = int(starts[-1])
    reader.x, reader.y = int(x[-1]), int(y[-1])
    reader.pen_down = bool(draws[-1])
    reader.interpolation = int(np.where(last_g[-1] >= 0, words.value[first + last_g[-1], G],
                                        reader.interpolation))
    reader.dcode = str(int(operations[-1]))
    return True


def _single_quadrant(kinds, i, j, arcs, sx, sy, ex, ey) -> bool:
    """Resolve G74 arcs in place, exactly as geometry.single_quadrant_centre does:
    of the four signed centres, those spanning at most 90 degrees in the arc's
    direction, and among them the best radius match (first on ties). An arc that
    ends where it starts is a zero-length draw. False if the numbers are too big
    for int64 products (the one-by-one path uses Python integers)."""
    k = np.flatnonzero(arcs)
    ai, aj = np.abs(i[k]), np.abs(j[k])
    dx, dy = ex[k] - sx[k], ey[k] - sy[k]
    if max(ai.max(), aj.max(), np.abs(dx).max(), np.abs(dy).max()) >= 2**30:
        return False
    ci = np.stack([ai, -ai, ai, -ai])  # candidates in single_quadrant_centre's order
    cj = np.stack([aj, aj, -aj, -aj])
    bx, by = dx - ci, dy - cj  # end relative to each candidate centre; start is -c
    cross = (-ci) * by - (-cj) * bx
    dot = (-ci) * bx + (-cj) * by
    clockwise = kinds[k] == ARC_CW
    within = (dot >= 0) & np.where(clockwise, cross <= 0, cross >= 0)
    mismatch = np.abs((ci * ci + cj * cj) - (bx * bx + by * by))
    best = np.where(within.any(axis=0),
                    np.argmin(np.where(within, mismatch, np.iinfo(np.int64).max), axis=0),
                    np.argmin(mismatch, axis=0))
    columns = np.arange(len(k))
    i[k], j[k] = ci[best, columns], cj[best, columns]
    closed = (dx == 0) & (dy == 0)
    kinds[k[closed]] = int(OpKind.LINE)
    i[k[closed]] = 0
    j[k[closed]] = 0
    return True


def _too_big(value: np.ndarray, digits: np.ndarray, fmt_x, fmt_y) -> bool:
    """True if any X, Y, I or J may come near the coordinate bound once scaled: checked
    in float, where nothing wraps, with a margin of two; int64 scaling of what passes
    stays far inside int64."""
    for columns, fmt in (([X, I], fmt_x), ([Y, J], fmt_y)):
        magnitude = np.abs(value[:, columns]).astype(np.float64)
        if fmt.trailing_zeros_omitted:
            width = fmt.integer_digits + fmt.decimal_digits
            magnitude *= 10.0 ** np.maximum(width - digits[:, columns], 0)
        if magnitude.max(initial=0.0) * (fmt.numerator / fmt.denominator) > MAX_GERBER_COORD_NM / 2:
            return True
    return False


def _scaled(numbers: np.ndarray, written: np.ndarray, fmt) -> np.ndarray:
    """Digits as written -> nm, padding on the right where trailing zeros are omitted,
    rounding half away from zero where the scale is not a whole number of nm."""
    if fmt.trailing_zeros_omitted:
        width = fmt.integer_digits + fmt.decimal_digits
        numbers = numbers * 10 ** np.maximum(width - written, 0)
    scaled = numbers * fmt.numerator
    if fmt.denominator == 1:
        return scaled
    twice, d = 2 * np.abs(scaled), fmt.denominator
    return np.sign(scaled) * ((twice + d) // (2 * d))


def _modal(given: np.ndarray, numbers: np.ndarray, current: int, incremental: bool) -> np.ndarray:
    """Coordinates in nm after each statement; a missing value keeps the last one."""
    if incremental:
        return current + np.cumsum(np.where(given, numbers, 0))
    last = np.maximum.accumulate(np.where(given, np.arange(len(given)), -1))
    return np.where(last >= 0, numbers[np.maximum(last, 0)], current)
