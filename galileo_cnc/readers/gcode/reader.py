"""Read G-code (the hobby-CNC dialect of GRBL, Marlin and LinuxCNC) into a Program.

The reader interprets the file the way a pen plotter would draw it: positions
are tracked in integer nanometres in the file's own frame (before any G92), Z is
the pen height, and every op keeps the line and column of the word that caused
it. docs/gcode.md describes the dialect and the decisions taken here.
"""

from __future__ import annotations

import io
import os
import re
from itertools import islice
from typing import Iterable, Iterator

from galileo_cnc.errors import GcodeError, SourcePos
from galileo_cnc.program.ops import (COL, COLUMNS, LINE, NM_PER_INCH, NM_PER_MM, NO_TOOL,
                                     OpKind, Program, ProgramBuilder)
from galileo_cnc.readers import limits
from galileo_cnc.readers.gcode import codes
from galileo_cnc.readers.gcode.arcs import r_form_centre_offset, radius_mismatch
from galileo_cnc.readers.gcode.lexer import (MAX_FRACTION_DIGITS, MAX_INTEGER_DIGITS, Word,
                                             code_number, error, has_code, scaled,
                                             split_words, whole_number)

# Positions further than this from the origin are refused: far beyond any
# plotter, and it keeps every intermediate product well inside int64.
MAX_COORD_NM = 10**12  # 1 km

# Plain ints: ProgramBuilder.emit is called once per op.
_MOVE, _LINE, _CW, _CCW = int(OpKind.MOVE), int(OpKind.LINE), int(OpKind.ARC_CW), int(OpKind.ARC_CCW)
_PEN_UP, _PEN_DOWN, _SELECT = int(OpKind.PEN_UP), int(OpKind.PEN_DOWN), int(OpKind.SELECT)
_DWELL, _FEED = int(OpKind.DWELL), int(OpKind.FEED)
_PARAMETER_LETTERS = codes.PARAMETER_LETTERS

# The shape of most lines in a big file: [N..] [G0|G1] [X..] [Y..] [F..] [; ..],
# in millimetres with at most 6 integer and 6 decimal digits (exact in nm without
# rounding). Such lines take a short path, four to five times faster; anything
# else, every error included, goes through the general path, which gives the
# same ops (a property test checks that).
_FAST_NUMBER = r"[ \t]*(?=[-+]?\.?\d)([-+]?\d{0,6})(?:\.(\d{0,6}))?[ \t]*"
_FAST_LINE = re.compile(
    r"[ \t]*(?:[Nn][ \t]*\d{1,12}[ \t]*)?"
    rf"(?:([Gg])0*([01])(?:\.0*)?[ \t]*)?(?:([Xx]){_FAST_NUMBER})?(?:([Yy]){_FAST_NUMBER})?"
    r"(?:([Ff])[ \t]*(\d{1,6}(?:\.\d{0,6})?|\.\d{1,6})[ \t]*)?(?:;.*)?\n?", re.ASCII)


# Lines read between two checks of the op limit (limits.MAX_OPS): no per-line cost.
CHECK_EVERY_LINES = 65_536
# Characters turned into lines at a time: a whole-text io.StringIO takes four bytes a
# character, a 1 MB piece at a time as fast and in constant memory.
_PIECE_CHARS = 1 << 20


def read_gcode(source: str | os.PathLike, text: str | None = None, *,
               max_ops: int | None = None) -> Program:
    """Read a G-code file (or `text`, with `source` naming it in messages).

    `max_ops` overrides the op limit (readers/limits.py, $GALILEO_MAX_OPS).
    """
    name = source if isinstance(source, str) else os.fsdecode(source)
    if text is None:
        from galileo_cnc.readers.source import FileAccessError, read_text

        try:
            # Undecodable bytes become U+FFFD: harmless in comments, an error in code.
            text = read_text(name, GcodeError)
        except FileAccessError as problem:  # missing, not a regular file, too big
            raise GcodeError(SourcePos(name, 0, 0), f"cannot read the file: {problem.why}") from None
    return _Reader(name, limits.max_ops(max_ops)).run(_lines(text.removeprefix("\ufeff")))


