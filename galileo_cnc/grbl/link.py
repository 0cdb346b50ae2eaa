"""A connection to a stock GRBL 1.1 board: banner, $I and $$, status, commands.

Single-threaded on purpose: every read happens in the caller's loop, so the
order of `ok`s, errors and pushed reports is the order GRBL sent them. The
port is anything pyserial-like (a real port, the simavr pseudo-terminal).
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable
from dataclasses import dataclass

from galileo_cnc.grbl.reports import (
    SUPPORTED_MAJOR_MINOR, BuildInfo, GrblError, GrblSettings, Status, StatusTracker,
    alarm_text, banner_version, error_text, parse_build_info, parse_settings, parse_status,
)
from galileo_cnc.program.ops import NM_PER_MM

BAUD = 115200
# Real-time bytes (commands.md): picked off by GRBL's RX interrupt, never buffered.
STATUS_QUERY = b"?"
FEED_HOLD = b"!"
CYCLE_START = b"~"
SOFT_RESET = b"\x18"
#: silence after our own soft reset before it is sent again (a byte lost on the line):
#: GRBL prints its banner in milliseconds, a loaded host may read it a second or more later
RESET_AGAIN_S = 3.0
#: silence after opening before the board is taken as one that did not reset on
#: opening (no auto-reset, a re-opened simulated board) and asked: `?`, then a soft
#: reset. A board that did reset prints its banner once its boot loader is done.
QUIET_BEFORE_ASKING_S = 1.0
JOG_CANCEL = b"\x85"
#: A command's answer: how long GRBL may stay silent after a line sent while its
#: planner has room (answered in ms; `$H`'s only once homed, and GRBL answers no `?`
#: while homing). A line behind a full planner is answered only when the moves
#: ahead of it have run, which may take minutes: jobs (stream) and wait_idle judge
#: the board by its status answers instead (StatusWatch), and give up on silence of
#: the lines only when GRBL stands Idle, not moving, for this long (a byte lost).
REPLY_TIMEOUT_S = 30.0
READ_SLICE_S = 0.2
#: How often `?` is asked while a job streams: GRBL's interface.md asks for at most
#: 5 Hz; UGS polls every 200 ms, cncjs every 250 ms. The byte never enters the RX ring.
STATUS_EVERY_S = 0.2
#: No status report for this long means the board stopped answering. GRBL answers
#: `?` within 5-20 ms (interface.md) from its main loop, also while a full planner
#: holds back a line's `ok`, in a feed hold and in a dwell; 3 s is 15 unanswered
#: queries, room for a loaded host to read late, and the stop is reported within
#: 3.2 s (one more read slice), inside the 5 s a user waits for.
STATUS_SILENCE_S = 3.0
#: A `?` unanswered for this long is asked again: one sent while GRBL resets (it does
#: after a failed homing, ALARM:9) is lost, and a report comes within 20 ms otherwise.
ASK_AGAIN_S = 1.0
#: Hard (1) and soft (2) limit alarms: GRBL blocks until a reset, after this line.
CRITICAL_ALARMS = (1, 2)
RESET_TO_CONTINUE = "[MSG:Reset to continue]"
#: How long a reset waits for that line (it follows the ALARM line at once).
CRITICAL_MESSAGE_WAIT_S = 3.0
#: Standing Idle this long with a line unanswered: a cycle start (StatusWatch).
IDLE_NUDGE_S = 0.4


@dataclass(frozen=True, slots=True)
class Reply:
    """What ended one command: `ok`, or `error:N` with GRBL's text."""

    ok: bool
    code: int | None = None
    lines: tuple[str, ...] = ()     # push lines that came before it ([VER:], $N=...)

    @property
    def text(self) -> str:
        return "ok" if self.ok else error_text(self.code)


