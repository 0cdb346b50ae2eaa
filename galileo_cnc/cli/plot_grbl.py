"""`galileo-cnc plot` on a stock GRBL 1.1 board (docs/grbl.md).

Plans the file as on our firmware, connects (`GrblLink`), refuses a profile
whose steps/mm differ from GRBL's `$100-$102` (the drawing would come out at
the wrong size), writes the job as GRBL G-code, prints GRBL's time estimate,
checks the job against GRBL's travel before the first byte, and streams it with
a progress line, stopping at each pen change. `--check` instead runs the job
through GRBL's check mode (`$C`) and lists every line GRBL rejects.
`--resume` continues a job whose port was lost: GRBL was reset by the reopening, so
it homes (or the user re-zeroes), then goes on after the last line GRBL had
acknowledged, from the GRBL job journal (docs/grbl.md, "Resume after a lost port"),
which the console's getg and resume keep too (console/grbl_job.py holds it).
`--trace` writes the steps GRBL's pins made on `simavr://?firmware=grbl` (a real
board cannot report its steps: the reference machine's trace of the job, saying so).
Exit codes as `plot`: 0 done (or nothing rejected), 1 refused, rejected or
alarmed, 3 port lost (resume with --resume), 130 stopped with Ctrl-C.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from typing import TextIO

import serial

from galileo_cnc.cli.plot import (EXIT_FAILED, EXIT_INTERRUPTED, EXIT_OK, EXIT_PORT_LOST,
                                  TextProgress)
from galileo_cnc.config.profile import Profile
from galileo_cnc.console.grbl_job import (GOES_ON_WITH, GRBL_JOURNAL_NAME, check_same_job,
                                          cut_short, grbl_journal, journal_begin,
                                          journal_config, journal_replies, pending_job)
from galileo_cnc.errors import GalileoError
from galileo_cnc.grbl.check import check_job
from galileo_cnc.grbl.estimate import Machine, estimate
from galileo_cnc.grbl.gcode import AxisScale, GcodeLine, job_to_gcode, pen_from_config, source_of
from galileo_cnc.grbl.link import GrblLink
from galileo_cnc.grbl.reports import GrblError
from galileo_cnc.grbl.resume import lead_in, resume_start
from galileo_cnc.grbl.session import (describe, find_position, hold_and_reset, position_text,
                                      refuse_other_scale, source_line, stream_job)
from galileo_cnc.grbl.stream import GrblStreamError
from galileo_cnc.grbl.travel import applies, check_travel
from galileo_cnc.machine.timing import duration_text
from galileo_cnc.machine.trace import Trace
from galileo_cnc.plan.pipeline import PlannedFile, PlanOptions, plan_file
from galileo_cnc.program.ops import NM_PER_MM
from galileo_cnc.simavr.grbl_firmware import grbl_step_trace
from galileo_cnc.stream.journal import ABORTED, FAILED, FINISHED, INTERRUPTED
from galileo_cnc.stream.resume import replan
from galileo_cnc.stream.streamer import PenChange, describe_aperture
from galileo_cnc.transport.port import open_port, port_error_text, with_step_trace

__all__ = ["GRBL_JOURNAL_NAME", "GrblPlotOptions", "grbl_journal", "run_grbl_plot"]


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
    resume: bool = False            # continue the journal's job (its file, offset, profile)
    trace: str | None = None        # write the steps (simavr://: GRBL's pins) as .npz


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


def run_grbl_plot(options: GrblPlotOptions, out: TextIO | None = None, port=None) -> int:
    """`port`: an already open port to use (and close) instead of opening options.port."""
    out = out if out is not None else sys.stdout
    if options.check and options.trace:
        raise GalileoError("plot --check --trace: check mode moves nothing, so there are no "
                           "steps to trace")
    progress = GrblProgress(out)
    journal = grbl_journal()
    entry = None
    with progress.staging() as on_stage:
        if options.resume:              # planned again from the journal, as it was
            entry = pending_job(journal, options.file)
            config = journal_config(entry)
            planned = replan(entry, config, on_stage=on_stage)
        else:
            config = options.profile.config
            planned = plan_file(options.file, config, options.offset,
                                margin_nm=options.margin_nm, on_progress=progress.planning,
                                on_stage=on_stage, options=options.plan)
    if port is None:                    # simavr:// records GRBL's pins for --trace
        port = open_grbl_port(with_step_trace(options.port) if options.trace else
                              options.port, options.profile.baud)
    board = getattr(port, "board", None)
    board = board if board is not None and board.records_steps else None
    try:
        link = GrblLink.connect(port)
        out.write(describe(link, options.port) + "\n")
        refuse_other_scale(link, config.steps_per_mm, options.profile.path, options.port)
        scale = AxisScale.from_texts([link.settings.steps_per_mm_text(a) for a in range(3)])
        pen = pen_from_config(config)
        lines = job_to_gcode(planned.job, scale, pen, feed_steps_per_s=config.feed_steps_per_s,
                             flash_dwell_ms=config.flash_dwell_ms)
        where = lambda command: source_of(planned.plotted, planned.job, command)
        _say_plan(planned, out)
        if options.check:
            report = check_job(link, lines, where=where)
            out.write(f"GRBL check mode ($C): {report}\n")
            return EXIT_OK if report.ok else EXIT_FAILED
        start, lead = 0, []
        if entry is not None:
            check_same_job(entry, lines)
            start, why = resume_start(lines, entry.confirmed, entry.first_index,
                                      link.build.planner_blocks, cut_short(link, entry))
            progress.message(why)
            if start >= len(lines):
                journal.begin(entry)
                journal.end(FINISHED, "every line was acknowledged before the port was lost")
                progress.message("nothing left to resume: GRBL had acknowledged every line "
                                 "of the job")
                return EXIT_OK
            find_position(link, scale, pen, progress.message,
                          lambda question: _at_work_zero(question, options.yes, progress))
            lead = lead_in(lines, start, scale, pen)
        else:
            _warn_g92(link, progress)
        rest = lead + lines[start:]
        guess = estimate(rest, Machine.from_settings(link.settings, link.build.planner_blocks))
        out.write(f"{len(lines) - start} G-code lines, about {duration_text(guess.seconds)} "
                  f"on GRBL (its planner's estimate)\n")
        now = link.status()
        if applies(link.settings):      # machine coordinates are known only once homed
            check_travel(rest, link.settings, link.tracker.wco_nm, now.mpos_nm, where=where)
        journal_begin(journal, entry, planned, config, scale, lines, start, now)
        began = time.monotonic()
        try:
            _stream_with_pen_changes(link, planned, lines, where, progress, options.yes,
                                     guess.seconds, start=start, lead=lead,
                                     on_reply=journal_replies(journal))
        except GrblStreamError as stopped:
            journal.end(FAILED, str(stopped))
            progress.message(f"galileo-cnc: {stopped}")
            if stopped.alarm:
                progress.message("GRBL is locked in alarm: its position may be lost; home "
                                 "or re-zero, then unlock it with $X")
            return EXIT_FAILED
        except (serial.SerialException, OSError) as lost:
            journal.end(INTERRUPTED, port_error_text(lost))
            done = journal.entry.confirmed + 1
            progress.message(f"galileo-cnc: {options.port}: {port_error_text(lost)} "
                             f"(GRBL had acknowledged {done} of {len(lines)} G-code lines)")
            progress.message(f"GRBL runs on with the lines it had; once the machine stands "
                             f"still the job can continue: galileo-cnc plot {options.file} "
                             f"--resume")
            return EXIT_PORT_LOST
        except KeyboardInterrupt:
            hold_and_reset(link)
            journal.end(ABORTED, "stopped with Ctrl-C")
            progress.message("stopped: GRBL held the feed, then was reset (its queue is "
                             "dropped, the position kept)")
            return EXIT_INTERRUPTED
        except GrblError as problem:
            journal.end(FAILED, str(problem))
            raise
        journal.end(FINISHED)
        final = link.tracker.last
        progress.message(f"\aprocess has finished in {duration_text(time.monotonic() - began)}; "
                         f"{position_text(final)}")
    except (serial.SerialException, OSError) as lost:     # before or after the job
        raise GalileoError(f"{options.port}: {port_error_text(lost)}") from None
    finally:
        port.close()                    # simavr: the board stops, its pin record is whole
    if options.trace:
        _write_trace(options.trace, board, link.settings, scale, final, planned, config,
                     options.port, out)
    if options.preview:
        _write_preview(options.preview, planned, config, out)
    return EXIT_OK


def _at_work_zero(question: str, yes: bool, progress: GrblProgress) -> bool:
    """plot's way to re-zero: the user puts the pen there and presses Enter."""
    progress.message(f"\a{question}: move it there"
                     + (" (--yes takes the machine as standing there)" if yes
                        else ", then press Enter"))
    if not yes:
        sys.stdin.readline()
    return True


