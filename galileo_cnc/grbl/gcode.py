"""A planned Job as GRBL 1.1 G-code: mm, G0/G1/G2/G3 (arcs stay arcs), feeds in mm/min.

Every coordinate is the decimal text that GRBL's own arithmetic turns back into
the job's step (numbers.mm_text), so the machine lands on exactly the steps the
planner chose. The pen is a Z axis (the profile's pen heights, in steps) or a
servo on the spindle output (M3 S<n> / M5 and a dwell after each change: GRBL
does not wait for a servo). Each line remembers the job command it came from,
so a GRBL error can name the source file's line. A stroke (pen down to pen up) is
G1/G2/G3 lines only: nothing in it makes GRBL's planner sync (M3/M5/S/G4 come only
at pen changes and job dwells), so GRBL blends its corners (docs/grbl.md, $11).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from galileo_cnc import job as J
from galileo_cnc.errors import GalileoError
from galileo_cnc.grbl.numbers import grbl_steps, mm_text, read_float, steps_per_mm_f32

#: GRBL's LINE_BUFFER_SIZE is 80 including the terminating NUL: 79 characters.
MAX_LINE_CHARS = 79
#: Preamble command index (not from the job).
PREAMBLE = -1
#: gcode.c: an arc end whose radius differs from the start's by more than 0.005 mm
#: (and by more than 0.1 % of the radius) is refused with error:33; we keep below
#: it, with room for GRBL's float arithmetic.
ARC_RADIUS_SLACK_MM = 0.0045


class GcodeError(GalileoError):
    """The job cannot be written as GRBL G-code (a line too long, ...)."""


@dataclass(frozen=True, slots=True)
class GrblPen:
    """How the pen moves on a GRBL machine.

    Z mode: `up_z_steps`/`down_z_steps` at `z_feed_steps_per_s`. Servo mode
    (`servo=True`): M3 S`down_s` lowers the pen, `up_s` None means M5 raises it
    (else M3 S`up_s`), and `servo_dwell_ms` follows every change.
    """

    servo: bool = False
    up_z_steps: int = 300
    down_z_steps: int = 0
    z_feed_steps_per_s: int = 800
    down_s: int = 1000
    up_s: int | None = None
    servo_dwell_ms: int = 150


@dataclass(frozen=True, slots=True)
class GcodeLine:
    text: str
    command: int            # index into job.commands, PREAMBLE for the preamble


@dataclass(frozen=True, slots=True)
class AxisScale:
    """GRBL's steps/mm per axis, as the float GRBL holds ($100-$102)."""

    steps_per_mm: tuple[np.float32, np.float32, np.float32]

    @classmethod
    def from_texts(cls, texts) -> "AxisScale":
        return cls(tuple(steps_per_mm_f32(t) for t in texts))

    def mm(self, axis: int, steps: int) -> str:
        return mm_text(steps, self.steps_per_mm[axis])

    def feed_mm_min(self, steps_per_s: int) -> str:
        """A path feed in steps/s as mm/min (XY steps/mm; 1 decimal is plenty:
        GRBL's feed is a float and the planner's, not a position)."""
        value = steps_per_s * 60 / float(self.steps_per_mm[0])
        return f"{value:.1f}".rstrip("0").rstrip(".")


def _seconds(ms: int) -> str:
    return f"{ms / 1000:.3f}".rstrip("0").rstrip(".") or "0"


