"""`galileo-cnc plot` on a stock GRBL 1.1 board (docs/grbl.md).

Plans the file as on our firmware, connects (`GrblLink`), refuses a profile
whose steps/mm differ from GRBL's `$100-$102` (the drawing would come out at
the wrong size), writes the job as GRBL G-code, prints GRBL's time estimate,
checks the job against GRBL's travel before the first byte, and streams it with
a progress line, stopping at each pen change. `--check` instead runs the job
through GRBL's check mode (`$C`) and lists every line GRBL rejects.
`--resume` continues a job whose port was lost: GRBL was reset by the reopening, so
it homes (or the user re-zeroes), then goes on after the last line GRBL had
acknowledged, from the GRBL job journal (docs/grbl.md, "Resume after a lost port").
Exit codes as `plot`: 0 done (or nothing rejected), 1 refused, rejected or
alarmed, 3 port lost (resume with --resume), 130 stopped with Ctrl-C.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

import serial

from galileo_cnc.cli.plot import (EXIT_FAILED, EXIT_INTERRUPTED, EXIT_OK, EXIT_PORT_LOST,
                                  TextProgress)
from galileo_cnc.config.machine import MachineConfig, tomllib
from galileo_cnc.config.profile import Profile
from galileo_cnc.config.userdirs import data_dir
from galileo_cnc.errors import GalileoError
from galileo_cnc.grbl.check import check_job
from galileo_cnc.grbl.estimate import Machine, estimate
from galileo_cnc.grbl.gcode import AxisScale, GcodeLine, job_to_gcode, pen_from_config, source_of
from galileo_cnc.grbl.jog import home, unlock
from galileo_cnc.grbl.link import GrblLink
from galileo_cnc.grbl.reports import GrblError
from galileo_cnc.grbl.session import (describe, hold_and_reset, pen_pieces, position_text,
                                      refuse_other_scale, source_line, stream_piece)
from galileo_cnc.grbl.resume import STEPPER_BLOCKS, GrblResumeError, lead_in, rewind
from galileo_cnc.grbl.stream import GrblStreamError
from galileo_cnc.grbl.travel import applies, check_travel
from galileo_cnc.machine.timing import duration_text
from galileo_cnc.plan.pipeline import PlannedFile, PlanOptions, plan_file
from galileo_cnc.program.ops import NM_PER_MM
from galileo_cnc.stream.journal import (ABORTED, FAILED, FINISHED, INTERRUPTED, RUNNING,
                                        Journal, JournalEntry, file_digest)
from galileo_cnc.stream.streamer import PenChange, describe_aperture
from galileo_cnc.transport.port import open_port, port_error_text

#: The GRBL job journal's file in the user's data folder (beside our firmware's).
GRBL_JOURNAL_NAME = "journal-grbl.json"


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
    progress = GrblProgress(out)
    journal = grbl_journal()
    entry = None
    if options.resume:                  # planned again from the journal, as it was
        entry = _pending(journal, options.file)
        config = MachineConfig.from_mapping(tomllib.loads(entry.profile), "journal")
        planned = _replan(entry, config)
    else:
        config = options.profile.config
        planned = plan_file(options.file, config, options.offset, margin_nm=options.margin_nm,
                            on_progress=progress.planning, options=options.plan)
    port = port if port is not None else open_grbl_port(options.port, options.profile.baud)
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
            start = _resume_start(link, entry, lines, progress)
            if start >= len(lines):
                journal.begin(entry)
                journal.end(FINISHED, "every line was acknowledged before the port was lost")
                progress.message("nothing left to resume: GRBL had acknowledged every line "
                                 "of the job")
                return EXIT_OK
            _find_position(link, scale, pen, options.yes, progress)
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
        _journal_begin(journal, entry, planned, config, scale, lines, start, now)
        refused = []

        def replied(number: int, reply) -> None:
            refused.extend([] if reply.ok else [number])
            if not refused:             # nothing after a refused line counts as done
                journal.confirm(number)

        began = time.monotonic()
        try:
            _stream_with_pen_changes(link, planned, lines, where, progress, options.yes,
                                     guess.seconds, start=start, lead=lead, on_reply=replied)
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
        progress.message(f"\aprocess has finished in {duration_text(time.monotonic() - began)}; "
                         f"{position_text(link.tracker.last)}")
    except (serial.SerialException, OSError) as lost:     # before or after the job
        raise GalileoError(f"{options.port}: {port_error_text(lost)}") from None
    finally:
        port.close()
    if options.preview:
        _write_preview(options.preview, planned, config, out)
    return EXIT_OK


# ---- the journal and resume -----------------------------------------------------------

def grbl_journal() -> Journal:
    """The GRBL job journal: our firmware's format (stream/journal.py), in a file of its
    own (a journal of one backend is never resumed on the other), counting G-code lines
    where ours counts commands: `total` G-code lines, `confirmed` the last line GRBL
    answered `ok` (with none refused before it), `first_index` the line the session
    began with, `first_seq` 0 (GRBL numbers no lines)."""
    return Journal(data_dir() / GRBL_JOURNAL_NAME)


def _pending(journal: Journal, file: str) -> JournalEntry:
    entry = journal.pending()
    if entry is None or Path(entry.source) != Path(file).resolve():
        raise GalileoError(f"no interrupted GRBL job of {file} to resume "
                           f"(journal {journal.path})")
    if not Path(entry.source).exists():
        raise GrblResumeError(f"{entry.source}: the file of the interrupted job is gone")
    if file_digest(entry.source) != entry.digest:
        raise GrblResumeError(f"{entry.source} changed since the job was planned: it cannot "
                              f"be resumed; plot it again")
    return entry


def _replan(entry: JournalEntry, config: MachineConfig) -> PlannedFile:
    """The interrupted job, planned again exactly as it was (the planner is deterministic)."""
    return plan_file(entry.source, config, tuple(entry.offset_nm),
                     options=PlanOptions(mode=entry.mode, file_order=not entry.group,
                                         pens_nm=tuple(entry.pens_nm),
                                         layers=tuple(entry.layers), units=entry.units),
                     optimize=entry.ordered)


def _resume_start(link: GrblLink, entry: JournalEntry, lines: list[GcodeLine],
                  progress: GrblProgress) -> int:
    """The G-code line to continue from: after the last one GRBL acknowledged, or,
    when GRBL's queue was cut short (reset while moving: ALARM:3 on connecting; the
    job stopped by Ctrl-C or an alarm), the first one that may not have run."""
    if len(lines) != entry.total:
        raise GrblResumeError(f"the replanned job has {len(lines)} G-code lines, the "
                              f"interrupted one had {entry.total}: it cannot be resumed")
    acked = entry.confirmed + 1
    if 3 in link.alarms or entry.state in (ABORTED, FAILED):
        depth = (link.build.planner_blocks or 15) + STEPPER_BLOCKS
        start = rewind(lines, entry.confirmed, entry.first_index, depth)
        why = ("GRBL was reset while it still moved (ALARM:3)" if 3 in link.alarms else
               f"the job was {entry.state} ({entry.reason})" if entry.reason else
               f"the job was {entry.state}")
        progress.message(f"resuming at G-code line {start + 1} of {len(lines)}: {why}, so "
                         f"the {acked - start} lines before line {acked + 1} that GRBL had "
                         f"queued may not have run")
    else:
        start = acked
        progress.message(f"resuming at G-code line {start + 1} of {len(lines)}, after the "
                         f"last line GRBL acknowledged")
    return start


def _find_position(link: GrblLink, scale: AxisScale, pen, yes: bool,
                   progress: GrblProgress) -> None:
    """Opening the port reset GRBL: its position is lost. Homes with $H when GRBL has
    homing ($22=1; the work offset G54 is in its EEPROM), else the user puts the pen
    on the job's work zero and that becomes G54's zero."""
    if link.settings.homing:
        progress.message("homing ($H): the reset lost GRBL's position")
        status = home(link)
        wco = ", ".join(f"{nm / NM_PER_MM:.3f}" for nm in link.tracker.wco_nm)
        progress.message(f"homed; work offset (G54, kept in GRBL's EEPROM) {wco} mm, "
                         f"state {status.state}")
        return
    down = scale.mm(2, pen.down_z_steps)
    progress.message(f"\aGRBL has no homing ($22=0): the reset lost its position. Move the "
                     f"pen to the job's work zero (X0 Y0, the pen down on the paper: Z{down})"
                     + (": --yes takes the machine as standing there" if yes
                        else ", then press Enter"))
    if not yes:
        sys.stdin.readline()
    if link.status().state == "Alarm":
        unlock(link)
    link.command_checked(f"G10 L20 P1 X0 Y0 Z{down}")


def _warn_g92(link: GrblLink, progress: GrblProgress) -> None:
    """A G92 offset is lost on any reset, so a resume could not restore it: say so."""
    reply = link.command("$#")
    g92 = next((line for line in reply.lines if line.startswith("[G92:")), "")
    if g92 and any(float(v) != 0 for v in g92[5:-1].split(",")):
        progress.message(f"note: GRBL has a G92 offset {g92}: GRBL forgets it on a reset, "
                         f"so a --resume after a lost port could not restore it (set the "
                         f"work zero with G10 L20 instead)")


def _journal_begin(journal: Journal, entry: JournalEntry | None, planned: PlannedFile,
                   config: MachineConfig, scale: AxisScale, lines: list[GcodeLine],
                   start: int, now) -> None:
    if entry is not None:               # the same job, a new session from `start`
        entry.state, entry.reason = RUNNING, ""
        entry.first_index, entry.confirmed = start, start - 1
        journal.begin(entry)
        return
    job = planned.job
    source = str(Path(job.source).resolve())
    try:
        digest = file_digest(source)
    except OSError:
        digest = ""
    here = tuple(round(nm * float(scale.steps_per_mm[a]) / NM_PER_MM)
                 for a, nm in enumerate(now.wpos_nm))
    journal.begin(JournalEntry(
        source, digest, job.offset_nm, config.to_toml(), job.grouped, len(lines), -1, 0, 0,
        start_position=here, mode=job.mode, ordered=job.ordered,
        pens_nm=tuple(job.pens_nm), layers=tuple(job.layers), units=job.units))


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
    """Streams lines[start:] (after the `lead` lines, a resume's lead-in) in pieces that
    end at the job's pen changes: each piece runs to a stop (GRBL's buffer drained)
    before the user is asked for a pen. `on_reply(line number in the job, reply)`."""
    job = planned.job
    total = len(lines)
    began = time.monotonic()

    def show(done: int) -> None:
        eta = max(0.0, estimate_s - (time.monotonic() - began))
        progress.lines(done, total, source_line(planned, lines[done - 1].command), eta)

    def ask(first: int, aperture: int, resuming: bool = False) -> None:
        label = job.pen_labels.get(aperture) or \
            f"pen for aperture {describe_aperture(planned.program, aperture)}"
        change = PenChange(aperture, label, lines[first].command)
        progress.message(f"\a{change.prompt}" + (" (the pen the job goes on with)"
                                                  if resuming else "")
                         + ("" if yes else ", then press Enter"))
        if not yes:
            sys.stdin.readline()

    pieces = pen_pieces(lines, job.pen_changes)
    before = [piece for piece in pieces if piece[0] < start]
    if before and not any(first == start for first, _ in pieces):
        # resuming: the pen in the holder may be another (a change at `start` asks anyway)
        ask(*before[-1], resuming=True)
    position, chunk = start, list(lead)
    numbers: list[int | None] = [None] * len(lead)
    for first, aperture in pieces:
        if first < start:
            continue
        if first > position or chunk:
            stream_piece(link, chunk + lines[position:first],
                          numbers + list(range(position, first)), where, show, on_reply)
            position, chunk, numbers = first, [], []
        ask(first, aperture)
    stream_piece(link, chunk + lines[position:total], numbers + list(range(position, total)),
                  where, show, on_reply)


def _write_preview(path: str, planned: PlannedFile, config, out: TextIO) -> None:
    """The plan as our reference machine steps it: GRBL cannot report its steps."""
    from galileo_cnc.machine import simulate
    from galileo_cnc.preview.render import render_preview
    trace = simulate(planned.job.commands, config)
    info = render_preview(planned.program, trace, config, planned.offset_nm, path,
                          job=planned.job, copper=planned.copper)
    out.write(f"preview: {path}: {info.summary()} (the plan: GRBL cannot report its steps)\n")
