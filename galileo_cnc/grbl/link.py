"""A connection to a stock GRBL 1.1 board: banner, $I and $$, status, commands.

Single-threaded on purpose: every read happens in the caller's loop, so the
order of `ok`s, errors and pushed reports is the order GRBL sent them. The
port is anything pyserial-like (a real port, the simavr pseudo-terminal).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from galileo_cnc.grbl.reports import (
    SUPPORTED_MAJOR_MINOR, BuildInfo, GrblError, GrblSettings, Status, StatusTracker,
    alarm_text, banner_version, error_text, parse_build_info, parse_settings, parse_status,
)

BAUD = 115200
# Real-time bytes (commands.md): picked off by GRBL's RX interrupt, never buffered.
STATUS_QUERY = b"?"
FEED_HOLD = b"!"
CYCLE_START = b"~"
SOFT_RESET = b"\x18"
#: silence after our own soft reset before it is sent again (a byte lost on the line):
#: GRBL answers in milliseconds, a loaded host may read it a second or more later
RESET_AGAIN_S = 3.0
JOG_CANCEL = b"\x85"
#: How long GRBL may stay silent while it is still expected to answer (simulated
#: boards run faster than the wall clock, real ones answer within ms).
REPLY_TIMEOUT_S = 30.0
READ_SLICE_S = 0.2
#: Hard (1) and soft (2) limit alarms: GRBL blocks until a reset, after this line.
CRITICAL_ALARMS = (1, 2)
RESET_TO_CONTINUE = "[MSG:Reset to continue]"
#: How long a reset waits for that line (it follows the ALARM line at once).
CRITICAL_MESSAGE_WAIT_S = 3.0


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

    def __init__(self, port, *, reply_timeout_s: float = REPLY_TIMEOUT_S):
        self.port = port
        self.reply_timeout_s = reply_timeout_s
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
        re-opened simulated board) is asked with a soft reset after a second of
        silence. After a reset of ours (`reset_sent`) a slow answer is not a silent
        board: the reset is sent again only after RESET_AGAIN_S (a byte lost on the
        line), and the board is not asked what it stands in."""
        deadline = time.monotonic() + timeout_s
        patience = RESET_AGAIN_S if reset_sent else 1.0
        quiet_since = time.monotonic()
        asked = False
        while time.monotonic() < deadline:
            line = self.read_line(min(1.0, max(0.05, deadline - time.monotonic())))
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
        pushed = []
        while True:
            line = self.read_line()
            if line is None:
                raise GrblError(f"GRBL gave no ok/error within {self.reply_timeout_s:g} s")
            reply = self.classify(line)
            if isinstance(reply, Reply):
                return Reply(reply.ok, reply.code, tuple(pushed))
            if reply is not None:
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
            line = self.read_line(deadline - time.monotonic())
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

    def wait_idle(self) -> Status:
        """Returns once every queued move has run: `G4 P0` is answered only after
        GRBL's buffer has drained (protocol_buffer_synchronize). Polling `?` for
        Idle is not enough: between one block's end and the auto cycle start of a
        block just queued, GRBL reports Idle with motion still to come."""
        self.write_line("G4 P0")
        # the ok may be a long move away: ask `?` while silent, and give up only
        # when GRBL neither answers nor moves for reply_timeout_s
        deadline = time.monotonic() + self.reply_timeout_s
        last = self.tracker.last.mpos_nm if self.tracker.last else None
        while True:
            line = self.read_line(min(1.0, self.reply_timeout_s))
            if line is None:
                if time.monotonic() > deadline:
                    raise GrblError(f"GRBL neither moved nor answered for "
                                    f"{self.reply_timeout_s:g} s")
                self.realtime(STATUS_QUERY)
                continue
            reply = self.classify(line)
            if isinstance(reply, Reply):
                if not reply.ok:
                    raise GrblError(f"GRBL refused 'G4 P0': {reply.text}", reply.code)
                break
            if line.startswith("<") and self.tracker.last.mpos_nm != last:
                last = self.tracker.last.mpos_nm
                deadline = time.monotonic() + self.reply_timeout_s
        status = self.status()
        if status.state == "Alarm":
            raise GrblError("GRBL is in alarm state", alarm=True)
        if status.state != "Idle":
            raise GrblError(f"GRBL is {status.state} after its buffer drained")
        return status

    def soft_reset(self, timeout_s: float = 10.0) -> str:
        """0x18: GRBL stops at once, forgets its queue, prints its banner again.
        A reset while moving ends in ALARM:3 (position lost): unlocking with
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
