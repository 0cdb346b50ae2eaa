"""Excellon drill and route files into a DrillFile, exact in integer nm.

One pass over the lines after a short look at the header (the unit, the zeros and
the digits must be known before the first coordinate, and files that do not state
them are judged from their comments and coordinates: dialects.py). The header
(M48 .. % or M95) holds the unit and the tools; the body drills holes (X..Y..),
repeats them (R), cuts G85 slots and routes slots (G00 to the start, M15 down,
G01/G02/G03, M16 up). Errors name file:line:col and stop the read; oddities a drill
file may hold (an unknown M code) are kept as warnings in the metadata.
"""

from __future__ import annotations

import os
import re
from dataclasses import replace
from math import isqrt

from galileo_cnc.errors import ReaderError, SourcePos
from galileo_cnc.program.drills import DrillFile, Hole, Slot
from galileo_cnc.readers import limits
from galileo_cnc.readers.excellon.dialects import (Stated, holesize_comment, infer_format,
                                                    plating_from_name, read_comment)
from galileo_cnc.readers.excellon.numbers import NumberFormat, coordinate_nm, size_nm
from galileo_cnc.readers.excellon.numbers import MAX_DRILL_COORD_NM
from galileo_cnc.readers.gerber.numbers import checked_nm, parse_decimal, round_div, to_nm
from galileo_cnc.readers.source import read_text


class ExcellonError(ReaderError):
    """Malformed Excellon input."""


_UNITS = re.compile(r"(METRIC|INCH)\s*(?:,\s*(LZ|TZ))?\s*(?:,\s*(0*)\.?(0*))?\s*$")
_UNIT_CODE = re.compile(r"M7([12])\s*(?:,\s*(LZ|TZ))?\s*$")
_HEADER_WORD = re.compile(r"[A-Z]{2,}\s*(,.*)?$|[A-Z]\s*,.*$|/.*$")
_FMAT = re.compile(r"FMAT\s*,\s*([12])\s*$")
_ICI = re.compile(r"ICI\s*,\s*(ON|OFF)\s*$")
_TEXT_CODE = re.compile(r"M(?:47|97|98)\s*,")  # operator message, canned text
_WORD = re.compile(r"([A-Z])([+-]?[0-9]*\.?[0-9]*)")
_XY_ONLY = re.compile(r"(?:X([+-]?[\d.]+))?(?:Y([+-]?[\d.]+))?")  # the common line: a hole
_BODY_START = re.compile(r"(?:G0\d|G85|R\d|[XY][+-]?[\d.])")
_GEDA_MIL_TOOL = re.compile(r"T\d+F00S00C\d\.\d{3}\s*$")
_ENDS = {0, 2, 30}              # M00, M02 (FMAT 1), M30: end of program
_IGNORED_G = {4, 40, 41, 42, 45, 46, 47, 48}     # dwell, cutter compensation
_IGNORED_M = {1, 6, 9, 18, 31, 45, 50, 51, 52, 60, 61, 62, 63}
_PATTERN_M = {8, 25, 70, 80, 90}  # patterns, their repeats, swaps and mirrors: not read
_MIL_NM = 25_400
MAX_WORDS = 64          # words on one line: a real one has at most a dozen


def read_excellon(path: str | os.PathLike, text: str | None = None, *,
                  max_ops: int | None = None) -> DrillFile:
    """Read an Excellon drill or route file; `text` if the caller already has it.
    `max_ops` bounds the holes and slots (limits.py, $GALILEO_MAX_OPS)."""
    name = os.fsdecode(path)
    if text is None:
        text = read_text(name, ExcellonError)
    return _Reader(name, text, limits.max_ops(max_ops)).read()


def looks_like_excellon(text: str) -> bool:
    """True if the start of `text` is an Excellon header, tool table or drill body."""
    seen = 0
    for raw in text[:65_536].splitlines()[:400]:
        line = raw.strip().upper()
        if not line or line.startswith(";") or line == "%":
            if re.match(r";\s*T\d+\s+HOLESIZE", line):
                return True
            continue
        if line in ("M48", "M72", "M71") or _UNITS.match(line) or _UNIT_CODE.match(line):
            return True
        if re.match(r"T\d+(?:[FSBHZ][+-]?[\d.]+)*C\d*\.?\d+", line):
            return True
        if re.fullmatch(r"(?:G\d+)?(?:X[+-]?\d+)?(?:Y[+-]?\d+)?", line) and re.search(r"[XY][+-]?\d{4,}$", line):
            return True            # implied-decimal coordinate, which no G-code writes
        seen += 1
        if seen >= 8:
            break
    return False


