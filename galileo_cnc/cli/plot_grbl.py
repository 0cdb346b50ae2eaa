"""`galileo-cnc plot` on a stock GRBL 1.1 board (docs/grbl.md).

Plans the file as on our firmware, connects (`GrblLink`), refuses a profile
whose steps/mm differ from GRBL's `$100-$102` (the drawing would come out at
the wrong size), writes the job as GRBL G-code, prints GRBL's time estimate,
checks the job against GRBL's travel before the first byte, and streams it with
a progress line, stopping at each pen change. `--check` instead runs the job
through GRBL's check mode (`$C`) and lists every line GRBL rejects.
Exit codes as `plot`: 0 done (or nothing rejected), 1 refused, rejected or
alarmed, 130 stopped with Ctrl-C.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from typing import TextIO

import numpy as np

from galileo_cnc.cli.plot import EXIT_FAILED, EXIT_INTERRUPTED, EXIT_OK, TextProgress
from galileo_cnc.config.profile import Profile
from galileo_cnc.errors import GalileoError
from galileo_cnc.grbl.check import check_job
from galileo_cnc.grbl.estimate import Machine, estimate
from galileo_cnc.grbl.gcode import AxisScale, GcodeLine, job_to_gcode, pen_from_config, source_of
from galileo_cnc.grbl.link import FEED_HOLD, GrblLink
from galileo_cnc.grbl.numbers import read_float, steps_per_mm_f32
from galileo_cnc.grbl.reports import GrblError, alarm_text
from galileo_cnc.grbl.stream import GrblStreamError, LineError, stream
from galileo_cnc.grbl.travel import applies, check_travel
from galileo_cnc.machine.timing import duration_text
from galileo_cnc.plan.pipeline import PlannedFile, PlanOptions, plan_file
from galileo_cnc.program.ops import NM_PER_MM
from galileo_cnc.stream.streamer import PenChange, describe_aperture
from galileo_cnc.transport.port import open_port

#: How long a feed hold may take to bring the machine to rest after Ctrl-C.
HOLD_WAIT_S = 30.0


@dataclass
class GrblPlotOptions:
    file: str
    profile: Profile
    port: str                       # a port identified as GRBL
    plan: PlanOptions
    offset: str = "auto"
    margin_nm: int = 0
    yes: bool = False
    check: bool = False
    preview: str | None = None


class GrblProgress(TextProgress):
    """plot's progress line, counting G-code lines; the file line is left out where a
    G-code line has none (the preamble, the final pen lift; in ink mode the fill)."""

    def lines(self, done: int, total: int, source_line: int, eta_s: float) -> None:
        percent = 100 * done // max(total, 1)
        where = f"  line {source_line} of the file" if source_line else ""
        text = f"{percent:3d}% {done}/{total} lines{where}  ETA {duration_text(eta_s)}"
        if self.tty:
            self.out.write(f"\r[{'#' * (percent // 4):<25}] {text}\x1b[K")
            self.out.flush()
        elif percent // 10 != self._shown:
            self._shown = percent // 10
            self.out.write(text + "\n")


def run_grbl_plot(options: GrblPlotOptions, out: TextIO | None = None) -> int:
    out = out if out is not None else sys.stdout
    config = options.profile.config
    progress = GrblProgress(out)
    planned = plan_file(options.file, config, options.offset, margin_nm=options.margin_nm,
                        on_progress=progress.planning, options=options.plan)
    with open_port(options.port, options.profile.baud, timeout=0.2) as port:
        link = GrblLink.connect(port)
        out.write(describe(link, options.port) + "\n")
        refuse_other_scale(link, config.steps_per_mm, options.profile.path)
        scale = AxisScale.from_texts([link.settings.steps_per_mm_text(a) for a in range(3)])
        lines = job_to_gcode(planned.job, scale, pen_from_config(config),
                             feed_steps_per_s=config.feed_steps_per_s,
                             flash_dwell_ms=config.flash_dwell_ms)
        where = lambda command: source_of(planned.plotted, planned.job, command)
        _say_plan(planned, out)
        if options.check:
            report = check_job(link, lines, where=where)
            out.write(f"GRBL check mode ($C): {report}\n")
            return EXIT_OK if report.ok else EXIT_FAILED
        guess = estimate(lines, Machine.from_settings(link.settings, link.build.planner_blocks))
        out.write(f"{len(lines)} G-code lines, about {duration_text(guess.seconds)} on GRBL "
                  f"(its planner's estimate)\n")
        if applies(link.settings):      # machine coordinates are known only once homed
            now = link.status()
            check_travel(lines, link.settings, link.tracker.wco_nm, now.mpos_nm, where=where)
        began = time.monotonic()
        try:
            _stream_with_pen_changes(link, planned, lines, where, progress, options.yes,
                                     guess.seconds)
        except GrblStreamError as stopped:
            progress.message(f"galileo-cnc: {stopped}")
            if stopped.alarm:
                progress.message("GRBL is locked in alarm: its position may be lost; home "
                                 "or re-zero, then unlock it with $X")
            return EXIT_FAILED
        except KeyboardInterrupt:
            _hold_and_reset(link)
            progress.message("stopped: GRBL held the feed, then was reset (its queue is "
                             "dropped, the position kept)")
            return EXIT_INTERRUPTED
        progress.message(f"\aprocess has finished in {duration_text(time.monotonic() - began)}")
    if options.preview:
        _write_preview(options.preview, planned, config, out)
    return EXIT_OK


def describe(link: GrblLink, device: str) -> str:
    """`GRBL 1.1h on /dev/ttyACM0 (RX 128 B, 15 blocks, 160 steps/mm)`."""
    spm = [float(read_float(link.settings.steps_per_mm_text(a))) for a in range(3)]
    steps = f"{spm[0]:g}" if len(set(spm)) == 1 else "/".join(f"{v:g}" for v in spm)
    blocks = link.build.planner_blocks or "?"
    return (f"GRBL {link.version} on {device} (RX {link.rx_buffer_bytes} B, {blocks} blocks, "
            f"{steps} steps/mm)")


def refuse_other_scale(link: GrblLink, steps_per_mm: float, profile_path) -> None:
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
    raise GalileoError(
        f"GRBL's steps/mm differ from {profile}'s {steps_per_mm:g} steps/mm: GRBL has "
        f"{theirs}. Nothing was sent. Send GRBL {wanted} (its settings, kept in its "
        f"EEPROM) if the profile is right, or set steps_per_rev/pitch_mm in the profile "
        f"to GRBL's")


def _say_plan(planned: PlannedFile, out: TextIO) -> None:
    box, offset = planned.artwork.drawn_box_nm, planned.offset_nm
    if box is not None:
        out.write(f"{planned.program.source}: minimum X {box[0] / NM_PER_MM:.3f} mm, "
                  f"Y {box[1] / NM_PER_MM:.3f} mm; offset {offset[0] / NM_PER_MM:.3f}, "
                  f"{offset[1] / NM_PER_MM:.3f} mm\n")


def _stream_with_pen_changes(link: GrblLink, planned: PlannedFile, lines: list[GcodeLine],
                             where, progress: GrblProgress, yes: bool,
                             estimate_s: float) -> None:
    """Streams the lines in pieces that end at the job's pen changes: each piece
    runs to a stop (GRBL's buffer drained) before the user is asked for a pen."""
    job = planned.job
    total = len(lines)
    began = time.monotonic()

    def show(done: int) -> None:
        eta = max(0.0, estimate_s - (time.monotonic() - began))
        progress.lines(done, total, _source_line(planned, lines[done - 1].command), eta)

    start = 0
    for first, aperture in _pieces(lines, job.pen_changes):
        if first > start:
            _stream_piece(link, lines, start, first, where, show)
            start = first
        label = job.pen_labels.get(aperture) or \
            f"pen for aperture {describe_aperture(planned.program, aperture)}"
        change = PenChange(aperture, label, lines[first].command)
        progress.message(f"\a{change.prompt}" + ("" if yes else ", then press Enter"))
        if not yes:
            sys.stdin.readline()
    _stream_piece(link, lines, start, total, where, show)


def _stream_piece(link: GrblLink, lines: list[GcodeLine], start: int, end: int, where,
                  show) -> None:
    """lines[start:end], to a stop; a refusal or an alarm is named by its number in
    the whole job (stream() counts from the piece's first line)."""
    try:
        stream(link, lines[start:end], where=where, travel_check=False,
               on_ack=lambda index, reply: show(start + index + 1))
    except GrblStreamError as stopped:
        if not stopped.alarm and not stopped.errors:
            raise                   # GRBL fell silent: no line to name
        if stopped.alarm:
            index = start + min(stopped.acked, end - start - 1)   # the line in flight
            place = where(lines[index].command)
            text = (f"{place + ': ' if place else ''}{alarm_text(stopped.code)} "
                    f"(at G-code line {index + 1} {lines[index].text!r})")
        else:
            first = stopped.errors[0]
            text = "GRBL refused a line: " + str(LineError(
                start + first.index, first.line, first.code, first.where))
        raise GrblStreamError(text, stopped.errors, start + stopped.acked,
                              code=stopped.code, alarm=stopped.alarm) from None


def _pieces(lines: list[GcodeLine], pen_changes: dict[int, int]) -> list[tuple[int, int]]:
    """(first G-code line of the change, aperture) for each pen change, in order."""
    found = []
    for command in sorted(pen_changes):
        first = next((i for i, line in enumerate(lines) if line.command >= command), None)
        if first is not None:
            found.append((first, pen_changes[command]))
    return found


def _source_line(planned: PlannedFile, command: int) -> int:
    job = planned.job
    if not 0 <= command < len(job.op_index) or job.op_index[command] < 0:
        return 0
    op = planned.plotted.op(job.op_index[command])
    pos = getattr(op, "pos", None) or getattr(op, "source", None)
    return pos.line if pos is not None else 0


def _hold_and_reset(link: GrblLink) -> None:
    """Ctrl-C: a feed hold decelerates on the path (no step lost), then the soft
    reset drops GRBL's queue; a reset while moving would lose the position."""
    try:
        link.realtime(FEED_HOLD)
        deadline = time.monotonic() + HOLD_WAIT_S
        while time.monotonic() < deadline:
            status = link.status()
            if status.state == "Idle" or (status.state == "Hold" and status.substate == 0):
                break
        link.soft_reset()
    except GrblError:
        pass        # the user already asked to stop; the message says what to do


def _write_preview(path: str, planned: PlannedFile, config, out: TextIO) -> None:
    """The plan as our reference machine steps it: GRBL cannot report its steps."""
    from galileo_cnc.machine import simulate
    from galileo_cnc.preview.render import render_preview
    trace = simulate(planned.job.commands, config)
    info = render_preview(planned.program, trace, config, planned.offset_nm, path,
                          job=planned.job, copper=planned.copper)
    out.write(f"preview: {path}: {info.summary()} (the plan: GRBL cannot report its steps)\n")
