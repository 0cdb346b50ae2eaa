"""`getg` and `resume` on GRBL: the planned file as GRBL G-code, streamed under the
console's progress bar and journalled, the way `galileo-cnc plot` does it on a GRBL
board (cli/plot_grbl.py uses this module's journal pieces, so both keep one journal).

G-code from `job_to_gcode` (the pen as the profile's Z heights or servo), GRBL's own
time estimate, the travel check on a homed machine before the first byte, then the
job in pieces that end at the pen changes (grbl/session.py's `stream_job`, as plot
does: each piece runs to a stop, a refusal or an alarm is named with GRBL's text, the
file line and its G-code line in the whole job). The bar, Enter at a pen change and
q/Ctrl-C are job_screen.JobScreen's, as on our firmware. A stop holds the feed (GRBL
decelerates on its path) and then soft-resets GRBL: its queue is dropped, its
position kept.

The journal: stream/journal.py's format and code in its own file, journal-grbl.json
(docs/grbl.md, "Resume after a lost port"), counting G-code lines. It lives here,
not in grbl/, because grbl/ and stream/ share a stage and may not import each other
(docs/architecture.md); `plot` (cli, a later stage) imports it from here. `resume`
continues a job of either front end: it replans the journal's file with the
journal's profile, homes ($H) or has the user re-zero, sends the lead-in and goes on
after the last line GRBL acknowledged (or, when GRBL's queue was cut short, from the
first line that may not have run).
"""

from __future__ import annotations

import time
from pathlib import Path

import serial

from galileo_cnc.config.machine import MachineConfig, tomllib
from galileo_cnc.config.userdirs import data_dir
from galileo_cnc.console.grbl_backend import JobInterrupted
from galileo_cnc.console.job_screen import BELL, JobScreen
from galileo_cnc.errors import GalileoError
from galileo_cnc.grbl.estimate import Machine, estimate
from galileo_cnc.grbl.gcode import (AxisScale, GcodeLine, job_to_gcode, pen_from_config,
                                    source_of)
from galileo_cnc.grbl.reports import GrblError
from galileo_cnc.grbl.resume import GrblResumeError, lead_in, resume_start
from galileo_cnc.grbl.session import (
    find_position,
    hold_and_reset,
    position_text,
    refuse_other_scale,
    source_line,
    stream_job,
)
from galileo_cnc.grbl.stream import GrblStreamError
from galileo_cnc.grbl.travel import applies, check_travel
from galileo_cnc.machine.timing import duration_text
from galileo_cnc.plan.pipeline import PlannedFile
from galileo_cnc.program.ops import NM_PER_MM
from galileo_cnc.stream.journal import (ABORTED, FAILED, FINISHED, INTERRUPTED, RUNNING,
                                        Journal, JournalEntry, file_digest)
from galileo_cnc.stream.resume import replan
from galileo_cnc.stream.streamer import (
    PenChange,
    Progress,
    StreamAborted,
    StreamResult,
    describe_aperture,
)
from galileo_cnc.transport.port import port_error_text

STOPPED = "stopped by the user"
#: The GRBL job journal's file in the user's data folder (beside our firmware's).
GRBL_JOURNAL_NAME = "journal-grbl.json"
#: Added to the pen asked for when a job goes on past a pen change.
GOES_ON_WITH = " (the pen the job goes on with)"


# ---- the journal: shared with `galileo-cnc plot` ----------------------------------------

def grbl_journal() -> Journal:
    """The GRBL job journal: our firmware's format (stream/journal.py), in a file of its
    own (a journal of one backend is never resumed on the other), counting G-code lines
    where ours counts commands: `total` G-code lines, `confirmed` the last line GRBL
    answered `ok` (with none refused before it), `first_index` the line the session
    began with, `first_seq` 0 (GRBL numbers no lines)."""
    return Journal(data_dir() / GRBL_JOURNAL_NAME)


def pending_job(journal: Journal, file: str | None = None) -> JournalEntry:
    """The interrupted GRBL job (of `file` when given), its file unchanged since it was
    planned (SHA-256); GalileoError saying why not."""
    entry = journal.pending()
    if entry is None or (file is not None and Path(entry.source) != Path(file).resolve()):
        of = f" of {file}" if file is not None else ""
        raise GalileoError(f"no interrupted GRBL job{of} to resume (journal {journal.path})")
    if not Path(entry.source).exists():
        raise GrblResumeError(f"{entry.source}: the file of the interrupted job is gone")
    if file_digest(entry.source) != entry.digest:
        raise GrblResumeError(f"{entry.source} changed since the job was planned: it cannot "
                              f"be resumed; plot it again")
    return entry


def journal_config(entry: JournalEntry) -> MachineConfig:
    """The profile the interrupted job was planned with (kept in the journal)."""
    return MachineConfig.from_mapping(tomllib.loads(entry.profile), "journal")


