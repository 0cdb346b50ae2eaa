"""RS-274X / Gerber X2 / X3 reader: text in, `Program` in integer nm out.

The file is cut into statements by one regular expression: `%...%` extended
commands and `...*` word commands. The common case, a coordinate block such as
`X1500Y-200D01*`, takes a fast path (one fullmatch); everything else goes to a
small method per command, found in a dispatch table.

Graphics state follows the Gerber Layer Format Specification (2023.08): modal
coordinates, modal interpolation and quadrant modes, D01/D02/D03, regions,
step-and-repeat, aperture blocks. Deprecated commands that real CAD output still
writes are accepted; the image transforms among them (AS, MI, SF, OF, IR) are
applied to the coordinates at the end, the rest is recorded with a warning.
"""

from __future__ import annotations

import dataclasses
import os
import re
from array import array
from collections import Counter

import numpy as np

from galileo_cnc.errors import GerberError, ReaderWarning, SourcePos
from galileo_cnc.program.geometry import single_quadrant_centre
from galileo_cnc.program.ops import COL as COL_COL
from galileo_cnc.program.ops import LINE as LINE_COL
from galileo_cnc.program.ops import (COLUMNS, KIND, NO_TOOL, POSITIONED_KINDS, TOOL, X, Y,
                                     Aperture, OpKind, Program, ProgramBuilder)
from galileo_cnc.readers import limits
from galileo_cnc.readers.gerber import vectorised as batch_reader
from galileo_cnc.readers.gerber.apertures import define_aperture, parse_parameters
from galileo_cnc.readers.gerber.image import ImageTransform
from galileo_cnc.readers.gerber.load import LoadTransform
from galileo_cnc.readers.gerber.macros import MacroTemplate
from galileo_cnc.readers.gerber.numbers import AxisFormat, decimal_to_nm, parse_decimal
from galileo_cnc.readers.gerber.transformed import derived_key, source_code, transform_aperture

# G04 comments get their own branch: EAGLE writes "%" inside them (G04 #@! %TF...).
_STATEMENT = re.compile(r"\s*(?:G0?4[^*]*\*|%([^%]*)%|([^%*]*)\*)")
_DATA = re.compile(
    r"(?:G0*([123])(?!\d))?(?:X([+-]?\d+))?(?:Y([+-]?\d+))?(?:I([+-]?\d+))?(?:J([+-]?\d+))?(?:D0*([123])(?!\d))?")
_SPACED_DATA = re.compile(r"\s*" + _DATA.pattern)
_PERCENT_IN_COMMENT = re.compile(r"G0?4[^*%]*%")
_SELECT = re.compile(r"(?:G0*(54|55))?D0*(\d+)")
_WORD = re.compile(r"([A-Z])([+-]?(?:\d+\.?\d*|\.\d+))")
_FS = re.compile(r"FS([LTD]?)([AI])(?:N\d+)?(?:G\d+)?X(\d)(\d)Y(\d)(\d)(?:Z\d\d)?(?:D\d+)?(?:M\d+)?$")
_AD = re.compile(r"ADD(\d+)([A-Za-z_.$][^,]*)(?:,(.*))?$", re.S)
_SR = re.compile(r"SR(?:X(\d+))?(?:Y(\d+))?(?:I([+-]?[\d.]+))?(?:J([+-]?[\d.]+))?$")

MOVE, LINE, ARC_CW, ARC_CCW, FLASH = (int(OpKind.MOVE), int(OpKind.LINE), int(OpKind.ARC_CW),
                                      int(OpKind.ARC_CCW), int(OpKind.FLASH))
PEN_DOWN, SELECT = int(OpKind.PEN_DOWN), int(OpKind.SELECT)
NCOL = len(COLUMNS)
MAX_DIGITS = batch_reader.MAX_DIGITS  # a 6.6 format has 12; more is a broken file
MAX_COORDINATE_CHARS = MAX_DIGITS + 1  # and a sign
MAX_COORD_NM = limits.MAX_GERBER_COORD_NM  # 10 m: coordinates beyond are refused
MAX_APERTURE = 2**31 - 1  # aperture numbers are 32-bit integers (Gerber specification)
MAX_CODE_CHARS = limits.MAX_NUMBER_CHARS
# Characters that can follow a stray '*' inside %AD: the parameters go on.
_AD_CONTINUATION = frozenset("0123456789.+-X,")
# X2/X3 attribute commands kept as metadata.
_ATTRIBUTES = ("TF", "TA", "TO", "TD")
# Deprecated commands with no geometric effect on a plot: accepted with a warning.
_IGNORED_DEPRECATED = {"IJ": "image justify", "IO": "image offset", "IC": "input code",
                       "KO": "knock out", "PF": "plot film", "IN": "image name",
                       "LN": "level name", "SM": "symbol mirror", "RO": "rotate image",
                       "PD": "plotter defaults", "FL": "film"}


def read_gerber(source, text: str | None = None, min_run: int = batch_reader.MIN_RUN, *,
                max_ops: int | None = None) -> Program:
    """Read an RS-274X file (or `text`, with `source` naming it) into a Program.

    `min_run` is the shortest run of coordinate blocks read vectorised; tests set it
    to 1 or to a huge number to compare both ways of reading. `max_ops` overrides the
    op limit (readers/limits.py, $GALILEO_MAX_OPS).
    """
    name = str(source)
    if text is None:
        from galileo_cnc.readers.source import read_text

        text = read_text(source, GerberError)
    return GerberReader(name, text, max_ops).run(min_run)


