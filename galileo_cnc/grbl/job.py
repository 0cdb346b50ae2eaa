"""A planned job on a GRBL board: the twin of stream/streamer.py's JobStreamer.

G-code from `job_to_gcode` (the pen as the profile's Z heights or servo), GRBL's own
time estimate, the travel check on a homed machine before the first byte, then the
job in pieces that end at the pen changes (grbl/session.py's `stream_job`: each piece
runs to a stop, a refusal or an alarm is named with GRBL's text, the file line and
its G-code line in the whole job). A stop holds the feed (GRBL decelerates on its
path) and then soft-resets GRBL: its queue is dropped, its position kept; then the pen
is lifted (a pen left on the paper blots), and a resume's lead-in lowers it again.

The journal: stream/journal.py's format and code in its own file, journal-grbl.json
(docs/grbl.md, "Resume after a lost port"), counting G-code lines. A resume replans
the journal's file with the journal's profile, homes ($H) or has the user re-zero,
sends the lead-in and goes on after the last line GRBL acknowledged (or, when GRBL's
queue was cut short, from the first line that may not have run). Every front end
runs GRBL jobs through this module (backends/grbl.py).
"""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Callable

import serial

from galileo_cnc.config.machine import MachineConfig, tomllib
from galileo_cnc.config.userdirs import data_dir
from galileo_cnc.errors import GalileoError
from galileo_cnc.grbl.estimate import Machine, estimate
from galileo_cnc.grbl.gcode import (AxisScale, GcodeLine, job_to_gcode, pen_from_config,
                                    source_of)
from galileo_cnc.grbl.link import FEED_HOLD
from galileo_cnc.grbl.reports import GrblError
from galileo_cnc.grbl.resume import GrblResumeError, lead_in, resume_start
from galileo_cnc.grbl.session import hold_and_reset, lift_pen, source_line, stream_job
from galileo_cnc.grbl.stream import GrblStreamError
from galileo_cnc.grbl.travel import applies, check_travel
from galileo_cnc.plan.pipeline import PlannedFile
from galileo_cnc.program.ops import NM_PER_MM
from galileo_cnc.stream.journal import (ABORTED, FAILED, FINISHED, INTERRUPTED, RUNNING,
                                        Journal, JournalEntry, file_digest)
from galileo_cnc.stream.streamer import (PenChange, Progress, StreamAborted, StreamResult,
                                         describe_aperture)
from galileo_cnc.transport.link import PortGone
from galileo_cnc.transport.port import port_error_text

STOPPED = "stopped by the user"
#: The GRBL job journal's file in the user's data folder (beside our firmware's).
GRBL_JOURNAL_NAME = "journal-grbl.json"
#: Added to the pen asked for when a job goes on past a pen change.
GOES_ON_WITH = " (the pen the job goes on with)"


class JobInterrupted(Exception):
    """The user stopped the job: raised by the port's next read in the streaming thread."""


class GrblPortLost(PortGone):
    """The port went away mid-job (journalled `interrupted`); GRBL runs on with the
    lines it had, so a resume waits until it stands still."""

    def __init__(self, text: str, acknowledged: int, total: int):
        super().__init__(text)
        self.acknowledged = acknowledged
        self.total = total

    @property
    def runs_on(self) -> str:
        return (f"GRBL had acknowledged {self.acknowledged} of {self.total} G-code lines "
                f"and runs on with the lines it had")


class InterruptiblePort:
    """A pyserial port whose `readline` raises JobInterrupted (once) after `interrupt`:
    a read under way is cut short (pyserial's cancel_read, where the port has it), else
    GrblLink and grbl.stream read in short slices, so the streaming thread notices at
    once (at most a slice, 0.2 s, later) that another thread asked for a stop: the pen
    is lifted soon after the machine stands still."""

    def __init__(self, port):
        self._port = port
        self._stop = threading.Event()
        self.armed = False

    @property
    def timeout(self):
        return self._port.timeout

    @timeout.setter
    def timeout(self, value) -> None:
        self._port.timeout = value

    def interrupt(self) -> None:
        self._stop.set()
        cancel_read = getattr(self._port, "cancel_read", None)
        if cancel_read is not None:
            cancel_read()               # the read returns what it has; GrblLink keeps it

    def arm(self) -> None:
        self._stop.clear()
        self.armed = True

    def disarm(self) -> None:
        self.armed = False
        self._stop.clear()

    def readline(self, *args) -> bytes:
        if self.armed and self._stop.is_set():
            self.disarm()
            raise JobInterrupted
        return self._port.readline(*args)

    def write(self, data: bytes) -> int:
        return self._port.write(data)

    def close(self) -> None:
        self._port.close()

    def __getattr__(self, name):
        return getattr(self._port, name)


