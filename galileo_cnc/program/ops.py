"""The Program: what every reader produces and the planner consumes.

A Program is an ordered list of operations in integer nanometres. To keep a
million-operation file small (about 72 bytes an operation) the operations live in
one int64 numpy table with a column per field; `Op` objects are made only when
someone iterates. Each row keeps the line and column it came from, and the
Program keeps the file name, so any operation can be traced back to its source.

Semantics of the operation kinds (the planner relies on them):

- MOVE:      travel to (x, y) with the pen up (the planner lifts it first).
- LINE:      straight move to (x, y) at the feed rate with the pen as it is.
- ARC_CW/CCW: circular move to (x, y) around centre = start + (i, j), at feed.
             Start == end means a full circle.
- FLASH:     expose aperture `tool` at (x, y) (pen down, dwell, pen up).
- PEN_UP / PEN_DOWN: change the pen state without moving.
- SELECT:    switch to aperture/pen `tool`.
- DWELL:     wait `value` milliseconds.
- FEED:      set the feed rate to `value` nm/s.
- REGION_BEGIN / REGION_END: the MOVE/LINE/ARC ops between them outline a
             filled Gerber region (G36/G37).
- POLARITY:  `value` 1 = dark, 0 = clear for what follows (Gerber %LP).

LINE, ARC and FLASH rows carry the aperture in force in `tool`, so work can be
grouped per aperture without replaying the program.
"""

from __future__ import annotations

from array import array
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Iterator

import numpy as np

from galileo_cnc.errors import ReaderWarning, SourcePos

NM_PER_MM = 1_000_000
NM_PER_INCH = 25_400_000


class OpKind(IntEnum):
    MOVE = 0
    LINE = 1
    ARC_CW = 2
    ARC_CCW = 3
    FLASH = 4
    PEN_UP = 5
    PEN_DOWN = 6
    SELECT = 7
    DWELL = 8
    FEED = 9
    REGION_BEGIN = 10
    REGION_END = 11
    POLARITY = 12


# Kinds whose (x, y) is a place the head goes to; other rows carry the current point.
POSITIONED_KINDS = tuple(int(k) for k in (OpKind.MOVE, OpKind.LINE, OpKind.ARC_CW,
                                          OpKind.ARC_CCW, OpKind.FLASH))

# Column order of Program.table.
COLUMNS = ("kind", "x_nm", "y_nm", "i_nm", "j_nm", "tool", "value", "line", "col")
KIND, X, Y, I, J, TOOL, VALUE, LINE, COL = range(len(COLUMNS))
NO_TOOL = -1


@dataclass(frozen=True, slots=True)
class Op:
    """One operation, materialised from a Program row."""

    kind: OpKind
    x_nm: int = 0
    y_nm: int = 0
    i_nm: int = 0
    j_nm: int = 0
    tool: int = NO_TOOL
    value: int = 0
    pos: SourcePos | None = None


@dataclass(frozen=True, slots=True)
class Aperture:
    """A Gerber aperture (or a G-code pen), sizes in nm.

    `shape` is one of circle, rectangle, obround, polygon, macro. For macros,
    `primitives` holds the evaluated shapes (see gerber.macros) and `macro` names
    the template. `extent_nm` is (xmin, ymin, xmax, ymax) relative to the flash
    point, used for bounding boxes that include aperture size.
    """

    code: int
    shape: str
    params_nm: tuple[int, ...] = ()
    hole_nm: tuple[int, ...] = ()
    rotation_udeg: int = 0
    vertices: int = 0
    macro: str | None = None
    primitives: tuple = ()
    extent_nm: tuple[int, int, int, int] = (0, 0, 0, 0)

    def describe(self) -> str:
        """Human text for prompts, e.g. '0.254 mm round'."""
        def mm(nm: int) -> str:
            return f"{nm / NM_PER_MM:.4f}".rstrip("0").rstrip(".")

        p = self.params_nm
        if self.shape == "circle":
            return f"{mm(p[0])} mm round"
        if self.shape in ("rectangle", "obround"):
            return f"{mm(p[0])} x {mm(p[1])} mm {self.shape}"
        if self.shape == "polygon":
            return f"{mm(p[0])} mm {self.vertices}-gon"
        width = self.extent_nm[2] - self.extent_nm[0]
        height = self.extent_nm[3] - self.extent_nm[1]
        return f"macro {self.macro} ({mm(width)} x {mm(height)} mm)"


@dataclass(slots=True)
class Program:
    """A read file: the op table plus what was learned about the file."""

    source: str
    format: str  # "gerber" or "gcode"
    units: str  # the file's own units, "mm" or "in"
    table: np.ndarray  # shape (N, len(COLUMNS)), int64
    apertures: dict[int, Aperture] = field(default_factory=dict)
    metadata: dict = field(default_factory=dict)
    warnings: list[ReaderWarning] = field(default_factory=list)
    line_count: int = 0

    def __len__(self) -> int:
        return self.table.shape[0]

    @property
    def kind(self) -> np.ndarray:
        return self.table[:, KIND]

    def op(self, index: int) -> Op:
        r = self.table[index].tolist()
        return Op(OpKind(r[KIND]), r[X], r[Y], r[I], r[J], r[TOOL], r[VALUE],
                  SourcePos(self.source, r[LINE], r[COL]))

    def __iter__(self) -> Iterator[Op]:
        for index in range(len(self)):
            yield self.op(index)



class ProgramBuilder:
    """Collects rows compactly (array of int64) while a reader runs."""

    __slots__ = ("rows", "warnings", "source")

    def __init__(self, source: str):
        self.source = source
        self.rows = array("q")
        self.warnings: list[ReaderWarning] = []

    def emit(self, kind: int, x: int = 0, y: int = 0, i: int = 0, j: int = 0,
             tool: int = NO_TOOL, value: int = 0, line: int = 0, col: int = 0) -> None:
        self.rows.extend((kind, x, y, i, j, tool, value, line, col))

    def warn(self, line: int, col: int, message: str, text: str = "") -> None:
        self.warnings.append(ReaderWarning(SourcePos(self.source, line, col), message, text))

    def count(self) -> int:
        return len(self.rows) // len(COLUMNS)

    def table(self) -> np.ndarray:
        """The rows as an (N, 9) table sharing the builder's memory (no copy, so a
        million-op file does not need twice its size); call it once, at the end."""
        if not self.rows:
            return np.zeros((0, len(COLUMNS)), dtype=np.int64)
        return np.frombuffer(self.rows, dtype=np.int64).reshape(-1, len(COLUMNS))

    def build(self, fmt: str, units: str, **kwargs) -> Program:
        return Program(self.source, fmt, units, self.table(), warnings=self.warnings, **kwargs)
