"""Streaming a planned job to the machine (docs/protocol.md, Host rules; docs/streaming.md).

- Character counting: the bytes of lines sent and not yet answered stay within
  the receive buffer the banner advertises, so the firmware's queue never runs
  dry for want of a line and its receive ring never overflows.
- Every line that arrives gets exactly one reply, in order; a reply frees the
  bytes of the oldest transmission. `ok N<s>` confirms line s and every line
  sent before it (the firmware accepts lines only in order, so a lost `ok` is
  confirmed by the next). `rs N<e>` resends every unconfirmed line from e on;
  the `rs N<e>` that lines already in flight draw are ignored until e is
  answered. `error` stops the job, naming the file line behind the command.
- A stall (no reply while the machine stands idle with an empty queue, e.g. a
  line or its reply lost to noise) is settled by the machine's status: lines up to its `N` were
  accepted, the rest are sent again.
- Replies carry no checksum, so a confirmation is provisional until the status's `N`
  agrees: before each pen change and at the end the machine stands still and its `N`
  must be the last line sent; lines after it (a garbled `ok` confirmed them) are sent
  again. Every line since the last agreement is kept for that (the window).
- A refused line is not counted by the machine (protocol 3): the lines behind it draw
  `rs` and never run, and its `error:` comes again when it is resent, so a lost
  refusal still stops the job.
- The machine in hold or abort without our asking (noise), or reset (its banner, or an
  `N` outside the window): the job stops with a message; after a hold or abort it can
  be resumed (journal `aborted`: the machine ramped down inside a command); after a
  reset (journal `reset`: the position is lost) only when the job's frame is the homed
  one (`plot --home`), by homing again.
- Pen changes: before the command where the planner put one, the streamer
  waits until the machine stands still (pen up), then asks (`on_pen_change`).
- Abort (`abort()`, `q` in the console, Ctrl-C): the machine ramps down and
  drops its queue; once it stands still the pen is lifted (a pen left on the paper
  blots), and the journal keeps where it stood before the lift (`stopped_at`), so a
  resume lowers the pen there again.
- The journal records every confirmation and where the job began, so a job whose
  port died or that was stopped resumes where the machine left it (stream/resume.py
  finds the command and the lead-in that goes back to it).
- At the end the machine stands still and gets `U`, so the job's EndJob leaves it
  ready for the next job, a jog or a home.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Sequence

from galileo_cnc import protocol as P
from galileo_cnc.errors import GalileoError, SourcePos
from galileo_cnc.job import NO_OP, Command, Job, PenUp
from galileo_cnc.machine.planner import exit_indices
from galileo_cnc.machine.timing import JobTiming, job_timing
from galileo_cnc.program.ops import COL, LINE, NM_PER_MM, Program
from galileo_cnc.stream.journal import (ABORTED, FAILED, FINISHED, INTERRUPTED, RESET,
                                        Journal, JournalEntry, file_digest)
from galileo_cnc.transport.link import (LinkError, MachineLink, MachineStopped, PortGone,
                                        previous_seq)

#: No reply for this long while the machine stands idle with an empty queue: a stall.
STALL_S = 2.0
#: A machine of unknown pace (simavr://?realtime=0) is timed once this much machine
#: time is confirmed; before, the few commands queued ahead would skew the rate.
MEASURE_PACE_AFTER_S = 2.0


_LOCKED = P.ERROR_BY_NAME["LOCKED"].code


class StreamAborted(GalileoError):
    """The user stopped the job (raise it from `on_pen_change` to stop there)."""


class MachineReset(LinkError):
    """The machine's line count no longer matches the job's: it was reset mid-job.
    `resumable`: the job's frame was the homed one, so a resume homes and goes on."""

    resumable = False


def after_reset_text(homed: bool) -> str:
    """What a reset mid-job leaves the user to do."""
    if homed:
        return ("the job's frame is the homed one: `galileo-cnc plot --resume` (or "
                "`resume` in the console) homes the machine and continues")
    return ("its position is lost, so the job cannot continue and must be started "
            "again; `galileo-cnc plot --home` homes the machine before a job, which "
            "makes a reset resumable next time")


