"""Continuing a GRBL job after a lost port (docs/grbl.md, "Resume after a lost port").

What the host knows: GRBL answered `ok` to lines 0..confirmed, so it had parsed and
planned them; lines sent after those may have reached it or not. A GRBL board runs
its queue on without the host, and opening the port again resets it (an Uno's
auto-reset): the position and the G92 offset are gone, G54..G59 stay in EEPROM.
So a resume homes (or has the user re-zero), then sends a lead-in that puts the
machine back in the state the job had before the next line, and goes on from there.

This module is G-code only: which line to continue from and the lead-in's lines,
from the job's own G-code texts, so the machine lands on exactly the steps the
job had there.
"""

from __future__ import annotations

from dataclasses import dataclass

from galileo_cnc.errors import GalileoError
from galileo_cnc.grbl.estimate import PLANNER_BLOCKS
from galileo_cnc.grbl.gcode import AxisScale, GcodeLine, GrblPen

#: Blocks GRBL's stepper may still be running once they have left the planner
#: (stepper.c: st_block_buffer[SEGMENT_BUFFER_SIZE - 1], SEGMENT_BUFFER_SIZE 6).
STEPPER_BLOCKS = 5
#: The lines that start a job on GRBL (gcode.job_to_gcode's preamble).
PREAMBLE_TEXT = "G21 G90 G17 G94 G54"
_MOTION = ("G0", "G1", "G2", "G3")
#: Lines GRBL answers only once everything before them has run (protocol_buffer_synchronize):
#: a dwell, and the spindle (a servo pen) switched.
_SYNCING = ("G4", "M3", "M4", "M5")


class GrblResumeError(GalileoError):
    """The job cannot be continued at that line."""


@dataclass(frozen=True, slots=True)
class JobState:
    """The machine state the job's lines leave before a given line, as GRBL texts."""

    axes: tuple[str | None, str | None, str | None]     # X, Y, Z word values (None: unknown)
    feed: str | None            # the modal F in force
    spindle: str | None         # "M3 S1000" when a servo pen's spindle is on, else None


def state_before(lines: list[GcodeLine], index: int) -> JobState:
    """Position (as the job's own texts), feed and spindle after lines[:index]."""
    axes: list[str | None] = [None, None, None]
    feed = spindle = None
    for line in lines[:index]:
        words = line.text.split()
        if not words:
            continue
        head = words[0]
        if head in _MOTION:
            for word in words[1:]:
                if word[0] in "XYZ":
                    axes["XYZ".index(word[0])] = word[1:]
                elif word[0] == "F":
                    feed = word[1:]
        elif head == "G10" and "L20" in words:          # here is now the named values
            for word in words[1:]:
                if word[0] in "XYZ":
                    axes["XYZ".index(word[0])] = word[1:]
        elif head in ("M3", "M4"):
            spindle = line.text
        elif head == "M5":
            spindle = None
        elif head == "$H" or head.startswith("$J="):
            axes = [None, None, None]
    return JobState(tuple(axes), feed, spindle)


def pen_up_texts(scale: AxisScale, pen: GrblPen) -> list[str]:
    """The lines that lift the pen (Z to its up height, or the servo up and its dwell)."""
    if pen.servo:
        return ["M5" if pen.up_s is None else f"M3 S{pen.up_s}",
                f"G4 P{pen.servo_dwell_ms / 1000:g}"]
    return [f"G0 Z{scale.mm(2, pen.up_z_steps)}"]


def lead_in(lines: list[GcodeLine], start: int, scale: AxisScale,
            pen: GrblPen) -> list[GcodeLine]:
    """The lines that take a just homed (or re-zeroed) GRBL to where the job stood
    before lines[start]: modes and G54, pen up, travel there, the pen as it was
    (down: lowered at the pen's Z feed), the job's feed. Their `command` is that of
    lines[start], so a refusal names the file line being resumed."""
    if start <= 0:
        return []
    state = state_before(lines, start)
    command = lines[start].command if start < len(lines) else lines[-1].command
    out = [PREAMBLE_TEXT, *pen_up_texts(scale, pen)]
    x, y, z = state.axes
    if x is not None and y is not None:
        out.append(f"G0 X{x} Y{y}")
    elif _draws(lines[start]):
        raise GrblResumeError(f"G-code line {start + 1} {lines[start].text!r} draws from a "
                              f"position the job's lines before it do not name: it cannot "
                              f"be resumed there")
    if not pen.servo and z is not None and z != scale.mm(2, pen.up_z_steps):
        out.append(f"G1 Z{z} F{scale.feed_mm_min(pen.z_feed_steps_per_s)}")
    if pen.servo and state.spindle is not None:
        out += [state.spindle, f"G4 P{pen.servo_dwell_ms / 1000:g}"]
    if state.feed is not None:
        out.append(f"F{state.feed}")
    return [GcodeLine(text, command) for text in out]


def _draws(line: GcodeLine) -> bool:
    return line.text.split()[0] in ("G1", "G2", "G3") if line.text.split() else False


def rewind(lines: list[GcodeLine], confirmed: int, floor: int, queue_blocks: int) -> int:
    """The first line that may not have run when GRBL's queue was cut short (a reset
    while it moved): every line up to `confirmed` had been planned, but up to
    `queue_blocks` motion blocks (planner and stepper) can have been dropped, each
    line at least one block. A dwell or spindle line answered means all before it
    had run. Never before `floor` (where this session of the job began)."""
    counted = 0
    index = confirmed
    while index >= max(floor, 0):
        head = lines[index].text.split()[0] if lines[index].text.split() else ""
        if head in _SYNCING:
            return index + 1
        if head in _MOTION or head.startswith("$J="):
            counted += 1
            if counted > queue_blocks:
                return index + 1
        index -= 1
    return max(floor, 0)


def resume_start(lines: list[GcodeLine], confirmed: int, first_index: int,
                 planner_blocks: int | None, cut_short: str | None) -> tuple[int, str]:
    """(the G-code line to continue from, the sentence that says why). After the
    last line GRBL acknowledged (`confirmed`), unless GRBL's queue was cut short
    (`cut_short` says how: a reset while it moved, the job stopped): then the first
    line that may not have run (`rewind` over GRBL's planner and stepper blocks),
    never before `first_index`, where the interrupted session began."""
    acked = confirmed + 1
    if cut_short is None:
        return acked, (f"resuming at G-code line {acked + 1} of {len(lines)}, after the "
                       f"last line GRBL acknowledged")
    depth = (planner_blocks or PLANNER_BLOCKS) + STEPPER_BLOCKS
    start = rewind(lines, confirmed, first_index, depth)
    queued = "the line" if acked - start == 1 else f"the {acked - start} lines"
    return start, (f"resuming at G-code line {start + 1} of {len(lines)}: {cut_short}, so "
                   f"{queued} before line {acked + 1} that GRBL had queued may not have run")