class GrblLink:
    """Open with `GrblLink.connect(port)`: waits for the banner (opening resets the
    board), reads `$I` and `$$`."""

    def __init__(self, port, *, reply_timeout_s: float = REPLY_TIMEOUT_S,
                 status_silence_s: float = STATUS_SILENCE_S):
        self.port = port
        self.reply_timeout_s = reply_timeout_s
        self.status_silence_s = status_silence_s
        self.version: str | None = None
        self.build: BuildInfo | None = None
        self.settings: GrblSettings | None = None
        self.tracker = StatusTracker()
        self.alarms: list[int] = []        # ALARM:N seen, in order
        self.messages: list[str] = []      # [MSG:...] and other push lines
        self.boot_lines: list[str] = []    # what came before the banner
        self.critical_alarm = False        # ALARM:1/2 seen, its reset message not yet
        #: the state a board that did not reset on opening stood in before our soft
        #: reset (Hold: its queue had not run out), None when it reset itself
        self.state_before_reset: str | None = None
        self._partial = b""

    # ---- lines ----------------------------------------------------------------
    def read_line(self, timeout_s: float | None = None) -> str | None:
        """One line without its CR LF, or None if none came within the timeout."""
        deadline = time.monotonic() + (self.reply_timeout_s if timeout_s is None else timeout_s)
        while True:
            self.port.timeout = max(0.0, min(READ_SLICE_S, deadline - time.monotonic()))
            chunk = self.port.readline()
            self._partial += chunk
            if self._partial.endswith(b"\n"):
                line, self._partial = self._partial, b""
                return line.decode("ascii", errors="replace").strip()
            if time.monotonic() >= deadline:
                return None

    def write_line(self, text: str) -> int:
        data = (text + "\n").encode("ascii")
        self.port.write(data)
        return len(data)

    def realtime(self, byte: bytes) -> None:
        self.port.write(byte)

    # ---- connecting -------------------------------------------------------------
    @classmethod
    def connect(cls, port, *, banner_timeout_s: float = 10.0, **kwargs) -> "GrblLink":
        link = cls(port, **kwargs)
        link.wait_banner(banner_timeout_s)
        link.read_info()
        return link

    def wait_banner(self, timeout_s: float = 10.0, reset_sent: bool = False) -> str:
        """Reads up to GRBL's banner; a board that does not reset on open (a
        re-opened simulated board) is asked with a soft reset after
        QUIET_BEFORE_ASKING_S of silence. After a reset of ours (`reset_sent`) a slow
        answer is not a silent board: the reset is sent again only after RESET_AGAIN_S
        (a byte lost on the line), and the board is not asked what it stands in."""
        deadline = time.monotonic() + timeout_s
        patience = RESET_AGAIN_S if reset_sent else QUIET_BEFORE_ASKING_S
        quiet_since = time.monotonic()
        asked = False
        while time.monotonic() < deadline:
            line = self.read_line(min(1.0, patience, max(0.05, deadline - time.monotonic())))
            if line is None:
                if not asked and time.monotonic() - quiet_since >= patience:
                    if not reset_sent:
                        self.state_before_reset = self._state_before_reset()
                    self.realtime(SOFT_RESET)
                    asked = True
                continue
            quiet_since = time.monotonic()
            version = banner_version(line)
            if version is None:
                self._boot_line(line)
                continue
            if not version.startswith(SUPPORTED_MAJOR_MINOR):
                raise GrblError(f"GRBL {version} found; only GRBL {SUPPORTED_MAJOR_MINOR} "
                                f"is supported (its replies differ)")
            self.version = version
            self.tracker = StatusTracker()
            return version
        raise GrblError(f"no GRBL banner within {timeout_s:g} s "
                        f"(got {self.boot_lines[-3:]!r})")

    def _state_before_reset(self) -> str | None:
        """A silent board did not reset on opening: what it stands in (`?`), before
        our reset makes it forget (a reset in a finished feed hold drops the queue
        without ALARM:3). None when it does not answer."""
        self.realtime(STATUS_QUERY)
        line = self.read_line(0.5)
        while line is not None and not line.startswith("<"):
            self._boot_line(line)
            line = self.read_line(0.5)
        try:
            return parse_status(line).state if line is not None else None
        except GrblError:
            return None

    def _boot_line(self, line: str) -> None:
        """A line before the banner: kept, and an alarm counted (a reset while
        moving: ALARM:3)."""
        self.boot_lines.append(line)
        if line.startswith("ALARM:"):
            self.alarms.append(int(line[6:]))

    def read_info(self) -> None:
        self.build = parse_build_info(list(self.command_checked("$I").lines))
        self.settings = parse_settings(list(self.command_checked("$$").lines))

    @property
    def rx_buffer_bytes(self) -> int:
        """GRBL's RX ring size ($I's OPT); the ring holds one byte less."""
        return self.build.rx_buffer_bytes if self.build and self.build.rx_buffer_bytes \
            else 128

    # ---- send-response ----------------------------------------------------------
    def command(self, text: str) -> Reply:
        """One line, then its `ok` or `error:N` (push lines in between are kept)."""
        self.write_line(text)
        return self.wait_reply()

    def command_checked(self, text: str) -> Reply:
        reply = self.command(text)
        if not reply.ok:
            raise GrblError(f"GRBL refused {text!r}: {reply.text}", reply.code)
        return reply

    def wait_reply(self) -> Reply:
        """The answer to a line sent while GRBL's planner has room (or `$H`): silence
        for reply_timeout_s is an error. Lines that may wait behind moves go through
        stream() or wait_idle(), which judge the board by its status answers."""
        pushed = []
        while True:
            line = self.read_line()
            if line is None:
                raise GrblError(f"GRBL gave no ok/error within {self.reply_timeout_s:g} s")
            reply = self.classify(line)
            if isinstance(reply, Reply):
                return Reply(reply.ok, reply.code, tuple(pushed))
            if reply is not None and not line.startswith("<"):   # a late `?` answer
                pushed.append(line)

    def classify(self, line: str):
        """A Reply for ok/error:N; for push lines, record them and return the
        line (None for an empty one). Raises on ALARM:N."""
        if line == "ok":
            return Reply(True)
        if line.startswith("error:"):
            return Reply(False, int(line[6:]))
        if not line:
            return None
        if line.startswith("ALARM:"):
            code = int(line[6:])
            self.alarms.append(code)
            self.critical_alarm = code in CRITICAL_ALARMS
            raise GrblError(alarm_text(code), code, alarm=True)
        if line.startswith("<"):
            self.tracker.update(parse_status(line))
        elif banner_version(line):
            self.version = banner_version(line)
            self.messages.append(line)
        elif line.startswith("[MSG:") or line.startswith(">"):
            self.messages.append(line)
            if line == RESET_TO_CONTINUE:
                self.critical_alarm = False
        return line

    def status(self, timeout_s: float = 5.0) -> Status:
        """Sends `?` and returns the next report (with WCO carried over). A report
        that does not parse (a byte lost or flipped on the cable) is asked for once
        more before it counts as an error."""
        self.realtime(STATUS_QUERY)
        deadline = time.monotonic() + timeout_s
        garbled = False
        while time.monotonic() < deadline:
            line = self.read_line(min(ASK_AGAIN_S, deadline - time.monotonic()))
            if line is None:                # GRBL resetting (after ALARM:9) drops a `?`
                self.realtime(STATUS_QUERY)
                continue
            if line is not None and line.startswith("<"):
                try:
                    return self.tracker.update(parse_status(line))
                except GrblError:
                    if garbled:
                        raise
                    garbled = True
                    self.realtime(STATUS_QUERY)
                    continue
            if line is not None:
                self.classify(line)
        raise GrblError(f"no status report within {timeout_s:g} s")

    def wait_idle(self, on_status: Callable[[Status], None] | None = None) -> Status:
        """Returns once every queued move has run: `G4 P0` is answered only after
        GRBL's buffer has drained (protocol_buffer_synchronize). Polling `?` for
        Idle is not enough: between one block's end and the auto cycle start of a
        block just queued, GRBL reports Idle with motion still to come. The `ok` may
        be a long move away: meanwhile `?` is asked (StatusWatch, each report handed
        to `on_status`), and the wait gives up only when GRBL stops answering those
        or stands Idle without answering.

        A board that still reports Run once an `ok` came (seen once in CI, GRBL 1.1h in
        simavr under load) is watched on until it stands Idle. GRBL's source answers
        `G4 P0` only once its buffer has drained, so that `ok` was likely a line's
        before it, read late; the `G4 P0`'s own, read on the way, pairs replies with
        lines again. An `error:N` on the way is the last line's refusal, raised once
        GRBL stands and every reply before is read; Run without moving for
        reply_timeout_s is a stall."""
        self.write_line("G4 P0")
        watch = StatusWatch(self, on_status=on_status)
        while True:
            line = _drain_line(watch)
            if line is None:
                continue
            reply = watch.classify(line)
            if isinstance(reply, Reply):
                if not reply.ok:
                    raise GrblError(f"GRBL refused 'G4 P0': {reply.text}", reply.code)
                break
        # the first report after the ok (asked at once), and on while GRBL reports Run;
        # a refusal read on the way is raised once GRBL stands, every reply read
        watch.ask_now()
        status: Status | None = None
        refused: Reply | None = None
        moved_at = time.monotonic()
        while status is None or status.state == "Run":
            if time.monotonic() - moved_at >= self.reply_timeout_s:
                raise GrblError(f"GRBL reports Run but has not moved for "
                                f"{time.monotonic() - moved_at:.0f} s, at {position_mm(status)}")
            line = _drain_line(watch)
            if line is None:
                continue
            reported = watch.classify(line)
            if isinstance(reported, Reply):
                refused = refused or (None if reported.ok else reported)
            elif line.startswith("<") and reported is not None:
                if status is None or watch.last.mpos_nm != status.mpos_nm:
                    moved_at = time.monotonic()
                status = watch.last
        if refused is not None:
            raise GrblError(f"GRBL refused a line: {refused.text}", refused.code)
        if status.state == "Alarm":
            raise GrblError("GRBL is in alarm state", alarm=True)
        if status.state != "Idle":
            raise GrblError(f"GRBL is {status.state} after its buffer drained")
        return status

    def soft_reset(self, timeout_s: float = 10.0) -> str:
        """0x18: GRBL stops at once, forgets its queue, prints its banner again.
        A reset while moving ends in ALARM:3 (position lost; GRBL 1.1h loses that
        alarm now and then, docs/grbl.md): unlocking with
        `$X` is the caller's choice, after asking the user.

        After a hard or soft limit alarm GRBL prints `[MSG:Reset to continue]` and
        only then starts listening for the reset, forgetting one that came before
        (protocol.c clears EXEC_RESET there): so the reset waits for that line."""
        if self.critical_alarm:
            deadline = time.monotonic() + CRITICAL_MESSAGE_WAIT_S
            while self.critical_alarm and time.monotonic() < deadline:
                line = self.read_line(max(0.05, deadline - time.monotonic()))
                if line is not None and not line.startswith("ALARM:"):
                    self.classify(line)
            self.critical_alarm = False
        self.realtime(SOFT_RESET)
        self._partial = b""
        return self.wait_banner(timeout_s, reset_sent=True)