def _lines(text: str) -> Iterator[str]:
    """The lines of `text` as io.StringIO(text, newline=None) gives them (\\r\\n and \\r
    read as \\n), a piece at a time; pieces end after a line break."""
    start, size = 0, len(text)
    while start < size:
        end = text.find("\n", start + _PIECE_CHARS)
        if end < 0:
            end = text.find("\r", start + _PIECE_CHARS)  # old Mac line ends only
        end = size if end < 0 else end + 1
        yield from io.StringIO(text[start:end], newline=None)
        start = end


class _Reader:
    """The interpreter's modal state, advanced one line at a time."""

    use_fast_path = True  # tests switch it off to check both paths agree

    def __init__(self, source: str, max_ops: int = limits.MAX_OPS):
        self.source = source
        self.max_ops = max_ops
        self.out = ProgramBuilder(source)
        self.nm_per_unit = NM_PER_MM
        self.file_units: str | None = None
        self.absolute = True
        self.arc_centre_absolute = False
        self.motion = codes.MOTION_RAPID  # GRBL's power-on default
        self.x = self.y = 0  # program frame, nm
        self.offset_x = self.offset_y = 0  # G92 shift: program = written + offset
        self.z: int | None = None  # program frame, unknown until the first Z
        self.offset_z = 0
        self.pen_wanted = False  # what the file last asked for (M3/M5, Z)
        self.pen_down = False  # what the ops emitted so far leave it at
        self.feed_nm_s: int | None = None
        self.tool = NO_TOOL
        self.home_rows: list[int] = []
        self.ended = False  # M2/M30 seen: the rest of the file is ignored
        self.warned_after_end = False
        # Per-line context for messages.
        self.line = 0
        self.raw = ""

    # ---- driver -----------------------------------------------------------

    def run(self, lines: Iterable[str]) -> Program:
        line_no = 0
        fast_line = _FAST_LINE.fullmatch if self.use_fast_path else lambda raw: None
        numbered = enumerate(lines, 1)
        while True:
            before = line_no
            for line_no, raw in islice(numbered, CHECK_EVERY_LINES):
                fast = fast_line(raw)
                if fast and not self.ended and self._fast_line(fast, line_no):
                    continue
                raw = raw.rstrip("\n")
                if self.ended:
                    self._warn_if_code_after_end(line_no, raw)
                    continue
                if "%" in raw and raw.strip() == "%":
                    continue  # tape start/end marker
                words = split_words(raw, self.source, line_no)
                if words:
                    self.line, self.raw = line_no, raw
                    self._execute(words)
            if self.out.count() > self.max_ops:
                self._too_many_ops()
            if line_no - before < CHECK_EVERY_LINES:
                break
        return self.out.build("gcode", self.file_units or "mm", line_count=line_no,
                              metadata={"home_rows": self.home_rows})

    def _too_many_ops(self) -> None:
        """The op limit is crossed: name the line of the first op beyond it."""
        row = self.max_ops * len(COLUMNS)
        line, col = self.out.rows[row + LINE], self.out.rows[row + COL]
        raise GcodeError(SourcePos(self.source, line, col),
                         limits.ops_message(self.max_ops, "by this line the file makes"))

    def _fast_line(self, m: re.Match, line_no: int) -> bool:
        """Run a line of the _FAST_LINE shape; False leaves it to the general path.

        Everything that can refuse the line is checked before any state changes.
        """
        (g, code, x_letter, x_whole, x_fraction, y_letter, y_whole, y_fraction,
         f_letter, f_number) = m.groups()
        mode = code if g else self.motion
        # Literal codes: this runs for almost every line of a big file.
        if (mode != "0" and mode != "1") or self.nm_per_unit != NM_PER_MM:
            return False
        if not (x_letter or y_letter or g or f_letter):
            return False  # blank, comment or line number only
        feed = None
        if f_letter:
            feed = scaled(f_number, NM_PER_MM, 60)
            if feed <= 0:
                return False
        x, y = self.x, self.y
        if x_letter:
            # Exact: '-12' + '5' padded to '-12500000' nm.
            x = int(x_whole + (x_fraction or "").ljust(6, "0"))
            x = x + self.offset_x if self.absolute else self.x + x
        if y_letter:
            y = int(y_whole + (y_fraction or "").ljust(6, "0"))
            y = y + self.offset_y if self.absolute else self.y + y
        if not (-MAX_COORD_NM <= x <= MAX_COORD_NM and -MAX_COORD_NM <= y <= MAX_COORD_NM):
            return False
        if g:
            self.motion = code
        if feed is not None and feed != self.feed_nm_s:
            self.feed_nm_s = feed
            self.out.emit(_FEED, 0, 0, 0, 0, NO_TOOL, feed, line_no, m.start(9) + 1)
        if not (x_letter or y_letter):
            return True
        col = m.start(1 if g else 3 if x_letter else 6) + 1
        if mode == "0":
            self.out.emit(_MOVE, x, y, 0, 0, NO_TOOL, 0, line_no, col)
            self.pen_down = False
        else:
            if self.pen_wanted and not self.pen_down:
                self.pen_down = True
                self.out.emit(_PEN_DOWN, 0, 0, 0, 0, NO_TOOL, 0, line_no, col)
            self.out.emit(_LINE, x, y, 0, 0, self.tool, 0, line_no, col)
        self.x, self.y = x, y
        return True

    def _warn_if_code_after_end(self, line_no: int, raw: str) -> None:
        if self.warned_after_end:
            return
        stripped = raw.strip()
        if stripped and stripped != "%" and has_code(stripped):
            self.out.warn(line_no, len(raw) - len(raw.lstrip()) + 1,
                          "text after the program end (M2/M30) is ignored", raw)
            self.warned_after_end = True

    def _fail(self, col: int, message: str) -> GcodeError:
        return error(self.source, self.line, col, message, self.raw)

    # ---- one line ---------------------------------------------------------
    # Words are (letter, number text, column) tuples; see lexer.Word.

    def _execute(self, words: list[Word]) -> None:
        groups: dict[str, tuple[str, Word]] = {}
        m_words: list[tuple[str, Word]] = []
        params: dict[str, Word] = {}
        for index, word in enumerate(words):
            letter = word[0]
            if letter in _PARAMETER_LETTERS:
                if letter in params:
                    raise self._fail(word[2], f"two {letter} words on one line")
                params[letter] = word
            elif letter == "G":
                self._collect_g(word, groups)
            elif letter == "M":
                key = code_number(word[1])
                if key is None:
                    raise self._fail(word[2], f"expected an M code number, not M{word[1]}")
                m_words.append((key, word))
            elif letter == "N":
                if index:
                    raise self._fail(word[2], "the line number N must be the first word")
                if whole_number(word[1]) is None:
                    raise self._fail(word[2], f"expected a whole line number after 'N', not {word[1]}")
            else:
                raise self._fail(word[2], f"unknown word '{letter}': expected one of G M N "
                                 "X Y Z I J R F P T S")
        # Execution order within a line follows RS274/NGC: units, feed, pen
        # selection, M codes, modes, then G4/G28/G92 or the motion; the end last.
        if groups:
            self._set_modes(groups)
        if "F" in params:
            self._set_feed(params["F"])
        if "T" in params:
            self._select_tool(params["T"])
        if m_words:
            self._m_codes(m_words)
        line_motion = groups.get("motion")
        if line_motion:
            self.motion = line_motion[0]
        non_modal = groups.get("non-modal")
        if "P" in params and (non_modal is None or non_modal[0] != "4"):
            raise self._fail(params["P"][2], "P is only used with G4 (dwell)")
        if non_modal:
            self._non_modal(non_modal[0], non_modal[1], params, line_motion)
        elif self.motion in (codes.MOTION_RAPID, codes.MOTION_LINE):
            self._straight(params, line_motion)
        else:
            self._pen_from_z(params)
            if "X" in params or "Y" in params or "I" in params or "J" in params or "R" in params:
                self._arc(params, line_motion)
        if m_words and any(key in codes.M_END for key, _ in m_words):
            self.ended = True

    def _collect_g(self, word: Word, groups: dict) -> None:
        key = code_number(word[1])
        group = codes.G_GROUPS.get(key)
        if group is None:
            reason = codes.G_REFUSED.get(key) or f"unknown G code G{word[1][:12]}"
            raise self._fail(word[2], reason)
        if group == "no-op":
            return
        if group in groups:
            other = groups[group][1]
            what = "motion codes" if group == "motion" else f"{group} codes"
            raise self._fail(word[2], f"two {what} on one line: G{other[1]} and G{word[1]}")
        groups[group] = (key, word)

    # ---- settings ---------------------------------------------------------

    def _set_modes(self, groups: dict) -> None:
        if "units" in groups:
            units = "in" if groups["units"][0] == "20" else "mm"
            self.nm_per_unit = NM_PER_INCH if units == "in" else NM_PER_MM
            if self.file_units is None:
                self.file_units = units
        if "distance" in groups:
            self.absolute = groups["distance"][0] == "90"
        if "arc-distance" in groups:
            self.arc_centre_absolute = groups["arc-distance"][0] == "90.1"

    def _set_feed(self, word: Word) -> None:
        # F is units per minute; the op wants nm per second, rounded once.
        feed = scaled(word[1], self.nm_per_unit, 60)
        if feed is None or feed > MAX_COORD_NM:
            raise self._fail(word[2], f"feed rate F{word[1][:20]} is out of range")
        if feed <= 0:
            raise self._fail(word[2], f"expected a positive feed rate, not F{word[1]}")
        if feed != self.feed_nm_s:
            self.feed_nm_s = feed
            self.out.emit(_FEED, 0, 0, 0, 0, NO_TOOL, feed, self.line, word[2])

    def _select_tool(self, word: Word) -> None:
        tool = whole_number(word[1])
        if tool is None:
            raise self._fail(word[2], f"expected a whole pen number after 'T', not {word[1][:20]}")
        self.tool = tool
        self.out.emit(_SELECT, 0, 0, 0, 0, tool, 0, self.line, word[2])

    def _m_codes(self, m_words: list) -> None:
        pen_words = [word for key, word in m_words if key in codes.M_PEN]
        if len(pen_words) > 1:
            raise self._fail(pen_words[1][2], "two pen (M3/M4/M5) codes on one line")
        for key, word in m_words:
            if key in codes.M_PEN:
                down = key in codes.M_PEN_DOWN
                self.pen_wanted = self.pen_down = down
                self.out.emit(_PEN_DOWN if down else _PEN_UP, 0, 0, 0, 0, NO_TOOL, 0,
                              self.line, word[2])
            elif key not in codes.M_KNOWN:
                self.out.warn(self.line, word[2], f"unknown M code M{word[1][:12]} is ignored",
                              self.raw)

    # ---- non-modal codes: G4, G28, G92, G92.1 -----------------------------

    def _non_modal(self, key: str, word: Word, params: dict, line_motion) -> None:
        name = f"G{word[1]}"
        if key == "4":
            self._dwell(word, params, line_motion)
            return
        axes = [params[a] for a in "XYZ" if a in params]
        if line_motion and axes:
            raise self._fail(line_motion[1][2], f"{name} and G{line_motion[1][1]} on one line "
                             "both want the axis words")
        self._refuse_arc_words(params, name)
        if key == "28":
            self._home(word, params)
        elif key == "92":
            self._set_position(params)
        elif axes:
            raise self._fail(axes[0][2], "G92.1 (clear the G92 shift) takes no axis words")
        else:
            self.offset_x = self.offset_y = self.offset_z = 0

    def _dwell(self, word: Word, params: dict, line_motion) -> None:
        if line_motion:
            raise self._fail(line_motion[1][2], "G4 (dwell) cannot share a line with a motion code")
        extra = [params[a] for a in "YZIJR" if a in params]
        if extra or ("P" in params and "X" in params):
            bad = extra[0] if extra else params["X"]
            raise self._fail(bad[2], "G4 takes only P (milliseconds) or X (seconds)")
        if "P" in params:
            time, ms = params["P"], scaled(params["P"][1], 1)
        elif "X" in params:
            time, ms = params["X"], scaled(params["X"][1], 1000)
        else:
            raise self._fail(word[2], "G4 needs P (milliseconds) or X (seconds)")
        if ms is None or ms > MAX_COORD_NM or time[1].startswith("-"):
            raise self._fail(time[2], f"expected a dwell time of 0 or more, "
                             f"not {time[0]}{time[1][:20]}")
        self.out.emit(_DWELL, 0, 0, 0, 0, NO_TOOL, ms, self.line, word[2])

    def _home(self, word: Word, params: dict) -> None:
        """G28, as GRBL: through the point X Y Z give, if any, then every axis home.

        Home is the frame's origin in XY, and the top in Z: the pen ends up, and
        drawing resumes only when the file lowers it again. `G28 G91 Z0`, the CAM
        idiom for "retract", therefore lifts the pen rather than lowering it.
        """
        if "Z" in params:
            self._length(params["Z"])  # only an intermediate height: checked, not used
        if "X" in params or "Y" in params:
            x, y = self._target(params)
            if (x, y) != (self.x, self.y):
                self.out.emit(_MOVE, x, y, 0, 0, NO_TOOL, 0, self.line, word[2])
        self.home_rows.append(self.out.count())
        self.out.emit(_MOVE, 0, 0, 0, 0, NO_TOOL, 0, self.line, word[2])
        self.x = self.y = 0
        self.z = None
        self.pen_down = self.pen_wanted = False

    def _set_position(self, params: dict) -> None:
        """G92: the current point now reads as the given coordinates (none: as 0)."""
        if not ("X" in params or "Y" in params or "Z" in params):
            self.offset_x, self.offset_y = self.x, self.y
            return
        if "X" in params:
            self.offset_x = self.x - self._length(params["X"])
        if "Y" in params:
            self.offset_y = self.y - self._length(params["Y"])
        if "Z" in params:
            z = self._length(params["Z"])
            if self.z is None:
                self.z = z
            self.offset_z = self.z - z

    # ---- motion -----------------------------------------------------------

    def _straight(self, params: dict, line_motion) -> None:
        """G0 (travel, pen up) or G1 (draw) to X/Y, with Z as the pen."""
        rapid = self.motion == codes.MOTION_RAPID
        if "I" in params or "J" in params or "R" in params:
            self._refuse_arc_words(params, f"G{self.motion}")
        has_xy = "X" in params or "Y" in params
        # A travel that lowers the pen lowers it on arrival, not before.
        lowering = self._pen_from_z(params, apply=not (rapid and has_xy))
        if not has_xy:
            return
        col = self._motion_col(params, line_motion)
        x, y = self._target(params)
        if rapid:
            self.out.emit(_MOVE, x, y, 0, 0, NO_TOOL, 0, self.line, col)
            self.pen_down = False
            if lowering:
                self._apply_pen(params["Z"][2])
        else:
            self._resume_pen(col)
            self.out.emit(_LINE, x, y, 0, 0, self.tool, 0, self.line, col)
        self.x, self.y = x, y

    def _arc(self, params: dict, line_motion) -> None:
        clockwise = self.motion == codes.MOTION_CW
        col = self._motion_col(params, line_motion)
        x, y = self._target(params)
        dx, dy = x - self.x, y - self.y
        radius_word = params.get("R")
        if radius_word is not None:
            _, text, r_col = radius_word
            if "I" in params or "J" in params:
                raise self._fail(r_col, "an arc takes either R or I/J, not both")
            if dx == 0 and dy == 0:
                raise self._fail(r_col, "an R arc cannot be a full circle (start = end): "
                                 "give the centre with I and J")
            r = self._length(radius_word)
            if r == 0:
                raise self._fail(r_col, "arc with zero radius: R must not be 0")
            offset = r_form_centre_offset(dx, dy, r, clockwise)
            if offset is None:
                raise self._fail(r_col, f"R{text} is too small: the end point is more than "
                                 "two radii away from the start")
            i, j = offset
        else:
            if "I" not in params and "J" not in params:
                raise self._fail(col, f"G{self.motion} needs the centre (I, J) or the radius (R)")
            i, j = self._centre_offset(params)
            mismatch = radius_mismatch(-i, -j, dx - i, dy - j)
            if mismatch is not None:
                raise self._fail(col, f"the end point is not on the arc: its distance from the "
                                 f"centre differs from the start's by {mismatch / NM_PER_MM:.6f} mm")
        self._resume_pen(col)
        self.out.emit(_CW if clockwise else _CCW, x, y, i, j, self.tool, 0, self.line, col)
        self.x, self.y = x, y

    def _centre_offset(self, params: dict) -> tuple[int, int]:
        i_word, j_word = params.get("I"), params.get("J")
        col = (i_word or j_word)[2]
        if self.arc_centre_absolute:
            if i_word is None or j_word is None:
                raise self._fail(col, "with G90.1 (absolute centres) an arc needs both I and J")
            i = self._length(i_word) + self.offset_x - self.x
            j = self._length(j_word) + self.offset_y - self.y
        else:
            i = self._length(i_word) if i_word else 0
            j = self._length(j_word) if j_word else 0
        if i == 0 and j == 0:
            raise self._fail(col, "arc with zero radius: the centre is the start point")
        if abs(self.x + i) > MAX_COORD_NM or abs(self.y + j) > MAX_COORD_NM:
            raise self._fail(col, "arc centre is out of range (more than 1 km from the origin)")
        return i, j

    def _target(self, params: dict) -> tuple[int, int]:
        x, y = self.x, self.y
        word = params.get("X")
        if word is not None:
            value = self._length(word)
            x = value + self.offset_x if self.absolute else x + value
            self._check_range(x, word)
        word = params.get("Y")
        if word is not None:
            value = self._length(word)
            y = value + self.offset_y if self.absolute else y + value
            self._check_range(y, word)
        return x, y

    def _motion_col(self, params: dict, line_motion) -> int:
        """The column of a motion op: its G word, or for a modal line its first axis word."""
        if line_motion:
            return line_motion[1][2]
        return min(params[a][2] for a in "XYIJR" if a in params)

    # ---- pen --------------------------------------------------------------

    def _pen_from_z(self, params: dict, apply: bool = True) -> bool:
        """Track Z (pen height: <= 0 is down); True if the file now wants the pen down.

        With apply, the pen op is emitted now; otherwise the caller emits it
        after the travel on the same line.
        """
        word = params.get("Z")
        if word is None:
            return False
        value = self._length(word)
        if self.absolute:
            self.z = value + self.offset_z
        else:
            if self.z is None:
                self.out.warn(self.line, word[2], "incremental Z before any absolute Z: "
                              "counted from Z0", self.raw)
                self.z = self.offset_z
            self.z += value
        self._check_range(self.z, word)
        self.pen_wanted = self.z - self.offset_z <= 0
        if apply:
            self._apply_pen(word[2])
        return self.pen_wanted

    def _apply_pen(self, col: int) -> None:
        if self.pen_wanted != self.pen_down:
            self.pen_down = self.pen_wanted
            self.out.emit(_PEN_DOWN if self.pen_down else _PEN_UP, 0, 0, 0, 0, NO_TOOL, 0,
                          self.line, col)

    def _resume_pen(self, col: int) -> None:
        """A travel lifted the pen; lower it again if the file still wants it down."""
        if self.pen_wanted and not self.pen_down:
            self.pen_down = True
            self.out.emit(_PEN_DOWN, 0, 0, 0, 0, NO_TOOL, 0, self.line, col)

    # ---- numbers ----------------------------------------------------------

    def _length(self, word: Word) -> int:
        letter, text, col = word
        value = scaled(text, self.nm_per_unit)
        if value is None:
            raise self._fail(col, f"{letter}{text[:20]}...: expected at most "
                             f"{MAX_INTEGER_DIGITS} digits before the point and "
                             f"{MAX_FRACTION_DIGITS} after it")
        if not -MAX_COORD_NM <= value <= MAX_COORD_NM:
            raise self._fail(col, f"{letter}{text} is out of range (more than 1 km)")
        return value

    def _check_range(self, value: int, word: Word) -> None:
        if not -MAX_COORD_NM <= value <= MAX_COORD_NM:
            raise self._fail(word[2], f"{word[0]}{word[1]} takes the position out of range "
                             "(more than 1 km from the origin)")

    def _refuse_arc_words(self, params: dict, code: str) -> None:
        for letter in "IJR":
            if letter in params:
                raise self._fail(params[letter][2], f"{letter} belongs to an arc (G2/G3), "
                                 f"not to {code}")