def _warn_g92(link: GrblLink, progress: GrblProgress) -> None:
    """A G92 offset is lost on any reset, so a resume could not restore it: say so."""
    reply = link.command("$#")
    g92 = next((line for line in reply.lines if line.startswith("[G92:")), "")
    if g92 and any(float(v) != 0 for v in g92[5:-1].split(",")):
        progress.message(f"note: GRBL has a G92 offset {g92}: GRBL forgets it on a reset, "
                         f"so a --resume after a lost port could not restore it (set the "
                         f"work zero with G10 L20 instead)")


def _write_trace(path: str, board, settings, scale: AxisScale, final, planned: PlannedFile,
                 config, port_name: str, out: TextIO) -> None:
    """The steps GRBL's pins made (simavr://, recorded from the board's power-on), in
    plot --trace's format (machine/trace.py), its final position GRBL's last work
    position; from a real board, which cannot report its steps, the reference
    machine's trace of the job, and the line says so."""
    if board is None:
        from galileo_cnc.machine import simulate
        trace = simulate(planned.job.commands, config)
        trace.save(path)
        out.write(f"step trace: {path} ({len(trace)} steps): the reference machine's, since "
                  f"{port_name} cannot report its steps\n")
        return
    tick, axis, direction = grbl_step_trace(board.trace(), settings.integer(3))
    here = tuple(round(nm * float(scale.steps_per_mm[a]) / NM_PER_MM)
                 for a, nm in enumerate(final.wpos_nm))
    Trace(tick, axis, direction, here, int(tick[-1]) if len(tick) else 0).save(path)
    out.write(f"step trace: {path} ({len(tick)} steps, as GRBL's step pins in simavr "
              f"reported them)\n")


