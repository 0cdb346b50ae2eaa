"""Running a planned job on a connected GRBL board: the pieces of grbl/job.py's
engine, which `plot` and the console's `getg` and `resume` run (backends/grbl.py).

The connection line, the steps/mm check against the profile, the job cut into
pieces at its pen changes and streamed (`stream_job`, a resume's lead-in first),
one piece streamed to a stop with refusals and alarms named by their line in the
whole job, a stop on the user's word (feed hold, then soft reset, so no step is
lost; then the pen up: `lift_pen`), and for a resume the position found again (`find_position`: $H, or the
user re-zeroes); the job is planned again from its journal entry by
stream/resume.py's `replan`, as for our firmware.
The journal itself (stream/journal.py) is bound to a job in grbl/job.py.
"""

from __future__ import annotations

import time

import numpy as np

from galileo_cnc.errors import GalileoError
from galileo_cnc.grbl.gcode import AxisScale, GcodeLine, GrblPen
from galileo_cnc.grbl.jog import home, unlock
from galileo_cnc.grbl.link import FEED_HOLD, GrblLink
from galileo_cnc.grbl.numbers import read_float, steps_per_mm_f32
from galileo_cnc.grbl.reports import GrblError, Status, alarm_text, error_text
from galileo_cnc.grbl.resume import PREAMBLE_TEXT, pen_up_texts
from galileo_cnc.grbl.stream import GrblStreamError, stream
from galileo_cnc.plan.pipeline import PlannedFile
from galileo_cnc.program.ops import NM_PER_MM
from galileo_cnc.transport.port import SIMAVR_URL

#: How long a feed hold may take to bring the machine to rest after Ctrl-C.
HOLD_WAIT_S = 30.0


def position_text(status) -> str:
    """`GRBL stands at X 5.000 Y 4.000 Z 1.875 mm (work)`, from its last report."""
    if status is None:
        return "GRBL's position was not reported"
    x, y, z = (f"{nm / NM_PER_MM:.3f}" for nm in status.wpos_nm)
    return f"GRBL stands at X {x} Y {y} Z {z} mm (work)"


def describe(link: GrblLink, device: str) -> str:
    """`GRBL 1.1h on /dev/ttyACM0 (RX 128 B, 15 blocks, 160 steps/mm)`."""
    spm = [float(read_float(link.settings.steps_per_mm_text(a))) for a in range(3)]
    steps = f"{spm[0]:g}" if len(set(spm)) == 1 else "/".join(f"{v:g}" for v in spm)
    blocks = link.build.planner_blocks or "?"
    return (f"GRBL {link.version} on {device} (RX {link.rx_buffer_bytes} B, {blocks} blocks, "
            f"{steps} steps/mm)")


def refuse_other_scale(link: GrblLink, steps_per_mm: float, profile_path,
                       port: str = "") -> None:
    """The job is planned in the profile's steps but sent in mm: GRBL turns them
    back into steps with its own $100-$102, so both must agree."""
    ours = np.float32(steps_per_mm)
    differ = [100 + a for a in range(3)
              if steps_per_mm_f32(link.settings.steps_per_mm_text(a)) != ours]
    if not differ:
        return
    theirs = ", ".join(f"${n}={link.settings[n]}" for n in differ)
    wanted = " ".join(f"${n}={steps_per_mm:g}" for n in differ)
    profile = f"the profile {profile_path}" if profile_path else "the default profile"
    if port.startswith(SIMAVR_URL):     # a fresh simulated EEPROM each time: in the URL
        send = f"Add {'&'.join(wanted.split())} to the simavr:// URL (GRBL's settings)"
    else:
        send = f"Send GRBL {wanted} (its settings, kept in its EEPROM)"
    raise GalileoError(
        f"GRBL's steps/mm differ from {profile}'s {steps_per_mm:g} steps/mm: GRBL has "
        f"{theirs}. Nothing was sent. {send} if the profile is right, or set "
        f"steps_per_rev/pitch_mm in the profile to GRBL's")


def stream_piece(link: GrblLink, chunk: list[GcodeLine], numbers: list[int | None], where,
                  show, on_reply=None, on_status=None) -> None:
    """`chunk` to a stop; numbers[i] is chunk[i]'s index in the whole job (None for a
    resume's lead-in), so a refusal or an alarm is named by its number in the job
    (stream() counts from the chunk's first line)."""
    if not chunk:
        return

    def acked(index: int, reply) -> None:
        if numbers[index] is not None:
            show(numbers[index] + 1)
            if on_reply is not None:
                on_reply(numbers[index], reply)

    def name(index: int) -> str:
        number = numbers[index]
        return (f"G-code line {number + 1}" if number is not None else
                f"line {index + 1} of the resume's lead-in")

    try:
        stream(link, chunk, where=where, travel_check=False, on_ack=acked,
               on_status=on_status)
    except GrblStreamError as stopped:
        if not stopped.alarm and not stopped.errors:
            raise                   # GRBL fell silent: no line to name
        if stopped.alarm:
            index = min(stopped.acked, len(chunk) - 1)      # the line in flight
            place = where(chunk[index].command)
            text = (f"{place + ': ' if place else ''}{alarm_text(stopped.code)} "
                    f"(at {name(index)} {chunk[index].text!r})")
        else:
            first = stopped.errors[0]
            place = f"{first.where}: " if first.where else ""
            text = (f"GRBL refused a line: {place}{error_text(first.code)} in "
                    f"{name(first.index)} {first.line.text!r}")
        done = sum(1 for n in numbers[:stopped.acked] if n is not None)
        raise GrblStreamError(text, stopped.errors, done, code=stopped.code,
                              alarm=stopped.alarm) from None