class _Writer:
    def __init__(self, scale: AxisScale, pen: GrblPen):
        self.scale = scale
        self.pen = pen
        self.lines: list[GcodeLine] = []
        self.command = PREAMBLE
        self.pos: list[int | None] = [None, None, None]   # last commanded steps
        self.feed_text: str | None = None                  # modal F last sent
        self.path_feed: str | None = None                  # SetFeed's, for G1/G2/G3
        self.pen_down: bool | None = None

    def emit(self, text: str) -> None:
        if len(text) > MAX_LINE_CHARS:
            raise GcodeError(f"G-code line of {len(text)} characters exceeds GRBL's "
                             f"{MAX_LINE_CHARS}: {text[:40]}...")
        self.lines.append(GcodeLine(text, self.command))

    def words(self, targets: dict[int, int]) -> list[str]:
        out = []
        for axis, steps in sorted(targets.items()):
            if self.pos[axis] != steps:
                out.append(f"{'XYZ'[axis]}{self.scale.mm(axis, steps)}")
                self.pos[axis] = steps
        return out

    def feed_word(self, feed_text: str | None) -> list[str]:
        if feed_text is None or feed_text == self.feed_text:
            return []
        self.feed_text = feed_text
        return [f"F{feed_text}"]

    def move(self, g: str, targets: dict[int, int], feed_text: str | None = None,
             extra: tuple[str, ...] = ()) -> None:
        words = self.words(targets)
        if not words and not extra:
            return
        if g != "G0":
            if feed_text is None:
                raise GcodeError("a feed move before any feed was set (SetFeed)")
            words += self.feed_word(feed_text)
        self.emit(" ".join([g, *words, *extra]))

    # ---- the pen ----------------------------------------------------------------
    def set_pen(self, down: bool) -> None:
        if self.pen_down == down:
            return
        self.pen_down = down
        pen = self.pen
        if pen.servo:
            if down:
                self.emit(f"M3 S{pen.down_s}")
            else:
                self.emit("M5" if pen.up_s is None else f"M3 S{pen.up_s}")
            self.emit(f"G4 P{_seconds(pen.servo_dwell_ms)}")
        else:
            z = pen.down_z_steps if down else pen.up_z_steps
            self.move("G1", {2: z}, self.scale.feed_mm_min(pen.z_feed_steps_per_s))


def _radius_error_mm(scale: AxisScale, start: tuple[int, int], end: tuple[int, int],
                     i_text: str, j_text: str) -> float:
    """GRBL's |target_r - r| for this arc (gcode.c), from the texts it will parse."""
    value = [float(read_float(scale.mm(a, (start + end)[k])))
             for k, a in enumerate((0, 1, 0, 1))]
    i, j = float(read_float(i_text)), float(read_float(j_text))
    dx, dy = value[2] - value[0] - i, value[3] - value[1] - j
    return abs(math.hypot(dx, dy) - math.hypot(i, j))


def _arc_end(scale: AxisScale, start, centre, end, i_text, j_text) -> tuple[int, int] | None:
    """The end point GRBL accepts for the arc: `end` itself, else the step nearest
    the start circle at end's angle (our machine's arc-then-correction, docs/motion.md
    §4.6), None if GRBL would refuse every candidate (a coarse step, a tiny radius)."""
    if _radius_error_mm(scale, start, end, i_text, j_text) <= ARC_RADIUS_SLACK_MM:
        return end
    angle = math.atan2(end[1] - centre[1], end[0] - centre[0])
    r = math.hypot(start[0] - centre[0], start[1] - centre[1])
    px = centre[0] + round(r * math.cos(angle))
    py = centre[1] + round(r * math.sin(angle))
    candidates = [(px + dx, py + dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1)]
    best = min(candidates, key=lambda p: _radius_error_mm(scale, start, p, i_text, j_text))
    return best if _radius_error_mm(scale, start, best, i_text, j_text) \
        <= ARC_RADIUS_SLACK_MM else None


def _arc(w: _Writer, c: J.ArcTo) -> None:
    x0, y0 = w.pos[0], w.pos[1]
    if x0 is None or y0 is None:
        raise GcodeError("an arc before any position is known")
    if w.path_feed is None:
        raise GcodeError("an arc before any feed was set (SetFeed)")
    scale = w.scale
    i_text, j_text = scale.mm(0, c.i_steps), scale.mm(1, c.j_steps)
    target = (c.x_steps, c.y_steps)
    end = _arc_end(scale, (x0, y0), (x0 + c.i_steps, y0 + c.j_steps), target,
                   i_text, j_text) if c.i_steps or c.j_steps else None
    if end is None:     # GRBL would refuse it as an arc: the straight line it nearly is
        w.move("G1", {0: c.x_steps, 1: c.y_steps}, w.path_feed)
        return
    words = w.words({0: end[0], 1: end[1]})
    if not words:   # a full circle: GRBL needs the (unchanged) end point named
        words = [f"X{scale.mm(0, end[0])}", f"Y{scale.mm(1, end[1])}"]
    words += [f"I{i_text}", f"J{j_text}", *w.feed_word(w.path_feed)]
    w.emit(" ".join(["G2" if c.cw else "G3", *words]))
    if end != target:
        w.move("G1", {0: c.x_steps, 1: c.y_steps}, w.path_feed)