# ---- the journal ------------------------------------------------------------------------

def grbl_journal() -> Journal:
    """The GRBL job journal: our firmware's format (stream/journal.py), in a file of its
    own (a journal of one kind of machine is never resumed on the other), counting
    G-code lines where ours counts commands: `total` G-code lines, `confirmed` the last
    line GRBL answered `ok` (with none refused before it), `first_index` the line the
    session began with, `first_seq` 0 (GRBL numbers no lines)."""
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
    if link.state_before_reset in ("Run", "Jog"):       # its ALARM:3 lost (docs/grbl.md)
        return f"GRBL was reset while it still moved (it reported {link.state_before_reset})"
    if link.state_before_reset in NOT_RUN_OUT:
        return f"GRBL stood in {link.state_before_reset} with lines still queued"
    if entry.state in (ABORTED, FAILED):
        ended = "the job was aborted" if entry.state == ABORTED else "the job failed"
        return f"{ended} ({entry.reason})" if entry.reason else ended
    return None


def journal_replies(journal: Journal):
    """on_reply for stream_job: each `ok` confirms its line, none after a refused one."""
    refused: list[int] = []

    def replied(number: int, reply) -> None:
        if not reply.ok:
            refused.append(number)
        if not refused:
            journal.confirm(number)
    return replied


def link_scale(link) -> AxisScale:
    """GRBL's $100-$102 as they are written in its settings."""
    return AxisScale.from_texts([link.settings.steps_per_mm_text(a) for a in range(3)])


# ---- the job ----------------------------------------------------------------------------

class GrblJob:
    """One planned file as G-code lines, streamed from line `start` (after a resume's
    lead-in) by `run` and stopped by `stop` (from any thread); journalled when it has
    a `journal`."""

    def __init__(self, link, port: InterruptiblePort | None, planned: PlannedFile,
                 config: MachineConfig, lines: list[GcodeLine] | None = None):
        self.link = link
        self.port = port
        self.planned = planned
        self.config = config
        self.scale = link_scale(link)
        self.pen = pen_from_config(config)
        self.lines = lines if lines is not None else job_to_gcode(
            planned.job, self.scale, self.pen, feed_steps_per_s=config.feed_steps_per_s,
            flash_dwell_ms=config.flash_dwell_ms)
        self.where = lambda command: source_of(planned.plotted, planned.job, command)
        self.start = 0
        self.lead: list[GcodeLine] = []
        self.journal: Journal | None = None
        self.port_name = ""                         # for a lost port's message
        self.entry: JournalEntry | None = None      # the interrupted job going on
        self.lift_failed = ""                       # a stop left the pen down: why
        self.stopped_at_rest = False                # a stop found GRBL standing (held)
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

    def begin_journal(self, journal: Journal, entry: JournalEntry | None = None) -> None:
        """A new job in `journal` (entry None), or the interrupted `entry` going on as a
        new session from line `start`."""
        self.journal = journal
        if entry is not None:
            go_on_in(journal, entry, self.start)
            return
        job = self.planned.job
        source = str(Path(job.source).resolve())
        try:
            digest = file_digest(source)
        except OSError:
            digest = ""
        now = self.link.status()
        here = tuple(round(nm * float(self.scale.steps_per_mm[a]) / NM_PER_MM)
                     for a, nm in enumerate(now.wpos_nm))
        journal.begin(JournalEntry(
            source, digest, job.offset_nm, self.config.to_toml(), job.grouped,
            len(self.lines), -1, 0, 0, start_position=here, mode=job.mode,
            ordered=job.ordered, pens_nm=tuple(job.pens_nm), layers=tuple(job.layers),
            units=job.units, scale=str(job.scale), rotate_deg=job.rotate_deg,
            board=job.board))

    def stop(self) -> None:
        """From another thread: feed hold now (GRBL decelerates on its path), and the
        streaming thread's next read raises JobInterrupted."""
        if self.port is not None:
            self.port.write(FEED_HOLD)
            self.port.interrupt()

    def run(self, on_progress=None, on_pen_change=None) -> StreamResult:
        """The job streamed, the journal ended with how it went: a stop (`stop`, or
        StreamAborted from `on_pen_change`) holds and resets GRBL and returns; Ctrl-C
        does the same; a lost port raises GrblPortLost."""
        job, lines, total = self.planned.job, self.lines, len(self.lines)
        progress = JobProgress(total, self.start, self.estimate_s, on_progress,
                               lambda index: source_line(self.planned, lines[index].command))

        def ask_pen(first: int, aperture: int, resuming: bool) -> None:
            label = job.pen_labels.get(aperture) or \
                f"pen for aperture {describe_aperture(self.planned.program, aperture)}"
            if on_pen_change is not None:
                on_pen_change(PenChange(aperture, label + (GOES_ON_WITH if resuming else ""),
                                        lines[first].command))

        journal = self.journal
        on_reply = journal_replies(journal) if journal is not None else None
        return run_journalled(
            self, lambda: stream_job(self.link, lines, job.pen_changes, self.where,
                                     progress.show, ask_pen, start=self.start,
                                     lead=self.lead, on_reply=on_reply, on_status=progress.seen),
            progress)

    def explain(self, stopped: GrblStreamError) -> GrblStreamError:
        """The error a refusal or an alarm is raised as (a mill job names a probe's)."""
        return stopped

    def _stop_and_lift(self) -> None:
        """Decelerate, drop GRBL's queue (its position kept), then lift the pen."""
        self.stopped_at_rest = hold_and_reset(self.link) is not None
        try:
            lift_pen(self.link, self.scale, self.pen)
        except GrblError as problem:
            self.lift_failed = f"the pen could not be lifted: {problem}"

    def _disarm(self) -> None:
        if self.port is not None:
            self.port.disarm()


