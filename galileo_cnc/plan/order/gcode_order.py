"""G-code from elsewhere, reordered only when asked (`--optimize`) and only when safe.

A pen-drawing file is travels, draws and the pen going up and down: its paths may be
drawn in any order and either way round. A milling or laser file carries state
that belongs to where it is in the file (a spindle speed or laser power set between
paths, depth passes at several Z heights, dwells, tool changes, pauses, homing, a
coordinate frame set mid-file, several feeds), and moving its paths about would
break it. `refusal` finds the first such thing (line and column, from the rows and
from the file's words, since the reader folds Z, S and G92 into the rows); when
there is none, `pen_rows` gives the drawing as pure geometry for paths.py:
MOVE and segments, and a pen-down with nothing drawn before the pen lifts (a dot) as
a zero-length LINE, which the planner draws as a dot.
"""

from __future__ import annotations

from decimal import Decimal, InvalidOperation
from pathlib import Path

from galileo_cnc.errors import GalileoError, SourcePos
from galileo_cnc.program.ops import COL, KIND, LINE, TOOL, VALUE, X, Y, OpKind, Program
from galileo_cnc.readers.gcode import codes
from galileo_cnc.readers.gcode.lexer import code_number, split_words

_SEGMENTS = (int(OpKind.LINE), int(OpKind.ARC_CW), int(OpKind.ARC_CCW))
_MOVE, _PEN_DOWN, _PEN_UP = int(OpKind.MOVE), int(OpKind.PEN_DOWN), int(OpKind.PEN_UP)
_FEED, _SELECT, _DWELL = int(OpKind.FEED), int(OpKind.SELECT), int(OpKind.DWELL)

#: G codes whose effect is tied to their place in the file (G4 dwell, G10 offsets,
#: G28/G30 homing, G53 machine coordinates, G92 frames; the reader refuses G55..G59)
_PLACED_G = {"4": "a dwell", "10": "a coordinate offset", "28": "homing",
             "30": "homing", "53": "a move in machine coordinates",
             "92": "a coordinate frame change", "92.1": "a coordinate frame change",
             "92.2": "a coordinate frame change", "92.3": "a coordinate frame change"}
#: M codes a pen plotter's drawing may hold (pen down/up, end, motors)
_PEN_M = set(codes.M_PEN_DOWN + codes.M_PEN_UP + codes.M_END + codes.M_MOTORS)

Refusal = tuple[SourcePos, str]


def refusal(program: Program) -> Refusal | None:
    """Where and why the file cannot be reordered (None: it draws with a pen only)."""
    first_draw = _first_draw_line(program)
    found = _row_refusal(program)
    text = _text_refusal(program, first_draw)
    candidates = [r for r in (found, text) if r is not None]
    return min(candidates, key=lambda r: (r[0].line, r[0].col)) if candidates else None


def pen_rows(program: Program) -> tuple[list[tuple[int, list[int]]], list[tuple[int, list[int]]]]:
    """(lead, rows): the feed and pen selection that hold for the whole file, then its
    drawing as MOVEs, segments and dots (zero-length LINEs), in file order."""
    lead: list[tuple[int, list[int]]] = []
    rows: list[tuple[int, list[int]]] = []
    point = (0, 0)
    dot: tuple[int, list[int]] | None = None     # a pen-down with nothing drawn yet

    def put_dot() -> None:
        nonlocal dot
        if dot is not None:
            index, row = dot
            rows.append((index, _row(row, _MOVE, point)))
            rows.append((index, _row(row, int(OpKind.LINE), point)))
            dot = None

    for index, row in enumerate(program.table.tolist()):
        kind = row[KIND]
        if kind in (_FEED, _SELECT):
            if not any(r[KIND] == kind for _i, r in lead):
                lead.append((index, row))
        elif kind == _PEN_DOWN:
            dot = dot or (index, row)
        elif kind == _PEN_UP:
            put_dot()
        elif kind == _MOVE:
            put_dot()
            rows.append((index, row))
            point = (row[X], row[Y])
        elif kind in _SEGMENTS:
            dot = None
            rows.append((index, row))
            point = (row[X], row[Y])
    put_dot()
    return lead, rows


def _row(row: list[int], kind: int, at: tuple[int, int]) -> list[int]:
    new = [0] * len(row)
    new[KIND], new[X], new[Y], new[TOOL] = kind, at[0], at[1], row[TOOL]
    new[LINE], new[COL] = row[LINE], row[COL]
    return new


def _first_draw_line(program: Program) -> int:
    for row in program.table.tolist():
        if row[KIND] in _SEGMENTS or row[KIND] == _PEN_DOWN:
            return row[LINE]
    return 1 << 62


def _row_refusal(program: Program) -> Refusal | None:
    """Dwells, a second feed, a second pen."""
    feed = tool = None
    for row in program.table.tolist():
        kind, pos = row[KIND], SourcePos(program.source, row[LINE], row[COL])
        if kind == _DWELL:
            return pos, "a dwell (G4)"
        if kind == _FEED:
            if feed is not None and row[VALUE] != feed:
                return pos, "a second feed (F): paths would be drawn at another speed"
            feed = row[VALUE]
        if kind == _SELECT or kind in _SEGMENTS:
            if tool is not None and row[TOOL] != tool:
                return pos, "a tool change (T): paths would be drawn with another tool"
            tool = row[TOOL]
    return None


def _text_refusal(program: Program, first_draw: int) -> Refusal | None:
    """What the reader folds away: S words, Z depths, placed G codes and M codes."""
    path = Path(program.source)
    if not path.is_file():
        return None
    spindle: str | None = None
    depth: Decimal | None = None
    inches = incremental = False
    with open(path, encoding="latin-1") as handle:
        for line_no, raw in enumerate(handle, 1):
            try:
                words = split_words(raw.rstrip("\n"), program.source, line_no)
            except GalileoError:
                continue                        # the reader has said what it thought
            for letter, number, col in words:
                pos = SourcePos(program.source, line_no, col)
                code = code_number(number) if letter in "GM" else None
                if letter == "G" and code in ("20", "21"):
                    inches = code == "20"
                elif letter == "G" and code in ("90", "91"):
                    incremental = code == "91"
                elif letter == "G" and code in _PLACED_G and (code != "92" or
                                                              line_no >= first_draw):
                    return pos, f"G{code} ({_PLACED_G[code]}) ties what follows to its place"
                elif letter == "M" and code in codes.M_END:
                    return None                 # the rest of the file is not read
                elif letter == "M" and code not in _PEN_M:
                    return pos, f"M{code}: machine state (pause, tool, coolant, ...) tied " \
                                "to its place in the file"
                elif letter == "S":
                    if spindle is not None and _number(number) != _number(spindle):
                        return pos, f"S{number} after S{spindle}: a spindle speed or " \
                                    "power that differs between paths"
                    spindle = number
                elif letter == "Z":
                    if incremental:
                        return pos, "an incremental Z move (G91)"
                    z = _number(number) * (Decimal("25.4") if inches else 1)
                    if z is not None and z <= 0:
                        if depth is not None and z != depth:
                            return pos, f"Z{number}: a second drawing depth (depth passes " \
                                        "must stay in their order)"
                        depth = z
    return None


def _number(text: str) -> Decimal:
    try:
        return Decimal(text)
    except InvalidOperation:
        return Decimal(0)