def check_same_job(entry: JournalEntry, lines: list[GcodeLine]) -> None:
    """The replanned job's G-code must have the interrupted job's line count (else it
    is not the same job: another GRBL scale, a changed planner)."""
    if len(lines) != entry.total:
        raise GrblResumeError(f"the replanned job has {len(lines)} G-code lines, the "
                              f"interrupted one had {entry.total}: it cannot be resumed")


#: States in which a board that did not reset on opening had not run its queue out.
NOT_RUN_OUT = ("Hold", "Door", "Run", "Jog")


def cut_short(link, entry: JournalEntry) -> str | None:
    """Why GRBL's queue may have been cut before it ran every acknowledged line, None
    when it ran on: GRBL was reset while it moved (`ALARM:3` on connecting) or while
    it stood held (a feed-hold button: no ALARM:3, but the queue is dropped all the
    same), or the job was stopped (q, Ctrl-C: hold and reset) or stopped by an alarm
    or a refusal."""
    if 3 in link.alarms:
        return "GRBL was reset while it still moved (ALARM:3)"
    if link.state_before_reset in NOT_RUN_OUT:
        return f"GRBL stood in {link.state_before_reset} with lines still queued"
    if entry.state in (ABORTED, FAILED):
        return f"the job was {entry.state} ({entry.reason})" if entry.reason else \
            f"the job was {entry.state}"
    return None


def journal_begin(journal: Journal, entry: JournalEntry | None, planned: PlannedFile,
                  config: MachineConfig, scale: AxisScale, lines: list[GcodeLine],
                  start: int, now) -> None:
    """A new job (entry None; `now`: GRBL's status before it), or the interrupted
    `entry` going on as a new session from line `start`."""
    if entry is not None:
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


def journal_replies(journal: Journal):
    """on_reply for stream_job: each `ok` confirms its line, none after a refused one."""
    refused: list[int] = []

    def replied(number: int, reply) -> None:
        if not reply.ok:
            refused.append(number)
        if not refused:
            journal.confirm(number)
    return replied


def job_gcode(link, planned: PlannedFile, config: MachineConfig) -> list[GcodeLine]:
    settings = link.settings
    scale = AxisScale.from_texts([settings.steps_per_mm_text(a) for a in range(3)])
    return job_to_gcode(planned.job, scale, pen_from_config(config),
                        feed_steps_per_s=config.feed_steps_per_s,
                        flash_dwell_ms=config.flash_dwell_ms)


# ---- the job on screen ------------------------------------------------------------------

class GrblJob:
    """One planned file as G-code lines, streamed from line `start` (after a resume's
    lead-in) by `run` (in the console's thread) and stopped by `abort` (from the
    progress bar's key thread)."""

    def __init__(self, backend, planned: PlannedFile, config: MachineConfig,
                 lines: list[GcodeLine] | None = None):
        self.backend = backend
        self.link = backend.link
        self.planned = planned
        settings = self.link.settings
        self.scale = AxisScale.from_texts([settings.steps_per_mm_text(a) for a in range(3)])
        self.pen = pen_from_config(config)
        self.lines = lines if lines is not None else job_gcode(self.link, planned, config)
        self.where = lambda command: source_of(planned.plotted, planned.job, command)
        self.start = 0
        self.lead: list[GcodeLine] = []
        self.journal: Journal | None = None
        self.estimate_s = self._estimate()

    def go_on_from(self, start: int) -> None:
        """Stream from line `start`, after the lead-in that brings GRBL there."""
        self.start = start
        self.lead = lead_in(self.lines, start, self.scale, self.pen)
        self.estimate_s = self._estimate()

    @property
    def rest(self) -> list[GcodeLine]:
        return self.lead + self.lines[self.start:]

    def _estimate(self) -> float:
        machine = Machine.from_settings(self.link.settings, self.link.build.planner_blocks)
        return estimate(self.rest, machine).seconds

    def check_travel(self) -> None:
        """TravelError (the file line, the axis, the limit) before the first byte, when
        GRBL knows where its travel is ($20 or $22): nothing is sent then."""
        settings = self.link.settings
        if applies(settings):
            now = self.link.status()
            check_travel(self.rest, settings, self.link.tracker.wco_nm, now.mpos_nm,
                         where=self.where)

    def abort(self) -> None:
        self.backend.stop_job()

    def run(self, on_progress, on_pen_change) -> StreamResult:
        job, lines, total = self.planned.job, self.lines, len(self.lines)
        began = time.monotonic()
        done = self.start

        def show(count: int) -> None:
            nonlocal done
            done = count
            elapsed = time.monotonic() - began
            on_progress(Progress(count, total, elapsed, max(0.0, self.estimate_s - elapsed),
                                 source_line(self.planned, lines[count - 1].command)))

        def ask_pen(first: int, aperture: int, resuming: bool) -> None:
            label = job.pen_labels.get(aperture) or \
                f"pen for aperture {describe_aperture(self.planned.program, aperture)}"
            on_pen_change(PenChange(aperture, label + (GOES_ON_WITH if resuming else ""),
                                    lines[first].command))

        on_reply = journal_replies(self.journal) if self.journal is not None else None
        port = self.backend.port
        port.arm()
        try:
            stream_job(self.link, lines, job.pen_changes, self.where, show, ask_pen,
                       start=self.start, lead=self.lead, on_reply=on_reply)
        except (JobInterrupted, StreamAborted):
            port.disarm()
            hold_and_reset(self.link)      # decelerate, then drop GRBL's queue
            return StreamResult(False, done, total, time.monotonic() - began, STOPPED)
        finally:
            port.disarm()
        return StreamResult(True, total, total, time.monotonic() - began)