class GerberReader:
    """Graphics state plus the statement loop. One instance reads one file."""

    def __init__(self, name: str, text: str, max_ops: int | None = None):
        self.name = name
        self.text = text
        self.max_ops = limits.max_ops(max_ops)
        self.includes: list[str] = []  # the %IF files being read, innermost last
        self.format_assumed_at: int | None = None  # line of the first coordinate read without %FS
        self.builder = ProgramBuilder(name)
        self.rows = self.builder.rows  # where ops go now (an %AB block redirects it)
        self.warning_counts: Counter[str] = Counter()
        self.metadata: dict = {"attributes": {}, "deprecated": []}
        self.apertures: dict[int, Aperture] = {}
        self.macros: dict[str, MacroTemplate] = {}
        self.blocks: dict[int, np.ndarray] = {}  # %AB aperture blocks, as op rows
        self.block_rows = 0  # rows held in self.blocks (they count against the op limit)
        self.definitions = 0  # %AD and %AM statements read
        self.max_definitions = limits.max_apertures()
        self.block_stack: list[tuple[int, array]] = []
        self.image = ImageTransform()
        self.load = LoadTransform()
        # (file code, transform key) -> (the aperture it was made from, derived key).
        self.derived: dict[tuple, tuple[Aperture, int]] = {}
        self.derived_count = 0
        # Format and units.
        self.units: str | None = None
        self.fs: tuple | None = None  # (trailing, incremental, xi, xd, yi, yd)
        self.fmt_x: AxisFormat | None = None
        self.fmt_y: AxisFormat | None = None
        self.incremental = False
        # Graphics state.
        self.x = self.y = 0
        self.interpolation = 1
        self.quadrant: int | None = None
        self.dcode = ""  # the last D01/D02/D03, as text
        self.aperture = NO_TOOL  # as selected by the file
        # What draws and flashes carry in the tool column: the selected aperture, or its
        # image under the load transform; None until first used (see drawing_tool).
        self.tool: int | None = NO_TOOL
        self.pen_down = False
        self.in_region = False
        # nx, ny, dx, dy, first row, offset of the %SR statement, current point there
        self.step_repeat: tuple[int, int, int, int, int, int, int, int] | None = None
        self.ended = False
        # Rows store the statement's character offset in the `line` column while
        # reading; offsets become line and column once, at the end.
        self.offset = 0

    # --- driver -----------------------------------------------------------------

    def run(self, min_run: int = batch_reader.MIN_RUN) -> Program:
        """Read the whole text. Runs of `min_run` or more plain coordinate blocks
        are read vectorised; a huge `min_run` reads every statement one by one
        (the reference the vectorised path is tested against)."""
        self.min_run = min_run
        end = self._read_statements()
        self._finish(end)
        return self._program()

    def _read_statements(self) -> int:
        """Read the statements of self.text; the offset where reading stopped."""
        end = 0
        for extended, content, start, end in self._statements():
            if extended:
                self.offset = start
                self._extended(content)
            else:
                self._words(content, start, self.min_run)
            if self.ended:
                break
        return end

    def _words(self, pieces: list[str], starts: np.ndarray, min_run: int) -> None:
        """Word statements (the text between two '*', blanks included) in order,
        scanned in chunks so memory stays small whatever the file size."""
        for chunk in range(0, len(pieces), batch_reader.CHUNK_STATEMENTS):
            end = chunk + batch_reader.CHUNK_STATEMENTS
            self._word_chunk(pieces[chunk:end], starts[chunk:end], min_run)
            if len(self.rows) > self.max_ops * NCOL:
                self._too_many_ops(self.rows, "the file")
            if self.ended:
                return

    def _word_chunk(self, pieces: list[str], starts: np.ndarray, min_run: int) -> None:
        """Runs of at least `min_run` plain coordinate blocks are read vectorised
        (gerber/batch.py); the rest, and any run batch declines, one by one."""
        if len(pieces) >= min_run:
            words = batch_reader.scan_words("*".join(pieces) + "*", len(pieces))
            breaks = np.flatnonzero(~words.plain).tolist()
            content_starts = starts + words.leading_blanks
        else:
            words, breaks, content_starts = None, list(range(len(pieces))), starts
        first = 0
        for stop in breaks + [len(pieces)]:
            if stop - first >= min_run and batch_reader.read_run(self, words, first, stop,
                                                                 content_starts[first:stop]):
                first = stop
            for k in range(first, min(stop + 1, len(pieces))):
                piece = pieces[k]
                self.offset = int(starts[k]) + len(piece) - len(piece.lstrip())
                match = _SPACED_DATA.fullmatch(piece)
                if match is not None:
                    self._data(match)
                else:
                    self._word(pieces[k])
                    if self.ended:
                        return
            first = stop + 1

    def _statements(self):
        """(extended?, content, start offset(s), end offset), in file order.

        Extended commands come one by one; word commands come as a list of pieces
        (the text between two '*') with their start offsets, one list per stretch
        between two '%'. Splitting with str.split is several times faster than a
        regular expression; files where a G04 comment holds a '%' (EAGLE writes
        'G04 #@! %TF...') or where a '%' is left open take the regex.
        """
        text = self.text
        parts = text.split("%")
        if len(parts) % 2 == 0 or _PERCENT_IN_COMMENT.search(text):
            yield from self._statements_by_regex()
            return
        offset = 0
        for index, part in enumerate(parts):
            if index % 2:
                yield True, part, offset - 1, offset + len(part) + 1
                offset += len(part) + 1
                continue
            pieces = part.split("*")
            tail = pieces.pop()
            lengths = np.fromiter(map(len, pieces), dtype=np.int64, count=len(pieces)) + 1
            starts = offset + np.concatenate(([0], np.cumsum(lengths)))
            offset = int(starts[-1])
            if pieces:
                yield False, pieces, starts[:-1], offset
            if tail.strip() and index + 1 < len(parts):
                # Text between a '*' and a '%' that ends no statement.
                self._unparsed(offset)
            offset += len(tail) + 1

    def _statements_by_regex(self):
        end = 0
        for m in _STATEMENT.finditer(self.text):
            if m.start() != end:
                self._unparsed(end)  # finditer skipped text that starts no statement
            end = m.end()
            extended, word = m.groups()
            if word is not None:
                yield False, [word], np.array([m.start(2)]), end
            elif extended is not None:
                yield True, extended, m.start(1) - 1, end

    def _position(self) -> tuple[int, int]:
        """(line, column), 1-based, of the statement being read."""
        text, offset = self.text, self.offset
        line = text.count("\n", 0, offset) + 1
        return line, offset - (text.rfind("\n", 0, offset) + 1) + 1

    def error(self, message: str, text: str = "") -> GerberError:
        return GerberError(SourcePos(self.name, *self._position()), message, text)

    def _too_many_ops(self, rows: array, what: str) -> None:
        """Op limit crossed by plain statements: name the first one beyond it."""
        self.offset = rows[self.max_ops * NCOL + LINE_COL]
        raise self.error(limits.ops_message(self.max_ops, f"by this statement {what} makes"))

    def _check_ops(self, extra: int, what: str) -> None:
        """Refuse, at the current statement, `extra` more rows beyond the op limit."""
        if len(self.rows) // NCOL + self.block_rows + extra > self.max_ops:
            raise self.error(limits.ops_message(self.max_ops, what))

    def _out_of_range(self, axis: str, value: int, text: str = "") -> GerberError:
        return self.error(f"{axis} coordinate of {value / 1e9:g} m is out of range (at most "
                          f"{MAX_COORD_NM / 1e9:g} m from the origin)", text)

    def warn(self, key: str, message: str, text: str = "") -> None:
        """Count a tolerated oddity; the first of each kind is kept with its position."""
        self.warn_many(key, 1, message, text)

    def warn_many(self, key: str, count: int, message: str, text: str = "") -> None:
        """`count` oddities of one kind, the first of them at the current statement."""
        if not self.warning_counts[key]:
            # Named by self.name, not the builder's source: an %IF file warns as itself.
            self.builder.warnings.append(ReaderWarning(SourcePos(self.name, *self._position()),
                                                       message, text))
        self.warning_counts[key] += count

    def emit(self, kind: int, x: int = 0, y: int = 0, i: int = 0, j: int = 0,
             tool: int = NO_TOOL, value: int = 0) -> None:
        self.rows.extend((kind, x, y, i, j, tool, value, self.offset, 0))

    # --- coordinate data --------------------------------------------------------

    def _data(self, match: re.Match) -> None:
        """One coordinate block (a match of _DATA; the operation d is '1', '2' or '3').

        The hot path of the reader: straight draws, moves and flashes are written
        out inline, everything else goes through _interpolate and _flash.
        """
        g, xs, ys, is_, js, d = match.groups()
        if g is not None:
            self.interpolation = int(g)
        if d is None:
            if xs is None and ys is None and is_ is None and js is None:
                return  # a bare G01/G02/G03 (or an empty statement)
            if self.dcode:
                self.warn("implicit-D", "coordinates without a D code repeat the last D code (deprecated)")
                d = self.dcode
            else:
                self.warn("no-D", "coordinates before any D code: taken as a move (D02)")
                d = "2"
        else:
            self.dcode = d
        fmt_x, fmt_y = self.fmt_x, self.fmt_y
        if fmt_x is None:
            self._require_format()
            fmt_x, fmt_y = self.fmt_x, self.fmt_y
        x, y = self.x, self.y
        if len(match.string) > MAX_COORDINATE_CHARS and (
                (xs is not None and len(xs) > MAX_COORDINATE_CHARS)
                or (ys is not None and len(ys) > MAX_COORDINATE_CHARS)
                or (is_ is not None and len(is_) > MAX_COORDINATE_CHARS)
                or (js is not None and len(js) > MAX_COORDINATE_CHARS)):
            raise self.error(f"coordinate with more than {MAX_DIGITS} digits", match.string.strip())
        if xs is not None:
            value = int(xs) * fmt_x.numerator if fmt_x.plain else fmt_x.to_nm(xs)
            x = x + value if self.incremental else value
            if not -MAX_COORD_NM <= x <= MAX_COORD_NM:
                raise self._out_of_range("X", x, match.string.strip())
        if ys is not None:
            value = int(ys) * fmt_y.numerator if fmt_y.plain else fmt_y.to_nm(ys)
            y = y + value if self.incremental else value
            if not -MAX_COORD_NM <= y <= MAX_COORD_NM:
                raise self._out_of_range("Y", y, match.string.strip())
        if d == "1":
            if self.interpolation == 1 and not self.in_region and self.aperture != NO_TOOL:
                tool = self.tool
                if tool is None:
                    tool = self.drawing_tool()
                if self.pen_down:
                    self.rows.extend((LINE, x, y, 0, 0, tool, 0, self.offset, 0))
                else:
                    self.rows.extend((PEN_DOWN, self.x, self.y, 0, 0, NO_TOOL, 0, self.offset, 0,
                                      LINE, x, y, 0, 0, tool, 0, self.offset, 0))
                    self.pen_down = True
            else:
                i = fmt_x.to_nm(is_) if is_ else 0
                j = fmt_y.to_nm(js) if js else 0
                if not (-MAX_COORD_NM <= i <= MAX_COORD_NM and -MAX_COORD_NM <= j <= MAX_COORD_NM):
                    raise self._out_of_range("I" if abs(i) > MAX_COORD_NM else "J",
                                             i if abs(i) > MAX_COORD_NM else j, match.string.strip())
                self._interpolate(x, y, i, j)
        elif d == "2":
            # a D02 that names no coordinate goes nowhere: the pen lifts, and no move is
            # made (before the first coordinate there is no current point to go to);
            # in a region it still ends one contour and starts the next
            if xs is not None or ys is not None or self.in_region:
                self.rows.extend((MOVE, x, y, 0, 0, NO_TOOL, 0, self.offset, 0))
            self.pen_down = False
        else:
            self._flash(x, y)
        self.x = x
        self.y = y

    def _require_format(self) -> None:
        if self.fs is None:
            # RS-274-D files and include fragments carry no header.
            self.warn("no-fs", "no %FS before the first coordinate: assuming %FSLAX24Y24*")
            self.fs = (False, 2, 4, 2, 4)
            self.format_assumed_at = self._position()[0]
        if self.units is None:
            self.warn("no-units", "no %MO before the first coordinate: assuming inches")
            self.units = "in"
        self._update_formats()

    def _interpolate(self, x: int, y: int, i: int, j: int) -> None:
        if not self.pen_down:
            self.emit(PEN_DOWN, self.x, self.y)
            self.pen_down = True
        if self.in_region:
            tool = NO_TOOL
        elif self.aperture == NO_TOOL:
            raise self.error("expected an aperture (Dnn) to be selected before drawing")
        else:
            tool = self.drawing_tool()
        mode = self.interpolation
        if mode == 1:
            self.emit(LINE, x, y, tool=tool)
            return
        clockwise = mode == 2
        if self.quadrant is None:
            self.warn("no-quadrant-mode", "arc before any G74/G75: using single-quadrant mode")
            self.quadrant = 74
        if self.quadrant == 74:
            if (x, y) == (self.x, self.y):
                self.emit(LINE, x, y, tool=tool)  # a single-quadrant arc cannot close a circle
                return
            i, j = single_quadrant_centre(self.x, self.y, x, y, i, j, clockwise)
        self.emit(ARC_CW if clockwise else ARC_CCW, x, y, i, j, tool=tool)

    def _flash(self, x: int, y: int) -> None:
        if self.in_region:
            raise self.error("D03 (flash) is not allowed inside a region (G36/G37)")
        if self.aperture == NO_TOOL:
            raise self.error("expected an aperture (Dnn) to be selected before flashing")
        self.pen_down = False
        block = self.blocks.get(self.aperture)
        if block is None:
            self.emit(FLASH, x, y, tool=self.drawing_tool())
            return
        self._check_ops(len(block), f"flashing block aperture D{self.aperture} "
                                    f"({len(block):,} operations) here would make")
        copy = self.load.transform_rows(block)
        if not self.load.is_identity():
            self._transform_tools(copy)
        if len(copy) and (np.abs(copy[:, [X, Y]]).max() + max(abs(x), abs(y)) > MAX_COORD_NM):
            raise self.error(f"flashing block aperture D{self.aperture} here puts its image "
                             f"out of range (more than {MAX_COORD_NM / 1e9:g} m from the origin)")
        moving = np.isin(copy[:, KIND], POSITIONED_KINDS)
        copy[moving, X] += x
        copy[moving, Y] += y
        self.rows.frombytes(memoryview(copy).cast("B"))

    # --- apertures under the load transform ------------------------------------------

    def drawing_tool(self) -> int:
        """The tool code of a draw or flash with the selected aperture now: the aperture
        itself, or its image under the load transform (made once, at the first use)."""
        if self.tool is None:
            self.tool = self._derive(self.aperture, self.load)
        return self.tool

    def _retool(self) -> None:
        """The selection, the load transform or a definition changed: derive anew."""
        plain = self.aperture == NO_TOOL or self.load.is_identity() or self.aperture in self.blocks
        self.tool = self.aperture if plain else None

    def _derive(self, code: int, load: LoadTransform) -> int:
        """The key of aperture `code` under `load` (`code` itself if the image is the
        same, as for a circle only turned). Cached per (aperture, transform); a redefined
        aperture (%AD again) gets a new one."""
        source = self.apertures[code]
        if source.shape == "block" or load.is_identity():
            return code
        cache_key = (code, load.key())
        cached = self.derived.get(cache_key)
        if cached is not None and cached[0] is source:
            return cached[1]
        if self.definitions + self.derived_count >= self.max_definitions:
            # Each new %LR angle makes new images: a file must not grow them without end.
            raise self.error(f"more than {self.max_definitions:,} apertures and aperture images "
                             f"under %LM/%LR/%LS, the limit (set {limits.MAX_APERTURES_ENV}"
                             "=<count> to raise it)")
        key = derived_key(self.derived_count + 1, code)
        try:
            image = transform_aperture(source, load, key)
        except ValueError as problem:
            raise self.error(f"aperture D{source_code(code)} under {load.describe()}: "
                             f"{problem}") from None
        if dataclasses.replace(image, code=code) == source:
            key = code
        else:
            self.derived_count += 1
            self.apertures[key] = image
            derived = self.metadata.setdefault("derived_apertures", {})
            before = derived.get(code)  # an image of an image (a block flashed under a transform)
            derived[key] = (source_code(code), load.describe() if before is None
                            else f"{before[1]}, then {load.describe()}")
        self.derived[cache_key] = (source, key)
        return key

    def _transform_tools(self, rows: np.ndarray) -> None:
        """A block flashed under a load transform: its flashes and draws use their
        apertures' images under it too (on top of any transform inside the block)."""
        drawn = np.isin(rows[:, KIND], (FLASH, LINE, ARC_CW, ARC_CCW)) & (rows[:, TOOL] != NO_TOOL)
        for code in np.unique(rows[drawn, TOOL]).tolist():
            rows[drawn & (rows[:, TOOL] == code), TOOL] = self._derive(code, self.load)

    # --- word commands ------------------------------------------------------------

    def _word(self, word: str) -> None:
        compact = "".join(word.split())
        if not compact or compact.startswith("G04") or (compact.startswith("G4")
                                                         and not compact[2:3].isdigit()):
            return  # empty, or a G04 comment
        handler = _WORD_COMMANDS.get(compact)
        if handler is not None:
            handler(self)
            return
        m = _SELECT.fullmatch(compact)
        if m and len(m.group(2)) <= 10 and int(m.group(2)) >= 10:
            if m.group(1):
                self.warn("G54", f"G{m.group(1)} before an aperture select is deprecated")
            self._select(int(m.group(2)))
            return
        d = _DATA.fullmatch(compact)
        if d is not None:
            self._data(d)
            return
        self._general_word(compact, word)

    def _general_word(self, compact: str, original: str) -> None:
        """Words in unusual order or with decimal points; G codes act before D codes."""
        words = _WORD.findall(compact)
        if sum(len(a) + len(b) for a, b in words) != len(compact):
            raise self.error("expected a Gerber word command (letter followed by a number)", original)
        values: dict[str, str] = {}
        for letter, number in words:
            if len(number) > MAX_CODE_CHARS:
                raise self.error(f"{letter} word with a number of {len(number):,} characters "
                                 f"(at most {MAX_CODE_CHARS})", original)
            if letter == "G":
                code = int(float(number))
                handler = _WORD_COMMANDS.get(f"G{code:02d}")
                if code in (1, 2, 3):
                    self.interpolation = code
                elif handler is not None:
                    handler(self)
                elif code in (54, 55):
                    self.warn("G54", f"G{code} before an aperture select is deprecated")
                else:
                    raise self.error(f"unknown G code G{number}", original)
            elif letter in "XYIJD" and letter not in values:
                values[letter] = number
            elif letter == "M":
                handler = _WORD_COMMANDS.get(f"M{int(float(number)):02d}")
                if handler is None:
                    raise self.error(f"unknown M code M{number}", original)
                handler(self)
            else:
                raise self.error(f"unexpected word {letter}{number}", original)
        d = values.pop("D", None)
        if d is not None and int(float(d)) >= 10:
            self._select(int(float(d)))
            d = None
        if not values and d is None:
            return
        if any("." in v for v in values.values()):
            values = {k: self._decimal_coordinate(k, v) for k, v in values.items()}
        words = "".join(f"{axis}{values[axis]}" for axis in "XYIJ" if axis in values)
        if d is not None:
            words += f"D{int(float(d))}"
        match = _DATA.fullmatch(words)
        if match is None:
            raise self.error("expected coordinates and D01, D02 or D03", original)
        self._data(match)

    def _decimal_coordinate(self, axis: str, number: str) -> str:
        """A coordinate written with a decimal point, re-expressed in %FS digits."""
        self.warn("decimal-coordinate", "coordinate with a decimal point (not allowed by the spec)")
        fmt = self.fmt_x if axis in "XI" else self.fmt_y
        if fmt is None:
            self._require_format()
            fmt = self.fmt_x if axis in "XI" else self.fmt_y
        value = parse_decimal(number) * 10 ** fmt.decimal_digits
        if fmt.trailing_zeros_omitted:
            raise self.error("decimal-point coordinates in a trailing-zero-omission file", number)
        return str(round(value))

    def _select(self, code: int) -> None:
        if code > MAX_APERTURE:
            raise self.error(f"aperture number D{code} is out of range (at most D{MAX_APERTURE})")
        if code not in self.apertures:
            if self.apertures or self.macros:
                raise self.error(f"aperture D{code} is used but not defined (%ADD{code}...)")
            # RS-274-D: the aperture list lived outside the file; a pen draws anyway.
            self.warn("rs274d", f"aperture D{code} is not defined and the file defines none "
                                "(RS-274-D?): using a zero-size round aperture")
            self.apertures[code] = Aperture(code, "circle", (0,))
        self.aperture = code
        self._retool()
        self.emit(SELECT, self.x, self.y, tool=code)

    def _region_begin(self) -> None:
        if self.in_region:
            raise self.error("G36 inside a region: expected G37 first")
        self.in_region = True
        self.pen_down = False
        self.emit(int(OpKind.REGION_BEGIN), self.x, self.y)

    def _region_end(self) -> None:
        if not self.in_region:
            raise self.error("G37 without a G36 before it")
        self.in_region = False
        self.pen_down = False
        self.emit(int(OpKind.REGION_END), self.x, self.y)

    def _set_quadrant(self, mode: int) -> None:
        self.quadrant = mode

    def _deprecated_units(self, units: str) -> None:
        self.warn("G70/G71", "G70/G71 units are deprecated (use %MO)")
        self._set_units(units)

    def _deprecated_notation(self, incremental: bool) -> None:
        self.warn("G90/G91", "G90/G91 notation is deprecated (use %FS)")
        self.incremental = incremental

    def _end(self) -> None:
        if self.in_region:
            raise self.error("region (G36) still open at the end of the file: expected G37 "
                             "before M02")
        self.ended = True

    # --- extended commands --------------------------------------------------------

    def _extended(self, content: str) -> None:
        blocks = content.split("*")
        if blocks[-1].strip():
            self.warn("missing-star", "extended command without '*' before the closing '%'", content)
        else:
            blocks.pop()
        if not blocks:
            return
        head = blocks[0].lstrip()
        if head.startswith("AM"):
            self._macro(head[2:].strip(), blocks[1:])
            return
        if head.startswith("AD") and len(blocks) > 1:
            blocks = self._stray_stars(blocks, content)
        for block in blocks:
            block = block.strip()
            if block:
                self._extended_block(block)

    def _stray_stars(self, blocks: list[str], content: str) -> list[str]:
        """A '*' inside an %AD's parameters ('%ADD10C,0.1*X0.05*%', as some CAD tools
        write) is ignored with a warning when what follows goes on with parameters."""
        merged = [blocks[0]]
        for block in blocks[1:]:
            stripped = block.strip()
            if stripped and stripped[0] in _AD_CONTINUATION and merged[-1].lstrip().startswith("AD"):
                self.warn("ad-stray-star", "stray '*' inside an %AD statement is ignored", content)
                merged[-1] = merged[-1].rstrip() + stripped
            else:
                merged.append(block)
        return merged

    def _extended_block(self, block: str) -> None:
        code = block[:2]
        handler = _EXTENDED_COMMANDS.get(code)
        if handler is not None:
            handler(self, block)
        elif code in _ATTRIBUTES:
            self._attribute(block)
        elif code in _IGNORED_DEPRECATED:
            self.metadata["deprecated"].append(block)
            self.warn(code, f"%{code} ({_IGNORED_DEPRECATED[code]}) is deprecated and ignored", block)
        elif block.startswith("G04") or block.startswith("G4"):
            return
        else:
            raise self.error(f"unknown extended command %{code}", block)

    def _format_spec(self, block: str) -> None:
        m = _FS.match("".join(block.split()))
        if not m:
            raise self.error("expected %FS[L|T][A|I]XnnYnn* (coordinate format)", block)
        zeros, notation, xi, xd, yi, yd = m.groups()
        if zeros == "":
            self.warn("fs-zeros", "%FS without L or T: assuming leading zeros are omitted", block)
        if zeros == "T":
            self.warn("fs-trailing", "trailing zero omission is deprecated", block)
        if notation == "I":
            self.warn("fs-incremental", "incremental notation is deprecated", block)
        if self.format_assumed_at is not None:
            raise self.error(f"coordinates before %FS (from line {self.format_assumed_at}) were "
                             "read with an assumed format: %FS must come before the first "
                             "coordinate", block)
        self.fs = (zeros == "T", int(xi), int(xd), int(yi), int(yd))
        self.incremental = notation == "I"
        self.metadata["format"] = f"{xi}.{xd}"
        self._update_formats()

    def _units_block(self, block: str) -> None:
        units = {"MOMM": "mm", "MOIN": "in"}.get("".join(block.split()))
        if units is None:
            raise self.error("expected %MOMM* or %MOIN*", block)
        self._set_units(units)

    def _set_units(self, units: str) -> None:
        self.units = units
        self._update_formats()

    def _update_formats(self) -> None:
        if self.fs is None or self.units is None:
            return
        trailing, xi, xd, yi, yd = self.fs
        self.fmt_x = AxisFormat.make(xi, xd, trailing, self.units)
        self.fmt_y = AxisFormat.make(yi, yd, trailing, self.units)

    def _aperture_definition(self, block: str) -> None:
        m = _AD.match(block)
        if not m:
            raise self.error("expected %ADDnn<template>[,<parameters>]*", block)
        self._count_definition(block)
        if len(m.group(1)) > 10:
            raise self.error(f"aperture number of {len(m.group(1)):,} digits (at most "
                             f"D{MAX_APERTURE})", block)
        code, template, parameters = int(m.group(1)), m.group(2).strip(), m.group(3)
        if code < 10:
            raise self.error(f"aperture numbers start at D10, got D{code}", block)
        if code > MAX_APERTURE:
            raise self.error(f"aperture number D{code} is out of range (at most D{MAX_APERTURE})",
                             block)
        if self.units is None:
            self.warn("no-units", "no %MO before the first aperture: assuming inches")
            self._set_units("in")
        try:
            values, irregular = parse_parameters("".join((parameters or "").split()))
            if irregular:
                self.warn("ad-parameters", "irregular aperture parameter list "
                                           "(glued numbers or a trailing 'X')", block)
            aperture = define_aperture(code, template, values, self.units, self.macros)
        except ValueError as problem:  # MacroError, or a number out of range
            raise self.error(str(problem), block) from None
        if code in self.apertures:
            self.warn("redefined-aperture", f"aperture D{code} defined again: the new one wins", block)
        self.apertures[code] = aperture
        self._retool()

    def _count_definition(self, block: str) -> None:
        self.definitions += 1
        if self.definitions > self.max_definitions:
            raise self.error(f"more than {self.max_definitions:,} aperture and macro definitions "
                             f"(%AD, %AM), the limit (set {limits.MAX_APERTURES_ENV}=<count> to "
                             "raise it)", block)

    def _macro(self, name: str, body: list[str]) -> None:
        self._count_definition(f"AM{name}")
        if not name:
            raise self.error("expected a macro name after %AM")
        try:
            self.macros[name] = MacroTemplate.parse(name, body)
        except ValueError as problem:  # MacroError, or a number out of range
            raise self.error(str(problem), "*".join(body)) from None

    def _polarity(self, block: str) -> None:
        value = {"LPD": 1, "LPC": 0}.get(block.strip())
        if value is None:
            raise self.error("expected %LPD* or %LPC*", block)
        self.emit(int(OpKind.POLARITY), self.x, self.y, value=value)

    def _step_repeat(self, block: str) -> None:
        m = _SR.match("".join(block.split()))
        if not m:
            raise self.error("expected %SRXnYnIdJd* or %SR*", block)
        self._close_step_repeat()
        nx, ny, di, dj = m.groups()
        if len(nx or "") > 18 or len(ny or "") > 18:
            raise self.error("step-and-repeat count with more than 18 digits", block)
        nx, ny = int(nx or 1), int(ny or 1)
        if nx < 1 or ny < 1:
            raise self.error("step-and-repeat counts must be at least 1", block)
        units = self.units or "in"
        try:
            dx = decimal_to_nm(di, units) if di else 0
            dy = decimal_to_nm(dj, units) if dj else 0
        except ValueError as problem:
            raise self.error(str(problem), block) from None
        if nx * ny > 1:
            self.step_repeat = (nx, ny, dx, dy, len(self.rows) // NCOL, self.offset,
                                self.x, self.y)
            self.pen_down = False  # each copy's first draw then lowers the pen itself

    def _close_step_repeat(self) -> None:
        if self.step_repeat is None:
            return
        nx, ny, dx, dy, first, where, start_x, start_y = self.step_repeat
        self.step_repeat = None
        rows = np.frombuffer(self.rows, dtype=np.int64).reshape(-1, NCOL)[first:].copy()
        if not len(rows):
            return
        here = self.offset
        self.offset = where  # limits are reported at the %SR statement
        self._check_ops((nx * ny - 1) * (len(rows) + 1),
                        f"%SR repeating {len(rows):,} operations {nx:,} x {ny:,} times would make")
        reach = int(np.abs(rows[:, [X, Y]]).max()) + max((nx - 1) * abs(dx), (ny - 1) * abs(dy))
        if reach > MAX_COORD_NM:
            raise self.error(f"%SR repeats the image {nx:,} x {ny:,} times up to "
                             f"{reach / 1e9:g} m from the origin (at most {MAX_COORD_NM / 1e9:g} m)")
        self.offset = here
        # Each copy is the block's rows moved by (ix dx, iy dy) (every row carries the
        # point it happens at), copies in the order ix, then iy, made a slab at a time.
        # A block that starts with a move or a flash goes to its point itself; one that
        # draws from the point where %SR stood gets a pen-up move to that point, moved,
        # first. No other move: the point of a row before any coordinate (a SELECT at
        # 0, 0) is no point of the drawing, and a move there would stretch the job's box
        # and the offset proposed from it.
        positioned = np.flatnonzero(np.isin(rows[:, KIND], POSITIONED_KINDS))
        unit = rows
        if len(positioned) and rows[positioned[0], KIND] in (LINE, ARC_CW, ARC_CCW):
            lead = rows[:1].copy()
            lead[0, :7] = (MOVE, start_x, start_y, 0, 0, NO_TOOL, 0)
            unit = np.concatenate((lead, rows))
        per_slab = max(1, 65_536 // len(unit))
        count = nx * ny - 1
        for start in range(0, count, per_slab):
            index = np.arange(start + 1, min(start + 1 + per_slab, count + 1), dtype=np.int64)
            ix, iy = index // ny, index % ny  # copy k is (k // ny, k % ny); 0 is the block itself
            slab = np.broadcast_to(unit, (len(index),) + unit.shape).copy()
            slab[:, :, X] += (ix * dx)[:, None]
            slab[:, :, Y] += (iy * dy)[:, None]
            self.rows.frombytes(memoryview(slab).cast("B"))
        self.pen_down = False

    def _aperture_block(self, block: str) -> None:
        body = "".join(block.split())
        if body == "AB":
            if not self.block_stack:
                raise self.error("%AB* closes a block that was never opened", block)
            code, outer, (self.x, self.y) = self.block_stack.pop()
            rows = np.frombuffer(self.rows, dtype=np.int64).reshape(-1, NCOL).copy()
            self.block_rows += len(rows) - len(self.blocks.get(code, ()))
            self.blocks[code] = rows
            self.apertures[code] = Aperture(code, "block", extent_nm=_rows_extent(rows))
            self._retool()
            self.rows = outer
            self.pen_down = False
            return
        m = re.fullmatch(r"ABD(\d{1,10})", body)
        if not m or int(m.group(1)) > MAX_APERTURE:
            raise self.error("expected %ABDnn* or %AB* (nn at most 2147483647)", block)
        # A block is a definition: the current point after it is the one before it.
        self.block_stack.append((int(m.group(1)), self.rows, (self.x, self.y)))
        self.rows = array("q")
        self.pen_down = False

    def _include(self, block: str) -> None:
        """%IF<file>*: read another file's statements here (old RS-274X; gerbv reads it).
        The file is found beside this one; its rows carry the %IF statement's position,
        its errors and warnings its own."""
        from galileo_cnc.readers.source import FileAccessError, read_text

        target = block[2:].strip()
        if not target:
            raise self.error("expected a file name after %IF", block)
        if len(self.includes) >= limits.MAX_INCLUDE_DEPTH:
            raise self.error(f"include files (%IF) nested more than {limits.MAX_INCLUDE_DEPTH} "
                             "deep: does a file include itself?", block)
        path = self._include_path(target, block)
        try:
            text = read_text(path, GerberError)
        except FileAccessError as problem:
            raise self.error(f"include file {target!r} (%IF) cannot be read: {problem.why} "
                             f"(looked for {path})", block) from None
        self.warn("IF", "%IF include files are deprecated: the included file is read here", block)
        where, rows, first = self.offset, self.rows, len(self.rows)
        depth = len(self.block_stack)
        outer = self.name, self.text
        self.includes.append(path)
        self.name, self.text = path, text
        end = self._read_statements()
        if not self.ended and text[end:].strip():
            self._unparsed(end)
        self.includes.pop()
        self.name, self.text = outer
        self.offset = where
        if self.rows is not rows or len(self.block_stack) != depth:
            raise self.error("an aperture block (%AB) must open and close in one file", block)
        if len(self.rows) > first:
            view = np.frombuffer(self.rows, dtype=np.int64).reshape(-1, NCOL)
            view[first // NCOL:, LINE_COL] = where  # the included rows sit at the %IF
            view[first // NCOL:, COL_COL] = 0
            del view  # a buffer exported by the array would stop it from growing

    def _include_path(self, target: str, block: str) -> str:
        """The path of an %IF file: relative to the including file and inside its folder
        (subfolders allowed). An absolute path, a drive, a `..` or a link that leads out
        is refused: a board file must not make the reader open files elsewhere."""
        folder = os.path.dirname(self.name) or "."
        parts = re.split(r"[\\/]", target)
        if os.path.isabs(target) or target[:1] in "\\/" or re.match(r"[A-Za-z]:", target) \
                or ".." in parts:
            raise self.error(f"include file {target!r} (%IF) is not inside the folder of "
                             f"{os.path.basename(self.name)}: only a relative path without "
                             "'..' is read (copy the file beside it)", block)
        path = os.path.join(folder, *[part for part in parts if part not in ("", ".")])
        real_folder = os.path.realpath(folder)
        if os.path.commonpath([real_folder, os.path.realpath(path)]) != real_folder:
            raise self.error(f"include file {target!r} (%IF) leads out of the folder of "
                             f"{os.path.basename(self.name)} (a link to "
                             f"{os.path.realpath(path)}): only files inside it are read", block)
        return path

    def _load_transform(self, block: str) -> None:
        self.metadata.setdefault("load_transforms", []).append(block)
        try:
            self.load.apply_command("".join(block.split()))
        except ValueError as problem:
            raise self.error(str(problem), block) from None
        self._retool()

    def _attribute(self, block: str) -> None:
        key, _, value = block[2:].partition(",")
        attributes = self.metadata["attributes"]
        if block[:2] == "TD":
            # %TD deletes aperture and object attributes (all of them without a name).
            for name in [n for n in attributes if n[:2] in ("TA", "TO") and (not key or n[2:] == key)]:
                del attributes[name]
        else:
            self.metadata["attributes"][f"{block[:2]}{key}"] = value

    def _image_parameter(self, block: str) -> None:
        try:
            changed = self.image.apply_command("".join(block.split()), self.units or "in")
        except ValueError as problem:
            raise self.error(str(problem), block) from None
        self.metadata["deprecated"].append(block)
        self.warn(block[:2], f"%{block[:2]} is deprecated"
                  + ("; applied to the coordinates" if changed else "; has no effect here"), block)

    # --- end ----------------------------------------------------------------------

    def _finish(self, end: int) -> None:
        rest = self.text[end:]
        if self.ended:
            if rest.strip():
                self.warn("after-M02", "text after M02 is ignored", rest.strip())
        else:
            if rest.strip():
                self._unparsed(end)
            self.warn("no-M02", "file does not end with M02")
        if self.in_region:
            self.warn("open-region", "region (G36) not closed with G37 before the end")
            self._region_end()
        if self.block_stack:
            raise self.error("aperture block (%AB) not closed before the end")
        self._close_step_repeat()

    def _unparsed(self, end: int) -> None:
        rest = self.text[end:]
        self.offset = end + len(rest) - len(rest.lstrip())
        # nothing after it parses: the file ends inside this statement
        if rest.lstrip().startswith("%"):
            raise self.error("the file ends inside this extended command (no closing '%'): "
                             "is the file cut short?", rest.strip())
        raise self.error("the file ends inside this statement (no closing '*'): is the file "
                         "cut short?", rest.strip())

    def _program(self) -> Program:
        table = self.builder.table()
        _offsets_to_positions(table, self.text)
        if not self.image.is_identity():
            self.image.apply(table)
            self._check_image_range(table)
        self.metadata["warning_counts"] = dict(self.warning_counts)
        self.metadata["image"] = self.image.describe()
        self.metadata["incremental"] = self.incremental
        return Program(self.name, "gerber", self.units or "in", table, apertures=self.apertures,
                       metadata=self.metadata, warnings=self.builder.warnings,
                       line_count=self.text.count("\n") + (0 if self.text.endswith("\n") else 1))


    def _check_image_range(self, table: np.ndarray) -> None:
        """The image transforms (%SF, %OF, ...) may not move anything out of range."""
        if not len(table):
            return
        beyond = np.flatnonzero((np.abs(table[:, [X, Y]]) > MAX_COORD_NM).any(axis=1))
        if len(beyond):
            row = table[beyond[0]]
            raise GerberError(SourcePos(self.name, int(row[LINE_COL]), int(row[COL_COL])),
                              "the deprecated image transforms (%AS, %MI, %SF, %OF, %IR) put "
                              f"this point out of range (more than {MAX_COORD_NM / 1e9:g} m from the origin)")


def _offsets_to_positions(table: np.ndarray, text: str) -> None:
    """Replace the character offsets in the line column by 1-based line and column."""
    if not len(table):
        return
    # One byte per character ('?' for anything beyond Latin-1): offsets stay valid.
    codes = np.frombuffer(text.encode("latin-1", errors="replace"), dtype=np.uint8)
    offsets = table[:, LINE_COL].copy()
    # Position -1 stands for the start of line 1, so line k starts after entry k-1.
    newlines = np.concatenate(([-1], np.flatnonzero(codes == 10)))
    before = np.searchsorted(newlines, offsets) - 1  # newlines before each offset
    line_start = newlines[before] + 1
    table[:, LINE_COL] = before + 1
    table[:, COL_COL] = offsets - line_start + 1


def _rows_extent(rows: np.ndarray) -> tuple[int, int, int, int]:
    drawn = rows[np.isin(rows[:, KIND], POSITIONED_KINDS)]
    if not len(drawn):
        return (0, 0, 0, 0)
    return (int(drawn[:, X].min()), int(drawn[:, Y].min()), int(drawn[:, X].max()), int(drawn[:, Y].max()))


_WORD_COMMANDS = {
    "G01": lambda r: setattr(r, "interpolation", 1),
    "G02": lambda r: setattr(r, "interpolation", 2),
    "G03": lambda r: setattr(r, "interpolation", 3),
    "G36": GerberReader._region_begin,
    "G37": GerberReader._region_end,
    "G74": lambda r: r._set_quadrant(74),
    "G75": lambda r: r._set_quadrant(75),
    "G70": lambda r: r._deprecated_units("in"),
    "G71": lambda r: r._deprecated_units("mm"),
    "G90": lambda r: r._deprecated_notation(False),
    "G91": lambda r: r._deprecated_notation(True),
    "M02": GerberReader._end,
    "M00": GerberReader._end,
    "M01": lambda r: None,
}
for _code in ("G1", "G2", "G3"):
    _WORD_COMMANDS[_code] = _WORD_COMMANDS["G0" + _code[1]]
_WORD_COMMANDS["M2"] = _WORD_COMMANDS["M02"]
_WORD_COMMANDS["M0"] = _WORD_COMMANDS["M00"]

_EXTENDED_COMMANDS = {
    "FS": GerberReader._format_spec,
    "MO": GerberReader._units_block,
    "AD": GerberReader._aperture_definition,
    "LP": GerberReader._polarity,
    "SR": GerberReader._step_repeat,
    "AB": GerberReader._aperture_block,
    "LM": GerberReader._load_transform,
    "LR": GerberReader._load_transform,
    "LS": GerberReader._load_transform,
    "IP": GerberReader._image_parameter,
    "IR": GerberReader._image_parameter,
    "MI": GerberReader._image_parameter,
    "OF": GerberReader._image_parameter,
    "SF": GerberReader._image_parameter,
    "AS": GerberReader._image_parameter,
    "IF": GerberReader._include,
}