_DWELL = re.compile(r"\bG0*4(?!\d)", re.IGNORECASE)


def is_dwell(text: str) -> bool:
    """A `G4` line: GRBL stands Idle, not moving, while it dwells, which is no stall."""
    return _DWELL.search(text) is not None


def position_mm(status: Status | None) -> str:
    """`X 5.000 Y 4.000 Z 1.875 mm (work)`, or that none was reported."""
    if status is None or status.wpos_nm is None:
        return "no position reported"
    x, y, z = (f"{nm / NM_PER_MM:.3f}" for nm in status.wpos_nm[:3])
    return f"X {x} Y {y} Z {z} mm (work)"


def _drain_line(watch: "StatusWatch") -> str | None:
    """The watch's next line while the host waits for the last moves; a board gone
    silent or stalled is an error."""
    line = watch.read_line()
    if line is None:
        fault = watch.fault()
        if fault is not None:
            raise GrblError(f"{fault} (waiting for the last moves to run)")
    return line


class StatusWatch:
    """Liveness while the host waits for GRBL's replies: asks `?` every `every_s`
    and judges the board by its status answers, not by how long a line's `ok`
    takes (a line behind a full planner is answered only when the moves ahead of it
    have run). The board is alive while reports come; `fault()` names a board that
    answered no `?` for the link's status_silence_s (at least three queries), or one
    that stood Idle, not moving, with a line unanswered for reply_timeout_s, unless
    that line is a dwell (a byte lost on the line: GRBL waits for the rest).
    Each report goes to `on_status` (with WCO carried over: the link's tracker).

    GRBL 1.1h can stall Idle with moves still planned: very short blocks at a high
    feed (a mill's 0.01 mm chords at 50 mm/s, seen in simavr) drain its segment buffer
    faster than it refills it, the stepper's cycle stops, and a line that waits for the
    buffer (M5, G4) waits in a loop that never restarts it. A cycle start (`~`) does;
    while Idle, it only starts moves already planned, so the watch sends one after
    IDLE_NUDGE_S of standing Idle with a line unanswered (`nudges` counts them)."""

    def __init__(self, link: GrblLink, every_s: float = STATUS_EVERY_S,
                 on_status: Callable[[Status], None] | None = None):
        self.link = link
        self.every_s = every_s
        self.silence_s = max(link.status_silence_s, 3 * every_s)
        self.on_status = on_status
        now = time.monotonic()
        self.answered_at = now          # the last status report (or the start)
        self.progress_at = now          # the last reply, or a report of motion or a hold
        self.asked_at: float | None = None
        self.queries = 0
        self.reports = 0
        self.last: Status | None = link.tracker.last
        self.nudged_at = now
        self.nudges = 0

    def ask_now(self) -> None:
        """The next read_line asks `?` at once, not when the last one is due again."""
        self.asked_at = None

    def read_line(self) -> str | None:
        """Asks `?` when one is due, then one line or None by the next one."""
        now = time.monotonic()
        if self.asked_at is None or now - self.asked_at >= self.every_s:
            self.link.realtime(STATUS_QUERY)
            self.asked_at, now = now, time.monotonic()
            self.queries += 1
        return self.link.read_line(max(0.01, self.asked_at + self.every_s - now))

    def classify(self, line: str):
        """link.classify; a status report counts as an answer. A garbled report (a
        byte flipped on the cable) is neither an answer nor an error: None."""
        if not line.startswith("<"):
            reply = self.link.classify(line)
            if isinstance(reply, Reply):
                self.progress_at = time.monotonic()
            return reply
        try:
            status = self.link.tracker.update(parse_status(line))
        except GrblError:
            return None
        now = time.monotonic()
        if status.state != "Idle" or self.last is None or status.mpos_nm != self.last.mpos_nm:
            self.progress_at = now
        self.answered_at, self.last = now, status
        self.reports += 1
        if self.on_status is not None:
            self.on_status(status)
        return line

    def silent_s(self) -> float:
        """Seconds since the last status report (or since the watch began)."""
        return time.monotonic() - self.answered_at

    def fault(self, waiting_for: str = "") -> str | None:
        """Why the board counts as gone, in a user's words, else None."""
        silent = self.silent_s()
        if silent >= self.silence_s:
            return (f"GRBL gave no answer to status queries for {silent:.1f} s (asked "
                    f"every {self.every_s:g} s; last reported at {position_mm(self.last)})")
        now = time.monotonic()
        stood = now - self.progress_at
        if stood >= IDLE_NUDGE_S and now - self.nudged_at >= IDLE_NUDGE_S and \
                self.last is not None and self.last.state == "Idle" and \
                not is_dwell(waiting_for):
            self.link.realtime(CYCLE_START)
            self.nudged_at = now
            self.nudges += 1
        if stood >= self.link.reply_timeout_s and not is_dwell(waiting_for):
            return (f"GRBL stood Idle for {stood:.0f} s without answering a line sent to "
                    f"it (a byte lost on the line?), at {position_mm(self.last)}")
        return None