def plot_on_grbl(console, backend, planned: PlannedFile, config: MachineConfig) -> None:
    """getg's job: estimated, travel-checked, journalled and streamed."""
    job = GrblJob(backend, planned, config)
    pens = len(planned.job.pen_changes)
    console.say(f"{len(job.lines)} G-code lines, {pens} pen change{'s' * (pens != 1)}, "
                f"about {duration_text(job.estimate_s)} on GRBL (its planner's estimate)")
    job.check_travel()
    job.journal = grbl_journal()
    journal_begin(job.journal, None, planned, config, job.scale, job.lines, 0,
                  backend.link.status())
    _run_journalled(console, backend, job)


def resume_on_grbl(console, backend) -> None:
    """`resume` on GRBL: the job the GRBL journal holds (from getg or plot), continued
    as `plot --resume` does it."""
    journal = grbl_journal()
    if journal.pending() is None:
        console.say(f"no interrupted GRBL job to resume (journal {journal.path})")
        return
    entry = pending_job(journal)
    link = backend.link
    config = journal_config(entry)
    refuse_other_scale(link, config.steps_per_mm, backend.config_path, backend.port_name)
    planned = replan(entry, config, on_stage=console.say_stage, plan=console.plans.plan_file)
    lines = job_gcode(link, planned, config)
    check_same_job(entry, lines)
    start, why = resume_start(lines, entry.confirmed, entry.first_index,
                              link.build.planner_blocks, cut_short(link, entry))
    console.say(f"{entry.source}: {why}")
    if start >= len(lines):
        journal.begin(entry)
        journal.end(FINISHED, "every line was acknowledged before the job stopped")
        console.say("nothing left to resume: GRBL had acknowledged every line of the job")
        return
    if not console.confirm("continue the job?"):
        return
    job = GrblJob(backend, planned, config, lines)

    def at_work_zero(question: str) -> bool:
        return console.confirm(f"{BELL}{question}. Is it there?", default=False)

    try:
        found = find_position(link, job.scale, job.pen, console.say, at_work_zero)
    except GrblError as problem:
        if not problem.alarm:
            raise
        backend.settle()                # what GRBL still says after the alarm
        return                          # the console prints the alarm and the hint
    if not found:
        console.say("then move it there (setup jogs the head), and type resume again")
        return
    job.go_on_from(start)
    console.say(f"{len(lines) - start} G-code lines, about {duration_text(job.estimate_s)} "
                f"on GRBL (its planner's estimate)")
    job.check_travel()
    job.journal = journal
    journal_begin(journal, entry, planned, config, job.scale, lines, start, None)
    _run_journalled(console, backend, job)


def _run_journalled(console, backend, job: GrblJob) -> None:
    """The job under the progress bar; the journal says how it ended."""
    journal, link, total = job.journal, backend.link, len(job.lines)
    screen = JobScreen(console, job.planned.program.source, total, start=job.start)
    try:
        result = screen.run(job.run, job.abort)
    except GrblStreamError as stopped:
        journal.end(FAILED, str(stopped))
        backend.news()                  # the alarm is in this message, with its file line
        console.say(str(stopped))
        return                          # the console adds the unlock hint when locked
    except (serial.SerialException, OSError) as lost:
        journal.end(INTERRUPTED, port_error_text(lost))
        console.say(f"GRBL had acknowledged {journal.entry.confirmed + 1} of {total} G-code "
                    f"lines and runs on with the lines it had; once the machine stands "
                    f"still, connect again and type resume")
        raise                           # the console says the port is gone
    except KeyboardInterrupt:
        journal.end(ABORTED, "stopped with Ctrl-C")
        raise                           # the console stops the machine
    except GrblError as problem:
        journal.end(FAILED, str(problem))
        raise
    if result.completed:
        journal.end(FINISHED)
        console.say(f"{BELL}process has finished in {duration_text(result.elapsed_s)} "
                    f"({result.total} G-code lines); {position_text(link.tracker.last)}")
        return
    journal.end(ABORTED, result.reason)
    try:
        where = position_text(link.status())
    except GrblError:
        where = "GRBL's position was not reported"
    console.say(f"job stopped after {result.confirmed} of {result.total} G-code lines: "
                f"{result.reason}; GRBL held the feed and was reset (its queue dropped, "
                f"the position kept); {where}; type resume to continue it")