def go_on_in(journal: Journal, entry: JournalEntry, start: int) -> None:
    """The interrupted `entry` going on in `journal` as a new session from line `start`."""
    entry.state, entry.reason = RUNNING, ""
    entry.first_index, entry.confirmed = start, start - 1
    journal.begin(entry)


class JobProgress:
    """A streamed job's progress: lines done (`show`, as GRBL confirms them) and where
    the head is (`seen`, from the `?` reports: GRBL answers a few times a second, so the
    ETA counts down and the position follows the head through a long move whose line
    GRBL confirmed long before it ends), each passed on as a Progress."""

    def __init__(self, total: int, done: int, estimate_s: float, on_progress,
                 file_line: Callable[[int], int]):
        self.total, self.done, self.estimate_s = total, done, estimate_s
        self.on_progress = on_progress
        self.file_line = file_line          # a line's index -> its line in the file
        self.began = time.monotonic()
        self.position: tuple[int, int, int] | None = None

    def show(self, count: int) -> None:
        self.done = count
        self._report()

    def seen(self, status) -> None:
        self.position = status.wpos_nm
        self._report()

    def _report(self) -> None:
        if self.on_progress is not None:
            elapsed = time.monotonic() - self.began
            line = self.file_line(self.done - 1) if self.done else 0
            self.on_progress(Progress(self.done, self.total, elapsed,
                                      max(0.0, self.estimate_s - elapsed), line,
                                      self.position))


def run_journalled(job, body, progress: JobProgress) -> StreamResult:
    """`body()` streams `job` (a GrblJob or a grbl.mill_job.GrblMillJob); its journal
    ended with how it went: a stop (JobInterrupted, or StreamAborted from a pen change
    or a pause) and Ctrl-C hold and reset GRBL, lift the tool and return; a refusal or
    an alarm is raised as `job.explain` says; a lost port raises GrblPortLost.
    `progress`: the lines done so far, and when it began."""
    journal = job.journal
    total, began = progress.total, progress.began
    end = journal.end if journal is not None else (lambda *args: None)
    if job.port is not None:
        job.port.arm()
    try:
        body()
    except (JobInterrupted, StreamAborted, KeyboardInterrupt) as stop:
        job._disarm()
        job._stop_and_lift()
        reason = "stopped with Ctrl-C" if isinstance(stop, KeyboardInterrupt) else STOPPED
        end(ABORTED, reason)
        return StreamResult(False, progress.done, total, time.monotonic() - began, reason)
    except GrblStreamError as stopped:
        stopped = job.explain(stopped)
        end(FAILED, str(stopped))
        raise stopped from None
    except (serial.SerialException, OSError) as lost:
        end(INTERRUPTED, port_error_text(lost))
        acknowledged = journal.entry.confirmed + 1 if journal is not None else progress.done
        name = f"{job.port_name}: " if job.port_name else ""
        raise GrblPortLost(f"{name}{port_error_text(lost)}", acknowledged, total) from None
    except GrblError as problem:
        end(FAILED, str(problem))
        raise
    finally:
        job._disarm()
    end(FINISHED)
    return StreamResult(True, total, total, time.monotonic() - began)


def resume_from(link, entry: JournalEntry, lines: list[GcodeLine]) -> tuple[int, str]:
    """(the line to go on from, why there) for the interrupted `entry` whose job
    replanned to `lines`; GrblResumeError when they are not the same job."""
    check_same_job(entry, lines)
    return resume_start(lines, entry.confirmed, entry.first_index,
                        link.build.planner_blocks, cut_short(link, entry))
