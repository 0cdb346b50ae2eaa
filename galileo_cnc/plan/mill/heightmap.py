"""The height map: a board's top probed on a grid, and a mill program's Z corrected by it.

A board is never flat (a warped laminate, a spoil board not surfaced): at a cut depth of
0.1 mm a warp of 0.2 mm cuts nothing on the crests and three times too deep in the troughs.
So the top is probed with G38.2 on a grid over where the job cuts, and every Z the
program commands is taken as depth below that surface:

- the grid (`job_grid`, `grid_over`) spans the XY extent of the job's cutting moves
  (Z < 0) in the fewest equal cells at most `height_map_spacing_mm` wide; each node is
  probed from `probe_clearance_mm` above Z = 0 down to at most `probe_depth_mm` below
  it, in rows that alternate their direction (`ProbeGrid.points`, `probe_lines`);
- GRBL reports each contact as `[PRB:x,y,z:1]` in machine coordinates (`parse_prb`); the
  height is that Z less the work offset: heights are work Z of the surface, so Z = 0
  need not lie on it;
- the height anywhere is the bilinear interpolation of its cell's four corners, exact
  in integers (one rounding to the nm, half away from zero); outside the grid the
  nearest edge's, though a cut outside the grid is refused;
- `HeightCorrector.line` turns one program line into the lines to send: a Z word becomes
  Z + height at the move's end; a feed move (G1) in the material (Z < 0 at either end) is
  split where it crosses a grid line and into pieces short enough that GRBL's straight Z
  between two piece ends stays within LINEAR_Z_BOUND_NM of the bilinear surface, every
  piece carrying its own Z. Along a line through one cell the bilinear surface is a
  quadratic in the line's parameter whose t^2 coefficient is
  c = twist * dx * dy / (cell width * cell height) (twist = z00 - z10 - z01 + z11, dx
  and dy the piece's extent); a chord strays from a quadratic by at most |c| / 4, so n
  equal pieces with |c| / (4 n^2) <= LINEAR_Z_BOUND_NM hold the bound (and an
  axis-parallel move is not split within a cell: the surface is linear along it);
- arcs (G2/G3: milled holes and slots, which go through the board) get their end Z
  corrected only: GRBL moves Z linearly along the arc;
- `G92 Z v` at X, Y re-bases the map there to 0: the program names its Z where the tool
  stands, so its frame and GRBL's move together and the height there is taken up by
  the new zero. After a G38.2 the tool stands on a plate v thick on the surface (a drill
  change's re-zero), which gives the same. `G92.1` takes the probed map back.

Integer nm inside; mm in every message and in the G-code (exact, readers/gcode/writer.mm).
`corrected_lines` is the whole program as a generator, one input line at a time, so the
correction applies as lines go out. docs/mill.md "Height map".
"""

from __future__ import annotations

import bisect
import math
import re
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from fractions import Fraction

from galileo_cnc.config.mill import MillConfig
from galileo_cnc.errors import GalileoError, GcodeError
from galileo_cnc.readers.gcode.arcs import round_half_away
from galileo_cnc.readers.gcode.lexer import code_number, scaled, split_words
from galileo_cnc.readers.gcode.writer import mm

NM_PER_MM = 1_000_000
#: GRBL's straight Z between two piece ends strays at most this far from the bilinear
#: surface (1 um: a sixth of a step at 160 steps/mm), plus 1 nm of rounding
LINEAR_Z_BOUND_NM = 1_000
#: a map larger than this many nodes per axis is a mistake in the spacing (a 300 mm
#: board at 1 mm): probing it would take hours
MAX_NODES_PER_AXIS = 201
_PRB = re.compile(r"^\[PRB:([-0-9.]+),([-0-9.]+),([-0-9.]+)(?:,[-0-9.]+)*:([01])\]$")
_MOTION = {"0": "G0", "1": "G1", "2": "G2", "3": "G3"}


class HeightMapError(GalileoError):
    """A grid, a map or a program the height map cannot serve (the message says why, in mm)."""


def mm_text(nm: int) -> str:
    """Integer nm as mm with three decimals, for messages: 12.500."""
    return f"{nm / NM_PER_MM:.3f}"