def _flash(w: _Writer, c: J.Flash, flash_dwell_ms: int) -> None:
    w.set_pen(True)
    w.emit(f"G4 P{_seconds(c.dwell_ms if c.dwell_ms is not None else flash_dwell_ms)}")
    w.set_pen(False)


def pen_from_config(config) -> GrblPen:
    """The profile's pen (MachineConfig): on the Z axis at its pen heights and Z feed,
    or, with `grbl_pen = "servo"` ([grbl] pen), a servo on the spindle output."""
    return GrblPen(servo=config.grbl_pen == "servo", up_z_steps=config.pen_up_z_steps,
                   down_z_steps=config.pen_down_z_steps,
                   z_feed_steps_per_s=config.z_feed_steps_per_s,
                   down_s=config.servo_down_s, up_s=config.servo_up_s or None,
                   servo_dwell_ms=config.servo_dwell_ms)


def job_to_gcode(job: J.Job, scale: AxisScale, pen: GrblPen = GrblPen(), *,
                 feed_steps_per_s: int, flash_dwell_ms: int = 200) -> list[GcodeLine]:
    """The job as GRBL lines, in order; `GcodeLine.command` maps back to the job.
    `feed_steps_per_s` is the path feed until the job's first SetFeed (the
    profile's feed: our firmware's configured default)."""
    w = _Writer(scale, pen)
    w.path_feed = scale.feed_mm_min(feed_steps_per_s)
    # mm, absolute, XY plane, feed per minute; work coordinates G54
    w.emit("G21 G90 G17 G94 G54")
    for index, c in enumerate(job.commands):
        w.command = index
        match c:
            case J.Rapid():
                w.set_pen(False)
                w.move("G0", {0: c.x_steps, 1: c.y_steps})
            case J.LineTo():
                targets = {0: c.x_steps, 1: c.y_steps}
                if c.z_steps is not None:
                    targets[2] = c.z_steps
                w.move("G1", targets, w.path_feed)
            case J.ArcTo():
                _arc(w, c)
            case J.PenUp():
                w.set_pen(False)
            case J.PenDown():
                w.set_pen(True)
            case J.Flash():
                _flash(w, c, flash_dwell_ms)
            case J.Dwell():
                w.emit(f"G4 P{_seconds(c.ms)}")
            case J.SetFeed():
                w.path_feed = scale.feed_mm_min(c.feed_steps_per_s)
            case J.Jog():
                parts = [f"{'XYZ'[a]}{scale.mm(a, d)}"
                         for a, d in enumerate((c.dx_steps, c.dy_steps, c.dz_steps)) if d]
                if parts:
                    w.emit(" ".join(["$J=G91 G21", *parts, f"F{w.path_feed or '100'}"]))
                    w.pos = [None, None, None]
            case J.SetOrigin():
                # persistent in GRBL's EEPROM, unlike G92: survives the reset a
                # reopened port causes
                w.emit("G10 L20 P0 X0 Y0 Z0")
                w.pos = [0, 0, 0]
            case J.Home():
                w.emit("$H")
                w.pos = [None, None, None]
            case J.Motors():
                pass    # GRBL powers its drivers itself ($1 idle delay)
            case J.EndJob():
                w.set_pen(False)
            case _:
                raise GcodeError(f"no GRBL G-code for {type(c).__name__}")
    return w.lines


def source_of(program, job: J.Job, command: int) -> str:
    """'file:line' of the source op a job command came from ('' if none)."""
    if command < 0 or command >= len(job.op_index) or job.op_index[command] < 0:
        return ""
    op = program.op(job.op_index[command])
    pos = getattr(op, "pos", None) or getattr(op, "source", None)
    return f"{pos.file}:{pos.line}" if pos is not None else ""


def expected_end_steps(lines: list[GcodeLine], scale: AxisScale) -> list[tuple[int, int, int]]:
    """Where GRBL ends each motion line, in its own arithmetic (tests, resume):
    the (x, y, z) machine steps after every G0/G1/G2/G3 line, WCO being 0."""
    pos = [0, 0, 0]
    ends = []
    for line in lines:
        words = line.text.split()
        if not words or words[0] not in ("G0", "G1", "G2", "G3"):
            continue
        for word in words[1:]:
            axis = "XYZ".find(word[0])
            if axis >= 0:
                pos[axis] = grbl_steps(word[1:], scale.steps_per_mm[axis])
        ends.append(tuple(pos))
    return ends