@dataclass
class Progress:
    confirmed: int          # commands the machine has confirmed
    total: int
    elapsed_s: float
    eta_s: float | None     # time left: the reference's machine time (at sim:// speed)
    source_line: int        # line of the file the last confirmed command came from
    #: where the machine reports the head (work coordinates, nm), for machines that
    #: report it while they stream (GRBL's status answers); None elsewhere
    position_nm: tuple[int, int, int] | None = None


def head_position_text(position_nm: tuple[int, int, int] | None) -> str:
    """`  at X 12.300 Y 4.000 mm`: a Progress's head position for a progress line; ""
    when the machine reported none."""
    if position_nm is None:
        return ""
    x, y = (position_nm[axis] / NM_PER_MM for axis in (0, 1))
    return f"  at X {x:.3f} Y {y:.3f} mm"


@dataclass
class PenChange:
    aperture: int           # the pen key (a Gerber aperture, or an ink pen)
    description: str        # "the 0.3 mm pen", "pen for aperture D11 (0.254 mm round)"
    command_index: int

    @property
    def prompt(self) -> str:
        return f"insert {self.description}"


@dataclass
class StreamResult:
    completed: bool
    confirmed: int          # commands confirmed, from the job's start
    total: int
    elapsed_s: float
    reason: str = ""
    held: str = ""          # stopped: what the stop left the machine in


@dataclass
class _Transmission:
    index: int              # command index in the job (start - 1 for a lead-in command)
    seq: int
    line: bytes
    command: object         # what the line carries, for messages


def describe_aperture(program: Program | None, aperture: int) -> str:
    ap = program.apertures.get(aperture) if program is not None else None
    return f"D{aperture} ({ap.describe()})" if ap is not None else f"D{aperture}"