# ---- the grid ------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class ProbeGrid:
    """Where to probe (work XY, nm) and how: from clearance_nm above Z = 0 down to at
    most depth_nm below it, at feed_um_min."""

    xs_nm: tuple[int, ...]
    ys_nm: tuple[int, ...]
    clearance_nm: int
    depth_nm: int
    feed_um_min: int

    def points(self) -> list[tuple[int, int]]:
        """Every node, row by row (Y up), each row the other way than the one before:
        the shortest travel between them."""
        order = []
        for row, y in enumerate(self.ys_nm):
            xs = self.xs_nm if row % 2 == 0 else self.xs_nm[::-1]
            order += [(x, y) for x in xs]
        return order

    def describe(self) -> str:
        return (f"{len(self.xs_nm)} x {len(self.ys_nm)} points over X {mm_text(self.xs_nm[0])}"
                f"..{mm_text(self.xs_nm[-1])} Y {mm_text(self.ys_nm[0])}.."
                f"{mm_text(self.ys_nm[-1])} mm (work), at most "
                f"{mm_text(max(_gaps(self.xs_nm) + _gaps(self.ys_nm) or [0]))} mm apart")


def _gaps(nodes: tuple[int, ...]) -> list[int]:
    return [b - a for a, b in zip(nodes, nodes[1:])]