def pen_pieces(lines: list[GcodeLine], pen_changes: dict[int, int]) -> list[tuple[int, int]]:
    """(first G-code line of the change, aperture) for each pen change, in order."""
    found = []
    for command in sorted(pen_changes):
        first = next((i for i, line in enumerate(lines) if line.command >= command), None)
        if first is not None:
            found.append((first, pen_changes[command]))
    return found


def source_line(planned: PlannedFile, command: int) -> int:
    job = planned.job
    if not 0 <= command < len(job.op_index) or job.op_index[command] < 0:
        return 0
    op = planned.plotted.op(job.op_index[command])
    pos = getattr(op, "pos", None) or getattr(op, "source", None)
    return pos.line if pos is not None else 0


def held(link: GrblLink, wait_s: float = HOLD_WAIT_S) -> Status | None:
    """After a feed hold: the first report of GRBL at rest (None when none came within
    `wait_s`). A hold makes an idle GRBL `Hold:0` at once (protocol.c), so an `Idle`
    report is trusted only twice in a row: the first may answer a `?` asked before the
    hold (the streamer's status watch), from a GRBL between two blocks of a run that
    then went on; a cancelled jog ends Idle."""
    deadline = time.monotonic() + wait_s
    idle = False
    while time.monotonic() < deadline:
        status = link.status()
        if (status.state == "Hold" and status.substate == 0) or status.state == "Alarm":
            return status
        if status.state == "Idle" and idle:
            return status
        idle = status.state == "Idle"
    return None


def hold_and_reset(link: GrblLink) -> Status | None:
    """Ctrl-C: a feed hold decelerates on the path (no step lost), then the soft
    reset drops GRBL's queue; a reset while moving would lose the position. Returns
    GRBL's report at rest before the reset (None when none came)."""
    status = None
    try:
        link.realtime(FEED_HOLD)
        status = held(link)
    except GrblError as problem:
        if not problem.alarm:
            return None     # the user already asked to stop; the message says what to do
        # an alarm stopped GRBL on its own: the reset below clears it
    try:
        link.soft_reset()
    except GrblError:
        pass
    return status


def lift_pen(link: GrblLink, scale: AxisScale, pen: GrblPen) -> None:
    """After a stop (hold_and_reset: GRBL stands still, its modes reset): the pen up,
    once it has come up. GrblError when GRBL refuses (locked in alarm)."""
    for text in (PREAMBLE_TEXT, *pen_up_texts(scale, pen)):
        link.command_checked(text)
    link.wait_idle()


def stream_job(link: GrblLink, lines: list[GcodeLine], pen_changes: dict[int, int], where,
               show, ask_pen, *, start: int = 0, lead: list[GcodeLine] = (),
               on_reply=None, on_status=None) -> None:
    """Streams lines[start:] (after the `lead` lines, a resume's lead-in) in pieces that
    end at the job's pen changes: each piece runs to a stop (GRBL's buffer drained)
    before `ask_pen(first line, aperture, resuming)` asks for the pen. Resuming past a
    pen change, the pen in use at `start` is asked for first (resuming=True) unless a
    change comes right there. `show(lines done)`, `on_reply(line in the job, reply)`,
    `on_status(status)` for each status answer while the lines stream."""
    total = len(lines)
    pieces = pen_pieces(lines, pen_changes)
    before = [piece for piece in pieces if piece[0] < start]
    if before and not any(first == start for first, _ in pieces):
        ask_pen(*before[-1], True)      # the pen in the holder may be another
    position, chunk = start, list(lead)
    numbers: list[int | None] = [None] * len(lead)
    for first, aperture in pieces:
        if first < start:
            continue
        if first > position or chunk:
            stream_piece(link, chunk + lines[position:first],
                         numbers + list(range(position, first)), where, show, on_reply,
                         on_status)
            position, chunk, numbers = first, [], []
        ask_pen(first, aperture, False)
    stream_piece(link, chunk + lines[position:total], numbers + list(range(position, total)),
                 where, show, on_reply, on_status)


def find_position(link: GrblLink, scale: AxisScale, pen: GrblPen, say, at_work_zero) -> bool:
    """A reset lost GRBL's position (opening the port again resets a board; a stop
    resets GRBL too). With homing ($22=1) `$H` finds the machine frame, and the work
    offset (G54) is in GRBL's EEPROM. Without, `at_work_zero(question)` asks the user
    whether the pen stands at the job's work zero (X0 Y0, down on the paper); yes
    makes that point G54's zero (after `$X` if GRBL is in alarm). False: the user
    said no, nothing was sent."""
    if link.settings.homing:
        say("homing ($H): the reset lost GRBL's position")
        status = home(link)
        wco = ", ".join(f"{nm / NM_PER_MM:.3f}" for nm in link.tracker.wco_nm)
        say(f"homed; work offset (G54, kept in GRBL's EEPROM) {wco} mm, state {status.state}")
        return True
    down = scale.mm(2, pen.down_z_steps)
    if not at_work_zero(f"GRBL has no homing ($22=0): the reset lost its position. The "
                        f"pen must stand at the job's work zero (X0 Y0, the pen down on "
                        f"the paper: Z{down})"):
        return False
    if link.status().state == "Alarm":
        unlock(link)
    link.command_checked(f"G10 L20 P1 X0 Y0 Z{down}")
    return True