class JobStreamer:
    """Sends `job` over `link` from command `start` (0 for a new job)."""

    def __init__(self, link: MachineLink, job: Job, program: Program | None = None, *,
                 journal: Journal | None = None, start: int = 0,
                 timing: JobTiming | None = None, lead_in: Sequence[Command] = (),
                 job_start: tuple[int, int, int] | None = None, homed: bool = False):
        self.link = link
        self.job = job
        self.program = program
        self.journal = journal
        self.start = start
        #: sent before command `start`, after the pen in force is asked for: what brings
        #: a machine stopped inside a command back to where that command begins
        self.lead_in = tuple(lead_in)
        #: where the job's first command started (a resumed job's, from its journal)
        self.job_start = job_start
        #: the job's frame is the homed one (journalled: a reset is then resumable)
        self.homed = homed
        self.timing = timing or job_timing(job.commands, link.config)
        #: per command, the exit index its move ends at (junction speeds, docs/motion.md
        #: §5.7): the wire carries it, the firmware ramps to it
        self._exits = exit_indices(job.commands, link.config)
        self._abort = threading.Event()
        self._rx_bytes = link.banner.rx_buffer_bytes if link.banner else P.RX_BUFFER_BYTES
        self.stall_s = STALL_S          # a bench against an instant machine shortens it

    def abort(self) -> None:
        """Stop the job from any thread; `run` ramps the machine down and returns."""
        self._abort.set()

    # ---- the loop ------------------------------------------------------------------------
    def run(self, *, on_progress: Callable[[Progress], None] | None = None,
            on_pen_change: Callable[[PenChange], None] | None = None) -> StreamResult:
        self.link.check_config()        # a board built for another machine gets no job
        total = len(self.job)
        began = time.monotonic()
        self.confirmed = self.start - 1                 # last confirmed command index
        self._next = self.start                         # next command to send
        self._wire: deque[_Transmission] = deque()      # sent, awaiting one reply each
        self._unconfirmed: dict[int, _Transmission] = {}  # by seq, in the order first sent
        # every line since the machine's `N` last agreed (`_base_seq`), confirmed or not
        self._window: dict[int, _Transmission] = {}
        self._base_seq = self.link.seq
        self._base_confirmed = self.start - 1
        self._resets = self.link.resets
        self._resend: deque[_Transmission] = deque()
        self._resend_from: int | None = None            # `rs N<e>` being answered
        self._changes = self._pen_changes_from(self.start)
        self._lead_in = deque(self.lead_in)
        self._asked: set[int] = set()
        self._on_progress = on_progress
        self._began = began
        self._journal_begin()

        def result(completed: bool, reason: str = "") -> StreamResult:
            return StreamResult(completed, self.confirmed + 1 - self.start, total - self.start,
                                time.monotonic() - began, reason)

        try:
            while True:
                self._stream(total, on_pen_change)
                self._wait_standing()
                if self._agrees_with_machine():
                    break                       # every line accepted: the job is done
            # the job's EndJob locks the planner until `U`: the next job, a jog or a
            # home must find the machine ready, as the user does
            self.link.send_protocol(P.Unlock())
        except (StreamAborted, KeyboardInterrupt) as stop:
            reason = str(stop) or "stopped by the user"
            self._stop_machine()
            lifted = self._lift_pen()
            self._journal_end(ABORTED, reason)
            return replace(result(False, reason), held=f"the machine ramped down; {lifted}")
        except MachineStopped as stopped:
            # a hold or abort we did not send: drop the queue, unlock, resumable
            self._stop_machine()
            self._journal_end(ABORTED, str(stopped))
            raise
        except PortGone as gone:
            self._journal_end(INTERRUPTED, str(gone))
            raise
        except MachineReset as reset:
            self._stop_machine()            # a fresh machine: nothing queued, unlocked
            told = MachineReset(f"{reset}; {after_reset_text(self.homed)}")
            told.resumable = self.homed
            self._journal_end(RESET, str(told))
            raise told from None
        except LinkError as refused:
            self._stop_machine()
            self._journal_end(FAILED, str(refused))
            raise
        self._journal_end(FINISHED)
        return result(True)

    def _stream(self, total: int, on_pen_change) -> None:
        """Send and confirm the job's lines, stopping at each pen change (the machine
        stands still and agrees it accepted every line) to ask for the pen."""
        while self.confirmed < total - 1:
            if self._abort.is_set():
                raise StreamAborted("stopped by the user")
            if self._pen_change_due():
                self._wait_until_confirmed()
                self._wait_standing()
                if not self._agrees_with_machine():
                    continue                    # lines to send again first
                self._asked.add(self._next)
                if on_pen_change is not None:
                    aperture = self._changes[self._next]
                    label = self.job.pen_labels.get(aperture) or \
                        f"pen for aperture {describe_aperture(self.program, aperture)}"
                    on_pen_change(PenChange(aperture, label, self._next))
                continue
            self._fill()
            self._take_reply(self._await_reply())

    def _pen_changes_from(self, start: int) -> dict[int, int]:
        """The job's pen changes; a resumed job first asks for the pen in force where
        it continues (it may have been taken out while the job was stopped)."""
        changes = dict(self.job.pen_changes)
        before = [k for k in changes if k <= start]
        if start > 0 and before:
            changes[start] = changes[max(before)]
        return changes

    def _pen_change_due(self) -> bool:
        return (not self._resend and self._next in self._changes
                and self._next not in self._asked)

    def _fill(self) -> None:
        """Send resends first, then new lines, while they fit the receive buffer."""
        in_flight = sum(len(t.line) for t in self._wire)
        while self._resend and in_flight + len(self._resend[0].line) <= self._rx_bytes:
            sent = self._resend.popleft()
            self.link.write(sent.line)
            self._wire.append(sent)
            in_flight += len(sent.line)
        while (not self._resend and self._next < len(self.job)
               and not self._pen_change_due()):
            leading = bool(self._lead_in)
            command = self._lead_in[0] if leading else self.job.commands[self._next]
            if not leading and self._exits[self._next] is not None:
                command = replace(command, exit_index=self._exits[self._next])
            seq = self.link.next_seq()
            line = P.encode_command(command, seq)
            if in_flight + len(line) > self._rx_bytes:
                break
            self.link.seq = seq
            self.link.write(line)
            sent = _Transmission(self.start - 1 if leading else self._next, seq, line, command)
            self._wire.append(sent)
            self._unconfirmed[seq] = sent
            self._window[seq] = sent
            in_flight += len(line)
            if leading:
                self._lead_in.popleft()
            else:
                self._next += 1

    def _await_reply(self) -> P.Reply | None:
        """The next reply; on a stall, settle the wire by the machine's status."""
        waited, poll = 0.0, min(0.2, self.stall_s)
        while not self._abort.is_set():
            self._check_reset()
            reply = self.link.next_reply(poll)
            if reply is not None:
                return reply
            waited += poll
            if waited >= self.stall_s and (self._unconfirmed or self._wire):
                status = self.link.status()
                if self.link.standing(status):
                    # an empty queue makes room for any line: this is no flow control
                    self._settle_by_status(status.last_seq)
                    return None
                waited = 0.0
        return None

    def _check_reset(self) -> None:
        if self.link.resets != self._resets:
            raise MachineReset(f"{self.link.port_name}: the machine was reset during the "
                               f"job (its banner arrived)")

    def _settle_by_status(self, last_seq: int) -> bool:
        """Nothing is in flight: lines up to the machine's `N` were accepted, the
        rest (after it in the window) are sent again; no reply is owed any more.
        True when nothing had to be sent again."""
        if last_seq in self._unconfirmed:
            self._confirm_through(last_seq)
        self._wire.clear()
        self._resend_from = None
        seqs = list(self._window)
        if last_seq == self._base_seq:
            after = seqs
        elif last_seq in self._window:
            after = seqs[seqs.index(last_seq) + 1:]
        elif last_seq != 0 and self.link.resets == self._resets:
            # a late answer to an earlier status query, or a garbled number: look again
            self._resend = deque(self._unconfirmed.values())
            return False
        else:
            raise MachineReset(f"{self.link.port_name}: the machine's last line is N{last_seq}, "
                               f"which this job never sent: it was reset")
        self._rewind(after)
        return not after

    def _rewind(self, seqs: list[int]) -> None:
        """Lines `seqs` (the window's tail) were not accepted: unconfirm, send again."""
        if not seqs:
            self._resend = deque()
            return
        keep = list(self._window)[:len(self._window) - len(seqs)]
        self.confirmed = self._window[keep[-1]].index if keep else self._base_confirmed
        self._unconfirmed = {s: self._window[s] for s in seqs}
        self._resend = deque(self._unconfirmed.values())
        if self.journal is not None:
            self.journal.confirm(self.confirmed)

    def _agrees_with_machine(self) -> bool:
        """The machine stands still: does its `N` say it accepted every line sent?
        If so the window starts afresh; if not, the lines after `N` go out again."""
        status = self.link.status()
        if not self._settle_by_status(status.last_seq):
            return False
        self._window.clear()
        self._base_seq = status.last_seq
        self._base_confirmed = self.confirmed
        return True

    def _take_reply(self, reply: P.Reply | None) -> None:
        if reply is None:
            return
        if reply.kind in ("ok", "error") and reply.seq is not None \
                and reply.seq not in self._unconfirmed:
            # not to a line awaiting one: a late or repeated reply, or a garbled number
            self._message(f"ignored a stray reply: {reply.kind} N{reply.seq}")
            return
        if self._wire:
            self._wire.popleft()                # one reply per transmission: frees its bytes
        if reply.kind == "ok":
            if reply.seq == self._resend_from:
                self._resend_from = None
            self._confirm_through(reply.seq)
        elif reply.kind == "rs":
            if reply.seq == self._resend_from:
                return                          # a line that was in flight: already resent
            if reply.seq not in self._window:
                return                          # garbled (a reset shows in the status)
            self._resend_from = reply.seq
            seqs = list(self._window)
            self._rewind(seqs[seqs.index(reply.seq):])
        elif reply.seq is None:
            # a line refused before its number was read: lines run together when a
            # newline is lost (too long), or noise the checksum missed; sent again
            # when the machine asks or stands still
            self._message(f"a line was garbled on the way: error:{reply.code} {reply.text}")
        else:
            sent = self._unconfirmed[reply.seq]
            self.link.seq = previous_seq(reply.seq)     # not counted: expected again
            if reply.code == _LOCKED:
                # the machine stopped in alarm before this line: say why (an abort
                # nobody sent is resumable), not "refused"
                self.link.standing(self.link.status())
            where = self._where(sent.index) if sent.index >= self.start else ""
            raise LinkError(f"{where}{self.link.refusal_text(sent.command, reply)}", reply)

    def _confirm_through(self, seq: int) -> None:
        """The machine accepts lines only in order: `ok N<seq>` confirms every
        unconfirmed line sent before it too (its own reply may have been lost)."""
        while self._unconfirmed:
            first_seq, sent = next(iter(self._unconfirmed.items()))
            del self._unconfirmed[first_seq]
            self._confirm(sent)
            if first_seq == seq:
                return

    def _confirm(self, sent: _Transmission) -> None:
        self.confirmed = max(self.confirmed, sent.index)
        if self.journal is not None:
            self.journal.confirm(self.confirmed)
        if self._on_progress is not None:
            self._on_progress(self.progress())

    def progress(self) -> Progress:
        done = self.confirmed + 1
        ops = [op for op in self.job.op_index[max(self.confirmed - 2, 0):done] if op != NO_OP]
        line = int(self.program.table[ops[-1], LINE]) if self.program is not None and ops else 0
        left = self.timing.remaining_s(done)
        elapsed = time.monotonic() - self._began
        if self.link.speed is None:     # a machine of unknown pace: measure it so far
            ran = self.timing.seconds_between(self.start, done)
            eta = left * elapsed / ran if ran >= MEASURE_PACE_AFTER_S and elapsed > 0 else None
        else:
            eta = left / self.link.speed if self.link.speed > 0 else 0.0
        return Progress(done - self.start, len(self.job) - self.start, elapsed, eta, line)

    def _wait_until_confirmed(self) -> None:
        while self._unconfirmed:
            self._fill()
            self._take_reply(self._await_reply())
            if self._abort.is_set():
                raise StreamAborted("stopped by the user")

    def _wait_standing(self) -> None:
        """Until the machine has run its queue (a stop request still ramps it down)."""
        while True:
            if self._abort.is_set():
                raise StreamAborted("stopped by the user")
            if self.link.standing(self.link.status()):
                return
            time.sleep(min(0.05, self.stall_s))

    def _stop_machine(self) -> None:
        """Ramp down and unlock; replies to lines in flight are collected."""
        try:
            self.link.abort()
        except LinkError as exc:
            self._message(f"could not stop the machine cleanly: {exc}")

    def _lift_pen(self) -> str:
        """The machine stands still after a stop: the pen up, where it stood kept in
        the journal (the resume's lead-in lowers the pen there again). Says which."""
        try:
            here = self.link.status()
            if self.journal is not None and self.journal.entry is not None:
                self.journal.entry.stopped_at = (here.x_steps, here.y_steps, here.z_steps)
            if here.z_steps < self.link.config.pen_up_z_steps:
                self.link.send(PenUp())
                self.link.wait_idle()
            return "the pen lifted"
        except LinkError as exc:
            self._message(f"could not lift the pen after the stop: {exc}")
            return "the pen could not be lifted"

    def _where(self, index: int) -> str:
        op = self.job.op_index[index]
        if self.program is None or op == NO_OP:
            return ""
        row = self.program.table[op]
        return f"{SourcePos(self.program.source, int(row[LINE]), int(row[COL]))}: "

    def _message(self, text: str) -> None:
        if self.link.on_message is not None:
            self.link.on_message(text)

    # ---- journal --------------------------------------------------------------------------
    def _journal_begin(self) -> None:
        if self.journal is None:
            return
        source = str(Path(self.job.source).resolve())
        try:
            digest = file_digest(source)
        except OSError:
            digest = ""
        if self.job_start is None:          # a new job starts where the head stands now
            here = self.link.status()
            self.job_start = (here.x_steps, here.y_steps, here.z_steps)
        first_seq = self.link.next_seq()
        for _ in self.lead_in:              # the lead-in's lines go out first
            first_seq = P.next_seq(first_seq)
        self.journal.begin(JournalEntry(
            source, digest, self.job.offset_nm, self.link.config.to_toml(),
            self.job.grouped, len(self.job), self.start - 1, self.start, first_seq,
            start_position=self.job_start, mode=self.job.mode, ordered=self.job.ordered,
            pens_nm=tuple(self.job.pens_nm), layers=tuple(self.job.layers),
            units=self.job.units, homed=self.homed, scale=str(self.job.scale),
            rotate_deg=self.job.rotate_deg, board=self.job.board))

    def _journal_end(self, state: str, reason: str = "") -> None:
        if self.journal is not None and self.journal.entry is not None:
            self.journal.entry.confirmed = self.confirmed
            self.journal.end(state, reason)