def axis_nodes(low_nm: int, high_nm: int, spacing_nm: int) -> tuple[int, ...]:
    """low..high in the fewest equal cells at most spacing_nm wide (integer nodes,
    ends exact); one node when low == high."""
    cells = max(1, -(-(high_nm - low_nm) // spacing_nm)) if high_nm > low_nm else 0
    if cells + 1 > MAX_NODES_PER_AXIS:
        raise HeightMapError(f"a height map over {mm_text(high_nm - low_nm)} mm at "
                             f"{mm_text(spacing_nm)} mm spacing has {cells + 1} points a row, "
                             f"more than {MAX_NODES_PER_AXIS}: raise height_map_spacing_mm")
    if cells == 0:
        return (low_nm,)
    return tuple(low_nm + (high_nm - low_nm) * i // cells for i in range(cells + 1))


def grid_over(box_nm: tuple[int, int, int, int], mill: MillConfig) -> ProbeGrid:
    """The probe grid over (x0, y0, x1, y1), by the profile's [mill] height map keys."""
    x0, y0, x1, y1 = box_nm
    return ProbeGrid(axis_nodes(x0, x1, mill.height_map_spacing_nm),
                     axis_nodes(y0, y1, mill.height_map_spacing_nm),
                     mill.probe_clearance_nm, mill.probe_depth_nm, mill.probe_feed_um_min)


def job_grid(lines: Iterable[str], mill: MillConfig, source: str = "G-code") -> ProbeGrid:
    """The probe grid over where the job's G-code lines cut (grid_over(cutting_box))."""
    box = cutting_box(lines, source)
    if box is None:
        raise HeightMapError(f"{source}: the job cuts nowhere below Z = 0: there is no "
                             f"board to map")
    return grid_over(box, mill)


def probe_lines(grid: ProbeGrid) -> list[list[str]]:
    """The probing, one list of G-code lines per node in `grid.points()` order: up to
    the clearance, over the node, G38.2 down (GRBL answers `[PRB:...]`), up again."""
    clear, down = mm(grid.clearance_nm), mm(-grid.depth_nm)
    feed = mm(grid.feed_um_min * 1000)
    return [[f"G0 Z{clear}", f"G0 X{mm(x)} Y{mm(y)}", f"G38.2 Z{down} F{feed}", f"G0 Z{clear}"]
            for x, y in grid.points()]


def parse_prb(line: str) -> tuple[tuple[int, int, int], bool] | None:
    """`[PRB:1.000,2.000,-0.125:1]` -> ((x, y, z) nm, contact made); None for other lines.
    GRBL reports the probe position in machine coordinates."""
    match = _PRB.match(line.strip())
    if match is None:
        return None
    x, y, z = (scaled(match[i], NM_PER_MM) for i in (1, 2, 3))
    return (x, y, z), match[4] == "1"


# ---- the map ---------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class HeightMap:
    """The surface's work Z (nm) at every node: z_nm[row][column], row along ys_nm."""

    xs_nm: tuple[int, ...]
    ys_nm: tuple[int, ...]
    z_nm: tuple[tuple[int, ...], ...]

    def __post_init__(self) -> None:
        for name, nodes in (("X", self.xs_nm), ("Y", self.ys_nm)):
            if not nodes or any(b <= a for a, b in zip(nodes, nodes[1:])):
                raise HeightMapError(f"height map: its {name} nodes must rise: {nodes!r}")
        if len(self.z_nm) != len(self.ys_nm) or \
                any(len(row) != len(self.xs_nm) for row in self.z_nm):
            raise HeightMapError(f"height map: {len(self.ys_nm)} rows of {len(self.xs_nm)} "
                                 f"heights expected")

    @classmethod
    def from_points(cls, grid: ProbeGrid, heights_nm: Iterable[int]) -> "HeightMap":
        """The map of `grid` from one height per node, in `grid.points()` order."""
        at = dict(zip(grid.points(), heights_nm))
        if len(at) != len(grid.xs_nm) * len(grid.ys_nm):
            raise HeightMapError(f"height map: {len(at)} heights for "
                                 f"{len(grid.xs_nm) * len(grid.ys_nm)} points")
        return cls(grid.xs_nm, grid.ys_nm,
                   tuple(tuple(at[x, y] for x in grid.xs_nm) for y in grid.ys_nm))

    def exact(self, x_nm, y_nm) -> Fraction:
        """The bilinear height at (x, y) (integers or Fractions), exact; clamped to the
        grid's edge outside it."""
        return Fraction(*self._weighted(x_nm, y_nm))

    def at(self, x_nm: int, y_nm: int) -> int:
        """The bilinear height at (x, y) to the nm (half away from zero)."""
        return round_half_away(*self._weighted(x_nm, y_nm))

    def _weighted(self, x_nm, y_nm) -> tuple:
        """(numerator, denominator) of the bilinear height: the corners weighted by the
        opposite sub-rectangles, over the cell's area."""
        (i0, i1, wx0, wx1, dx), (j0, j1, wy0, wy1, dy) = \
            _cell(self.xs_nm, x_nm), _cell(self.ys_nm, y_nm)
        z = self.z_nm
        return (z[j0][i0] * wx0 * wy0 + z[j0][i1] * wx1 * wy0
                + z[j1][i0] * wx0 * wy1 + z[j1][i1] * wx1 * wy1, dx * dy)

    def contains(self, x_nm: int, y_nm: int) -> bool:
        return (self.xs_nm[0] <= x_nm <= self.xs_nm[-1]
                and self.ys_nm[0] <= y_nm <= self.ys_nm[-1])

    def rebased(self, x_nm: int, y_nm: int) -> "HeightMap":
        """The map once Z = 0 is moved to the surface at (x, y)."""
        base = self.at(x_nm, y_nm)
        return HeightMap(self.xs_nm, self.ys_nm,
                         tuple(tuple(z - base for z in row) for row in self.z_nm))

    def describe(self) -> str:
        heights = [z for row in self.z_nm for z in row]
        return (f"height map of {len(self.xs_nm)} x {len(self.ys_nm)} points over X "
                f"{mm_text(self.xs_nm[0])}..{mm_text(self.xs_nm[-1])} Y "
                f"{mm_text(self.ys_nm[0])}..{mm_text(self.ys_nm[-1])} mm (work): the "
                f"surface lies at Z {mm_text(min(heights))}..{mm_text(max(heights))} mm")

    def to_json(self) -> dict:
        return {"xs_nm": list(self.xs_nm), "ys_nm": list(self.ys_nm),
                "z_nm": [list(row) for row in self.z_nm]}

    @classmethod
    def from_json(cls, data) -> "HeightMap":
        """The map of to_json(); HeightMapError naming what is wrong."""
        def integers(value) -> bool:
            return isinstance(value, list) and value and all(
                isinstance(v, int) and not isinstance(v, bool) for v in value)
        if not isinstance(data, dict) or set(data) != {"xs_nm", "ys_nm", "z_nm"}:
            raise HeightMapError("height map: expected xs_nm, ys_nm and z_nm")
        if not (integers(data["xs_nm"]) and integers(data["ys_nm"])
                and isinstance(data["z_nm"], list) and all(integers(r) for r in data["z_nm"])):
            raise HeightMapError("height map: xs_nm, ys_nm and the rows of z_nm must be "
                                 "lists of integers")
        return cls(tuple(data["xs_nm"]), tuple(data["ys_nm"]),
                   tuple(tuple(row) for row in data["z_nm"]))


def _cell(nodes: tuple[int, ...], v: int) -> tuple[int, int, int, int, int]:
    """(first node, second node, weight of the first, of the second, their sum) of the
    cell holding v, v clamped to the nodes; a one-node axis is one cell of width 1."""
    if len(nodes) == 1:
        return 0, 0, 1, 0, 1
    v = min(max(v, nodes[0]), nodes[-1])
    i = min(max(bisect.bisect_right(nodes, v) - 1, 0), len(nodes) - 2)
    return i, i + 1, nodes[i + 1] - v, v - nodes[i], nodes[i + 1] - nodes[i]


def split_parameters(height_map: HeightMap, start: tuple[int, int], end: tuple[int, int],
                     bound_nm: int = LINEAR_Z_BOUND_NM) -> list[Fraction]:
    """The parameters 0 < t < 1 (exact, rising) at which the move start -> end is cut:
    where it crosses a grid line, and within each cell into the fewest equal pieces
    whose chords stay within bound_nm of the bilinear surface (module doc)."""
    (px, py), (qx, qy) = start, end
    dx, dy = qx - px, qy - py
    cuts = set()
    for nodes, p, d in ((height_map.xs_nm, px, dx), (height_map.ys_nm, py, dy)):
        if d:
            low, high = min(p, p + d), max(p, p + d)
            for node in nodes[bisect.bisect_right(nodes, low):bisect.bisect_left(nodes, high)]:
                cuts.add(Fraction(node - p, d))
    if not cuts and _pieces(height_map, (px + qx) // 2, (py + qy) // 2, dx, dy, bound_nm) == 1:
        return []                   # the common short chord inside one cell: no Fractions
    edges = [Fraction(0), *sorted(cuts), Fraction(1)]
    out = []
    for a, b in zip(edges, edges[1:]):
        pieces = _pieces(height_map, px + (a + b) / 2 * dx, py + (a + b) / 2 * dy,
                         (b - a) * dx, (b - a) * dy, bound_nm)
        out += [a + (b - a) * Fraction(k, pieces) for k in range(1, pieces)]
        out.append(b)
    return out[:-1]


def _pieces(height_map: HeightMap, mid_x: Fraction, mid_y: Fraction, span_x: Fraction,
            span_y: Fraction, bound_nm: int) -> int:
    """The fewest equal pieces of a span within one cell (its middle at mid) whose
    chords stray at most bound_nm from the surface: |c| / (4 n^2) <= bound."""
    if not span_x or not span_y or len(height_map.xs_nm) == 1 or len(height_map.ys_nm) == 1:
        return 1
    i0, i1, _, _, wx = _cell(height_map.xs_nm, math.floor(mid_x))
    j0, j1, _, _, wy = _cell(height_map.ys_nm, math.floor(mid_y))
    z = height_map.z_nm
    twist = z[j0][i0] - z[j0][i1] - z[j1][i0] + z[j1][i1]
    if abs(twist * span_x * span_y) <= 4 * bound_nm * wx * wy:
        return 1
    need = Fraction(abs(twist * span_x * span_y)) / (4 * bound_nm * wx * wy)   # n^2 >= need
    pieces = max(1, math.isqrt(math.ceil(need)))
    while pieces * pieces < need:
        pieces += 1
    return pieces


# ---- correcting a program -----------------------------------------------------------------

def cutting_box(lines: Iterable[str], source: str = "G-code") -> tuple[int, int, int, int] | None:
    """(x0, y0, x1, y1) nm of every point where the program moves in the material (Z < 0
    at either end of a move; an arc's whole circle), None when it cuts nowhere."""
    state = _State(source)
    box = None
    for text in lines:
        move = state.read(text)
        if move is None or move.kind is None or move.passthrough or not move.cuts:
            continue
        points = [p for p in (move.start[:2], move.end[:2]) if None not in p]
        if move.centre is not None:
            cx, cy = move.centre
            r = math.isqrt((move.start[0] - cx) ** 2 + (move.start[1] - cy) ** 2) + 1
            points += [(cx - r, cy - r), (cx + r, cy + r)]
        for x, y in points:
            box = (x, y, x, y) if box is None else (
                min(box[0], x), min(box[1], y), max(box[2], x), max(box[3], y))
    return box


def corrected_lines(lines: Iterable[str], height_map: HeightMap,
                    source: str = "G-code") -> Iterator[str]:
    """The program's lines with Z by the height map (module doc), one input line at a
    time: a generator, so a streamer corrects as it sends."""
    corrector = HeightCorrector(height_map, source)
    for text in lines:
        yield from corrector.line(text)


class HeightCorrector:
    """Corrects a program line by line (`line`), keeping its modal state and the map in
    the program's Z frame (a `G92 Z` re-bases it, `G92.1` takes the probed one back)."""

    def __init__(self, height_map: HeightMap, source: str = "G-code",
                 bound_nm: int = LINEAR_Z_BOUND_NM):
        self.height_map = height_map
        self.bound_nm = bound_nm
        self.state = _State(source)
        self.probed_map = height_map

    def line(self, text: str) -> list[str]:
        """The lines to send for one program line (itself when nothing changes)."""
        move = self.state.read(text)
        if move is not None and move.kind is None and move.rebase_z is not None:
            x, y, _ = move.end
            if x is None or y is None:
                raise self.state.error("G92 Z where X and Y are unknown: the height map "
                                       "cannot follow it")
            self.height_map = self.height_map.rebased(x, y)
        elif move is not None and move.clears_g92:
            self.height_map = self.probed_map
        if move is None or move.passthrough or move.kind is None or move.end[2] is None:
            return [text]           # a comment, a mode, a probe, a move of unknown Z
        return self._move(move)

    def _move(self, move: "_Move") -> list[str]:
        x, y, z = move.end
        if x is None or y is None:          # the start's rise to the safe height: as it is
            if move.cuts:
                raise self.state.error("a cut where X and Y are unknown: the height map "
                                       "cannot correct it")
            return [move.text]
        if move.cuts and not self.height_map.contains(x, y):
            raise self.state.error(
                f"cuts at X {mm_text(x)} Y {mm_text(y)} mm (work), outside the height map "
                f"(X {mm_text(self.height_map.xs_nm[0])}..{mm_text(self.height_map.xs_nm[-1])}"
                f" Y {mm_text(self.height_map.ys_nm[0])}..{mm_text(self.height_map.ys_nm[-1])}"
                f" mm): probe a grid over this job")
        if move.kind == "G1" and move.cuts and move.start[:2] != move.end[:2]:
            return self._split(move)
        if move.kind in ("G0", "G1") and not move.has_z:
            return [move.text]          # Z stays where the last corrected move left it
        return [move.with_z(mm(z + self.height_map.at(x, y)))]

    def _split(self, move: "_Move") -> list[str]:
        (px, py, pz), (qx, qy, qz) = move.start, move.end
        ts = split_parameters(self.height_map, (px, py), (qx, qy), self.bound_nm)
        lines = []
        extra = move.other_words()          # F and the like: on the first piece
        for t in [*ts, Fraction(1)]:
            x, y, zp = (_lerp(a, b, t) for a, b, in ((px, qx), (py, qy), (pz, qz)))
            lines.append(" ".join([move.kind, f"X{mm(x)}", f"Y{mm(y)}",
                                   f"Z{mm(zp + self.height_map.at(x, y))}", *extra]))
            extra = []
        return lines


def _lerp(a: int, b: int, t: Fraction) -> int:
    value = a + (b - a) * t
    return round_half_away(value.numerator, value.denominator)


@dataclass(slots=True)
class _Move:
    """One line's effect: a motion (kind G0..G3, from start to end, nm, None = unknown),
    or none (kind None) with a G92 Z's value in rebase_z, or a G92.1 (clears_g92)."""

    text: str
    kind: str | None
    start: tuple
    end: tuple
    words: list
    has_z: bool = False
    centre: tuple | None = None
    passthrough: bool = False
    rebase_z: int | None = None
    clears_g92: bool = False

    @property
    def cuts(self) -> bool:
        return any(z is not None and z < 0 for z in (self.start[2], self.end[2]))

    def with_z(self, z_text: str) -> str:
        """The line (upper case, no comments) with its Z word, or one after its axes, of
        z_text; its motion's G word first when the line relied on the modal one."""
        words = [f"{letter}{number}" for letter, number, _ in self.words if letter != "Z"]
        if not any(w[0] == "G" and code_number(w[1:]) in _MOTION for w in words):
            words.insert(0, self.kind)
        after = max(k for k, word in enumerate(words)
                    if word[0] in "XY" or (word[0] == "G" and code_number(word[1:]) in _MOTION))
        words.insert(after + 1, f"Z{z_text}")
        return " ".join(words)

    def other_words(self) -> list[str]:
        """The line's words but its motion and axes (F, S, and G codes of modes)."""
        return [f"{letter}{number}" for letter, number, _ in self.words if letter not in "XYZIJ"
                and not (letter == "G" and code_number(number) in _MOTION)]


#: G codes that are neither motion nor a mode the correction must know: passed on
_PLAIN_G = {"4", "17", "21", "28.1", "30.1", "40", "43.1", "49", "54", "55", "56", "57",
            "58", "59", "61", "80", "90", "90.1", "91.1", "93", "94"}


class _State:
    """The modal state the correction needs: motion mode and the program's position."""

    def __init__(self, source: str):
        self.source = source
        self.number = 0
        self.text = ""
        self.motion = "G0"
        self.position: list[int | None] = [None, None, None]

    def error(self, message: str) -> HeightMapError:
        return HeightMapError(f"{self.source}:{self.number}: {message} ({self.text.strip()!r})")

    def read(self, text: str) -> _Move | None:
        """The line's effect (None for a blank line, a comment, a $ command)."""
        self.number += 1
        self.text = text
        stripped = text.strip()
        if not stripped or stripped.startswith(("$", "%")):
            return None
        try:
            words = split_words(stripped, self.source, self.number)
        except GcodeError as exc:
            raise self.error(f"not G-code the height map can read: {exc}") from None
        if not words:
            return None
        g_codes = [code_number(n) for letter, n, _ in words if letter == "G"]
        axes = {letter: scaled(n, NM_PER_MM) for letter, n, _ in words if letter in "XYZIJ"}
        for code in g_codes:
            if code == "91":
                raise self.error("relative moves (G91): the height map corrects absolute "
                                 "(G90) programs only")
            if code == "20":
                raise self.error("inches (G20): the height map corrects mm (G21) programs only")
            if code in ("18", "19"):
                raise self.error("arcs outside the XY plane: the height map corrects G17 "
                                 "programs only")
        start = tuple(self.position)
        if any(code.startswith("38.") for code in g_codes):
            # a probe stops wherever it touches: Z is unknown until set again
            self._moved(axes, unknown=True)
            return _Move(text, "G38", start, tuple(self.position), words, passthrough=True)
        if any(code in ("28", "30", "53") for code in g_codes):
            self._moved(axes, unknown=True)
            return _Move(text, "G53", start, tuple(self.position), words, passthrough=True)
        if "10" in g_codes or ("92" in g_codes and ("X" in axes or "Y" in axes)):
            raise self.error("a work offset moved in X or Y: the height map's points would "
                             "lie elsewhere on the board")
        if "92.1" in g_codes:          # the G92 offset gone: Z in the old numbers
            self.position[2] = None
            return _Move(text, None, start, tuple(self.position), words, clears_g92=True)
        if "92" in g_codes:
            self._moved(axes)
            return _Move(text, None, start, tuple(self.position), words, rebase_z=axes.get("Z"))
        for code in g_codes:
            if code in _MOTION:
                self.motion = _MOTION[code]
            elif code not in _PLAIN_G:
                raise self.error(f"G{code}: a code the height map does not know")
        if not any(letter in axes for letter in "XYZ"):
            return _Move(text, None, start, start, words, passthrough=True)
        self._moved(axes)
        end = tuple(self.position)
        centre = None
        if self.motion in ("G2", "G3"):
            if start[0] is None or start[1] is None:
                raise self.error("an arc from an unknown position")
            centre = (start[0] + axes.get("I", 0), start[1] + axes.get("J", 0))
        if self.motion == "G1" and ("X" in axes or "Y" in axes) and \
                (None in start[:2] or None in end[:2]) and \
                any(z is not None and z < 0 for z in (start[2], end[2])):
            raise self.error("a cut from an unknown position: the height map cannot split it")
        return _Move(text, self.motion, start, end, words, has_z="Z" in axes, centre=centre)

    def _moved(self, axes: dict, unknown: bool = False) -> None:
        for a, letter in enumerate("XYZ"):
            if letter in axes:
                self.position[a] = None if unknown else axes[letter]