class _Reader:
    def __init__(self, name: str, text: str, max_items: int):
        self.name = name
        self.lines = text.removeprefix("\ufeff").splitlines()
        self.max_items = max_items
        self.stated = Stated()
        self.fmt = NumberFormat()
        self.result = DrillFile(source=name, line_count=len(self.lines))
        self.warnings: list[str] = []
        self.tool_size: dict[int, int] = {}
        self.tool_plated: dict[int, bool | None] = {}
        self.group_plated: bool | None = None    # Altium ;TYPE= group now open
        self.tool: int | None = None
        self.in_header = False
        self.incremental = False
        self.drilling = True                     # G05/G81 (else route mode, G00)
        self.motion = 0                          # route motion: 0, 1, 2 or 3
        self.down = False                        # M15 .. M16
        self.x = self.y = 0
        self.zero = (0, 0)                       # G93
        self.lineno = 0

    # -- errors -------------------------------------------------------------------
    def error(self, col: int, message: str, text: str = "") -> ExcellonError:
        line = self.lines[self.lineno - 1] if 0 < self.lineno <= len(self.lines) else ""
        return ExcellonError(SourcePos(self.name, self.lineno, col), message, text or line)

    def warn(self, col: int, message: str) -> None:
        if len(self.warnings) < 100:
            self.warnings.append(f"{self.name}:{self.lineno}:{col}: {message}")

    # -- the format ---------------------------------------------------------------
    def settle_format(self) -> None:
        """Units, zeros and digits from the header and comments, else inferred."""
        units = zeros = digits = None
        geda_mils = True
        for raw in self.lines:
            line = raw.strip().upper()
            if line.startswith(";"):
                read_comment(raw.strip(), self.stated)
                if (sized := holesize_comment(raw.strip())) and units is None:
                    units = "mm" if sized[2] == "mm" else "in"
                continue
            if m := _UNITS.match(line):
                units = units or ("mm" if m.group(1) == "METRIC" else "in")
                zeros = zeros or m.group(2)
                if m.group(3) is not None and (m.group(3) or m.group(4)):
                    digits = digits or (len(m.group(3)), len(m.group(4)))
            elif m := _UNIT_CODE.match(line):
                units = units or ("mm" if m.group(1) == "1" else "in")
                zeros = zeros or m.group(2)
            elif line.startswith("T") and "C" in line:
                geda_mils = geda_mils and bool(_GEDA_MIL_TOOL.match(line))
            elif _BODY_START.match(line):
                break
        stated = self.stated
        notes = []
        units = units or stated.units
        if units is None:
            units = "in"
            notes.append("unit not stated: inch (Excellon's default)")
        zeros = zeros or stated.zeros
        digits = digits or stated.digits
        if not stated.generator and geda_mils and units == "in" and zeros == "TZ" and digits is None \
                and any(_GEDA_MIL_TOOL.match(l.strip()) for l in self.lines[:50]):
            stated.generator = "gEDA PCB (mils)"
        zeros, digits, inferred = infer_format(units, zeros, digits, self.lines, stated.generator)
        self.fmt = NumberFormat(units, zeros, digits[0], digits[1], stated.decimal)
        self.result.units = units
        meta = self.result.metadata
        meta["format"] = "decimal" if stated.decimal else self.fmt.describe()
        meta["generator"] = stated.generator
        meta["assumed"] = notes + inferred

    # -- the read -----------------------------------------------------------------
    def read(self) -> DrillFile:
        self.settle_format()
        for self.lineno, raw in enumerate(self.lines, 1):
            if self.line(raw):
                break
        self.finish()
        return self.result

    def line(self, raw: str) -> bool:
        """Read one line; True at the end of the program."""
        stripped = raw.strip()
        if not stripped:
            return False
        col0 = raw.index(stripped[0]) + 1
        if self.drilling and not self.in_header and not self.incremental \
                and (m := _XY_ONLY.fullmatch(stripped)) and m.lastindex:
            return self.fast_hole(m, col0)
        if stripped.startswith(";") or stripped.startswith("("):
            self.comment(stripped)
            return False
        code = stripped.split(";", 1)[0].rstrip().upper()
        if code == "%":
            self.in_header = False
            return False
        if code == "M48":
            self.in_header = True
            return False
        if code == "M95":
            self.in_header = False
            return False
        if m := _UNITS.match(code):
            self.fmt.units = "mm" if m.group(1) == "METRIC" else "in"
            return False
        if m := _UNIT_CODE.match(code):
            self.fmt.units = "mm" if m.group(1) == "1" else "in"
            return False
        if m := _FMAT.match(code):
            self.result.metadata["fmat"] = int(m.group(1))
            return False
        if m := _ICI.match(code):
            self.incremental = m.group(1) == "ON"
            return False
        if _TEXT_CODE.match(code):
            return False
        if _HEADER_WORD.match(code):
            if not self.in_header and not code.startswith("/"):
                self.warn(col0, f"header statement {code[:20]!r} in the body ignored")
            return False
        return self.words(code, col0)

    def fast_hole(self, m: re.Match, col0: int) -> bool:
        """A line of only X and Y while drilling absolute: `words` does the same, slower."""
        x = self.x if m.group(1) is None else self.value((m.group(1), col0), 0) + self.zero[0]
        y = self.y if m.group(2) is None else \
            self.value((m.group(2), col0 + m.start(2) - 1), 0) + self.zero[1]
        if self.zero != (0, 0):
            x, y = self.bounded(x, y, col0)
        self.hole(x, y, col0)
        self.x, self.y = x, y
        return False

    def comment(self, text: str) -> None:
        group = read_comment(text, Stated()) \
            if re.match(r";\s*(TYPE|#@!\s*TA\.AperFunction)", text, re.I) else None
        if group is not None:
            self.group_plated = group
            return
        sized = holesize_comment(text)
        if sized is not None:
            number, size, unit, plated = sized
            try:
                value = parse_decimal(size)
                nm = checked_nm(round_div(value.numerator * _MIL_NM, value.denominator)) \
                    if unit == "mil" else to_nm(value, unit)
            except ValueError:
                return                  # a legend comment we cannot use: no size from it
            self.tool_size.setdefault(number, nm)
            self.tool_plated.setdefault(number, plated)

    def words(self, code: str, col0: int) -> bool:
        words = []
        at = 0
        while at < len(code):
            if code[at] in " \t":
                at += 1
                continue
            m = _WORD.match(code, at)
            if not m:
                raise self.error(col0 + at, f"unexpected {code[at]!r}: an Excellon line is "
                                 "words of a letter and a number (X1.5, T01, G85)")
            if not m.group(2) or m.group(2) in ("+", "-", ".", "+.", "-."):
                raise self.error(col0 + at, f"{m.group(1)} without a number")
            words.append((m.group(1), m.group(2), col0 + at))
            at = m.end()
            if len(words) > MAX_WORDS:
                raise self.error(col0 + at, f"more than {MAX_WORDS} words on one line")
        first: dict[str, tuple[str, int]] = {}
        second: dict[str, tuple[str, int]] = {}
        extra: dict[str, tuple[str, int]] = {}
        g85 = g93 = False
        repeat = None
        tool_word = None
        ended = False
        up_after = False
        for letter, number, col in words:
            if letter in "GMT" and "." in number:
                raise self.error(col, f"{letter}{number}: a code is a whole number")
            if letter == "G":
                code_number = self.small_int(number, col)
                if code_number == 85:
                    g85 = True
                elif code_number == 93:
                    g93 = True
                elif code_number in (0, 1, 2, 3):
                    self.drilling = False
                    self.motion = code_number
                    if code_number == 0:
                        self.down = False
                elif code_number in (5, 81):
                    self.drilling = True
                    self.down = False
                elif code_number == 90:
                    self.incremental = False
                elif code_number == 91:
                    self.incremental = True
                elif code_number not in _IGNORED_G:
                    raise self.error(col, f"G{code_number} is not supported in a drill file "
                                     "(read: G00-G03 routing, G05/G81 drilling, G85 slots, "
                                     "G90/G91, G93)")
            elif letter == "M":
                code_number = self.small_int(number, col)
                if code_number == 2 and any(w[0] in "XY" for w in words):
                    raise self.error(col, "M02 X Y: a pattern repeat; patterns are not read")
                if code_number in _ENDS:
                    ended = True
                elif code_number == 15:
                    self.down = True
                elif code_number in (16, 17):
                    up_after = True
                elif code_number in (71, 72):
                    self.fmt.units = "mm" if code_number == 71 else "in"
                elif code_number == 48:
                    self.in_header = True
                elif code_number == 95:
                    self.in_header = False
                elif code_number in _PATTERN_M:
                    raise self.error(col, f"M{code_number}: patterns (M25 .. M01, M02 X Y "
                                     "repeats, M70/M80/M90 swaps and mirrors) are not read")
                elif code_number not in _IGNORED_M:
                    self.warn(col, f"M{code_number} ignored")
            elif letter == "T":
                tool_word = (number, col)
            elif letter == "R":
                repeat = (self.small_int(number, col), col)
            elif letter in "XY":
                target = second if g85 else first
                if letter in target:
                    raise self.error(col, f"{letter} given twice")
                target[letter] = (number, col)
            elif letter in "IJAC":
                extra[letter] = (number, col)
            elif letter not in "FSBHZNP":
                raise self.error(col, f"{letter}{number}: not an Excellon word")
        if tool_word is not None:
            self.select_tool(tool_word, extra.get("C"))
        elif "C" in extra:
            raise self.error(extra["C"][1], "C (a tool size) without its T")
        if g93:
            self.zero = self.bounded(self.value(first.get("X"), 0), self.value(first.get("Y"), 0),
                                     min((c for _, c in first.values()), default=1))
        elif repeat is not None:
            self.repeat(repeat, first)
        elif g85:
            self.g85_slot(first, second)
        elif first:
            self.move(first, extra)
        elif extra.keys() - {"C"}:
            letter = next(iter(extra.keys() - {"C"}))
            raise self.error(extra[letter][1], f"{letter} without X or Y")
        if up_after:
            self.down = False
        return ended

    def small_int(self, number: str, col: int) -> int:
        digits = number.lstrip("+-")
        if not digits.isdigit() or len(digits) > 9 or number.startswith("-"):
            raise self.error(col, f"{number!r} is not a code number")
        return int(digits)

    # -- tools --------------------------------------------------------------------
    def select_tool(self, word: tuple[str, int], size: tuple[str, int] | None) -> None:
        number = self.small_int(*word)
        if size is not None:
            try:
                nm = size_nm(size[0], self.fmt.units)
            except ValueError as problem:
                raise self.error(size[1], f"tool size: {problem}") from None
            if number not in self.tool_size and len(self.tool_size) >= limits.max_apertures():
                raise self.error(word[1], f"more than {limits.max_apertures():,} tools "
                                 f"(set {limits.MAX_APERTURES_ENV} to raise the limit)")
            self.tool_size[number] = nm
            self.tool_plated[number] = self.group_plated
            if self.in_header:
                return
        if self.in_header:
            return
        if number == 0 and number not in self.tool_size:   # T0: unload (unless defined)
            self.tool = None
            return
        if number not in self.tool_size:
            self.warn(word[1], f"tool T{number:02d} has no size in the file: its holes and "
                      "slots have diameter 0")
            self.tool_size[number] = 0
            self.tool_plated[number] = None
        self.tool = number

    def diameter(self, col: int) -> tuple[int, str, bool | None]:
        if self.tool is None:
            raise self.error(col, "a hole or slot before any tool is selected (T01 ...)")
        return self.tool_size[self.tool], f"T{self.tool:02d}", self.tool_plated.get(self.tool)

    # -- coordinates --------------------------------------------------------------
    def value(self, word: tuple[str, int] | None, default: int) -> int:
        if word is None:
            return default
        try:
            return coordinate_nm(word[0], self.fmt)
        except ValueError as problem:
            raise self.error(word[1] + 1, str(problem)) from None   # at the number

    def point(self, words: dict, from_x: int, from_y: int) -> tuple[int, int]:
        """The point the X/Y words name: absolute (after G93), or from (from_x, from_y)."""
        if self.incremental:
            x, y = from_x + self.value(words.get("X"), 0), from_y + self.value(words.get("Y"), 0)
        else:
            x = self.value(words["X"], 0) + self.zero[0] if "X" in words else from_x
            y = self.value(words["Y"], 0) + self.zero[1] if "Y" in words else from_y
        return self.bounded(x, y, min((c for _, c in words.values()), default=1))

    def bounded(self, x: int, y: int, col: int) -> tuple[int, int]:
        """(x, y), or an error if sums (G91, G93, R, arc centres) took it past the bound."""
        if abs(x) > MAX_DRILL_COORD_NM or abs(y) > MAX_DRILL_COORD_NM:
            raise self.error(col, f"the point ({x / 1e6:g}, {y / 1e6:g}) mm lies more than "
                             f"{MAX_DRILL_COORD_NM // 10**9} m from the origin")
        return x, y

    def count(self, col: int, more: int = 1) -> None:
        if len(self.result.holes) + len(self.result.slots) + more > self.max_items:
            raise self.error(col, limits.ops_message(self.max_items, "the file makes",
                                                     "holes and slots"))

    # -- holes and slots ----------------------------------------------------------
    def hole(self, x: int, y: int, col: int) -> None:
        size, tool, plated = self.diameter(col)
        self.count(col)
        self.result.holes.append(Hole(x, y, size, tool, plated, self.lineno))

    def move(self, words: dict, extra: dict) -> None:
        col = min(c for _, c in words.values())
        x, y = self.point(words, self.x, self.y)
        if self.drilling:
            self.hole(x, y, col)
        elif self.motion == 0 or not self.down:
            pass                                   # travel with the tool up
        elif self.motion == 1:
            self.slot(self.x, self.y, x, y, col)
        else:
            self.arc(x, y, extra, col)
        self.x, self.y = x, y

    def slot(self, x0: int, y0: int, x1: int, y1: int, col: int, arc: str = "",
             cx: int = 0, cy: int = 0) -> None:
        size, tool, plated = self.diameter(col)
        self.count(col)
        self.result.slots.append(Slot(x0, y0, x1, y1, size, tool, plated, self.lineno,
                                      arc, cx, cy))

    def arc(self, x: int, y: int, extra: dict, col: int) -> None:
        direction = "cw" if self.motion == 2 else "ccw"
        if "A" in extra:
            cx, cy = self.bounded(*self.centre_from_radius(x, y, extra["A"], direction), col)
        elif "I" in extra or "J" in extra:
            cx, cy = self.bounded(self.x + self.value(extra.get("I"), 0),
                                  self.y + self.value(extra.get("J"), 0), col)
        else:
            raise self.error(col, f"G0{self.motion} arc without its centre (I/J) or radius (A)")
        self.slot(self.x, self.y, x, y, col, direction, cx, cy)

    def centre_from_radius(self, x: int, y: int, word: tuple[str, int],
                           direction: str) -> tuple[int, int]:
        """The centre of the arc of radius A from here to (x, y): the shorter arc for a
        positive A, the longer for a negative one; rounded to the nm."""
        r = self.value(word, 0)
        dx, dy = x - self.x, y - self.y
        chord2 = dx * dx + dy * dy
        q = 4 * r * r - chord2
        if chord2 == 0 or q < 0:
            raise self.error(word[1], f"an arc of radius {abs(r) / 1e6:g} mm cannot join "
                             f"points {isqrt(chord2) / 1e6:g} mm apart")
        scale = 1 << 20
        root = isqrt(q * scale * scale)                 # sqrt(q), scaled
        denominator = 2 * isqrt(chord2 * scale * scale)
        side = 1 if (direction == "ccw") == (r > 0) else -1   # centre left of the chord
        mx2, my2 = self.x + x, self.y + y
        return (round_div(mx2 * denominator - side * 2 * dy * root, 2 * denominator),
                round_div(my2 * denominator + side * 2 * dx * root, 2 * denominator))

    def g85_slot(self, first: dict, second: dict) -> None:
        col = min(c for _, c in {**first, **second}.values()) if first or second else 1
        x0, y0 = self.point(first, self.x, self.y)
        x1, y1 = self.point(second, x0, y0)
        self.slot(x0, y0, x1, y1, col)
        self.x, self.y = x1, y1

    def repeat(self, word: tuple[int, int], step: dict) -> None:
        times, col = word
        dx, dy = self.value(step.get("X"), 0), self.value(step.get("Y"), 0)
        if not self.drilling:
            raise self.error(col, "a repeat (R) in route mode")
        self.count(col, times)
        self.bounded(self.x + times * dx, self.y + times * dy, col)   # the last, before any
        for _ in range(times):
            self.x += dx
            self.y += dy
            self.hole(self.x, self.y, col)

    # -- the end ------------------------------------------------------------------
    def finish(self) -> None:
        result, stated = self.result, self.stated
        result.tools = {f"T{n:02d}": nm for n, nm in sorted(self.tool_size.items())}
        if stated.plated is not None:
            result.plated, why = stated.plated, stated.plated_from
        else:
            known = {p for p in self.tool_plated.values() if p is not None}
            if len(known) == 1 and None not in self.tool_plated.values():
                result.plated, why = known.pop(), "the tool table"
            else:
                result.plated, why = plating_from_name(self.name), "the file name"
                if known:           # mixed tools: each hole says its own
                    result.plated, why = None, "each tool (mixed)"
        if result.plated is not None or why == "each tool (mixed)":
            result.metadata["plated_from"] = why
        if result.plated is not None:
            result.holes = [h if h.plated is not None else _with_plating(h, result.plated)
                            for h in result.holes]
            result.slots = [s if s.plated is not None else _with_plating(s, result.plated)
                            for s in result.slots]
        result.metadata["warnings"] = self.warnings


def _with_plating(item, plated: bool):
    return replace(item, plated=plated)