def open_grbl_port(port: str, baud: int):
    """The port, or a GalileoError naming it and what went wrong (a missing
    package for simavr://?firmware=grbl, a busy or vanished device)."""
    try:
        return open_port(port, baud, timeout=0.2)
    except (serial.SerialException, OSError) as problem:
        raise GalileoError(f"cannot open {port}: {port_error_text(problem)}") from None


def _say_plan(planned: PlannedFile, out: TextIO) -> None:
    box, offset = planned.artwork.drawn_box_nm, planned.offset_nm
    if box is not None:
        out.write(f"{planned.program.source}: minimum X {box[0] / NM_PER_MM:.3f} mm, "
                  f"Y {box[1] / NM_PER_MM:.3f} mm; offset {offset[0] / NM_PER_MM:.3f}, "
                  f"{offset[1] / NM_PER_MM:.3f} mm\n")


def _stream_with_pen_changes(link: GrblLink, planned: PlannedFile, lines: list[GcodeLine],
                             where, progress: GrblProgress, yes: bool, estimate_s: float, *,
                             start: int = 0, lead: list[GcodeLine] = (),
                             on_reply=None) -> None:
    """stream_job with plot's progress line and its pen questions (Enter, or
    announced with --yes)."""
    job = planned.job
    total = len(lines)
    began = time.monotonic()

    def show(done: int) -> None:
        eta = max(0.0, estimate_s - (time.monotonic() - began))
        progress.lines(done, total, source_line(planned, lines[done - 1].command), eta)

    def ask(first: int, aperture: int, resuming: bool) -> None:
        label = job.pen_labels.get(aperture) or \
            f"pen for aperture {describe_aperture(planned.program, aperture)}"
        change = PenChange(aperture, label, lines[first].command)
        progress.message(f"\a{change.prompt}" + (GOES_ON_WITH if resuming else "")
                         + ("" if yes else ", then press Enter"))
        if not yes:
            sys.stdin.readline()

    stream_job(link, lines, job.pen_changes, where, show, ask, start=start, lead=lead,
               on_reply=on_reply)


def _write_preview(path: str, planned: PlannedFile, config, out: TextIO) -> None:
    """The plan as our reference machine steps it: GRBL cannot report its steps."""
    from galileo_cnc.machine import simulate
    from galileo_cnc.preview.render import render_preview
    trace = simulate(planned.job.commands, config)
    info = render_preview(planned.program, trace, config, planned.offset_nm, path,
                          job=planned.job, copper=planned.copper)
    out.write(f"preview: {path}: {info.summary()} (the plan: GRBL cannot report its steps)\n")
