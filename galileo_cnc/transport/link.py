"""A session with the machine over one pyserial port (docs/protocol.md, Host rules).

`MachineLink.open` opens the port (a board, a pseudo-terminal to the firmware in
simavr, or `sim://`), greets the firmware with `N0 V`, checks its protocol version
and keeps a reader thread that sorts what arrives: line replies (`ok`, `error`,
`rs`) in order for whoever sent the lines, `status:` lines for `status()`, and
`alarm:`/`msg:` lines (and anything undocumented) for `on_message`.

A port that vanishes, or stops answering the real-time status query, raises
`PortGone` within SILENT_S: a motion line may legitimately wait unanswered while
the machine's queue is full, so silence is judged by the status query (RT_STATUS),
never by line replies. Every line from the machine carries a check (protocol 4): a
garbled one is dropped, never believed. Every wait is bounded: the status is asked
again when it does not come or a garbled line came instead, and a line whose reply
is lost is settled by the status's `N` (accepted: done; not accepted and nothing
queued: sent again), never waited for.
"""

from __future__ import annotations

import queue
import threading
import time
from typing import Callable

import serial

from galileo_cnc import job as J
from galileo_cnc import protocol as P
from galileo_cnc.command_text import command_text
from galileo_cnc.config.hardware import BANNER_WAIT_S, DEFAULT_BAUD
from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.errors import GalileoError
from galileo_cnc.job import Command
from galileo_cnc.transport.port import (SIMAVR_URL, is_simulated, open_port, port_error_text,
                                        with_sim_config)

#: Ask for a status when no reply came for this long...
POLL_S = 1.0
#: ...and give the port up when the status did not come within this.
SILENT_S = 3.0
#: The greeting's reply comes after any the machine still owed the last session.
GREETING_S = 10.0
#: The status query is sent again when no status came for this long (lost or garbled).
STATUS_RETRY_S = 0.5
#: A line with no reply for this long is settled by the status (see send_protocol).
REPLY_S = 2.0
#: Sends of one line (each answered `rs` or settled as lost) before the link gives up.
MAX_SENDS = 20
#: Commands whose `ok` carries what the host asked for: resent, not settled by status.
_PAYLOAD = (P.QueryStatus, P.QueryVersion, P.QueryConfig)


class LinkError(GalileoError):
    """The machine refused a line, raised an alarm, or the link failed."""

    def __init__(self, message: str, reply: P.Reply | None = None):
        self.reply = reply
        super().__init__(message)


class PortGone(LinkError):
    """The port vanished or fell silent: the job can be resumed from its journal."""


class MachineAlarm(LinkError):
    """The machine stopped in alarm; its `alarm:` line went to `on_message` already."""


class MachineStopped(PortGone):
    """The machine went into hold or alarm without the host asking (noise on the
    line): the job stopped where the machine ramped down and can be resumed."""


class ConfigMismatch(LinkError):
    """The flashed firmware was built for another machine than the profile plans for."""


def _machine_speed(port: serial.SerialBase) -> float | None:
    """Machine seconds per wall second: a board runs in real time, sim://?speed=S S times
    faster (0: instantly); None for simavr://?realtime=0, whose pace nobody knows
    beforehand (the streamer measures it)."""
    machine = getattr(port, "machine", None)
    if machine is not None:
        return float(machine.speed)
    board = getattr(port, "board", None)
    if board is not None and not getattr(board, "realtime", True):
        return None
    return 1.0


_ABORTED = P.ERROR_BY_NAME["ABORTED"].code


class MachineLink:
    """An open, greeted port; thread-safe for real-time bytes and status."""

    def __init__(self, port: serial.SerialBase, name: str, baud: int,
                 config: MachineConfig, config_path=None, profile: MachineConfig | None = None):
        self.port_name = name
        self.baud = baud
        self.config = config                # what jobs are planned with (the feed may change)
        self.config_path = config_path
        #: the profile as read: what the firmware must have been built for
        self.profile = profile or config
        #: (name, firmware's value, profile's value) where the build and the profile differ
        self.config_differences: tuple[tuple[str, str, int], ...] = ()
        self.simulated = is_simulated(name)
        self.speed = _machine_speed(port)
        self.banner: P.Banner | None = None
        self.initial_status: P.Status | None = None   # before our greeting reset the count
        self.on_message: Callable[[str], None] | None = None
        self.seq = 0                                   # the last sequence number sent
        self._port = port
        self._replies: queue.Queue = queue.Queue()
        self._status_cond = threading.Condition()
        self._status: P.Status | None = None
        self._status_count = 0
        self._garbled_count = 0        # lines whose check failed (one may be our status)
        self._alarm: P.Reply | None = None
        self._failure: Exception | None = None
        self._write_lock = threading.Lock()
        self._closed = False
        self._aborting = False         # our own abort: its alarm:14 is no news to the user
        self.held = False              # we sent a hold and no resume since
        self.resets = 0                # banners after the greeting: the board was reset
        #: seconds before a missing status or line reply is acted on (a test or bench
        #: against an instant machine may shorten them)
        self.status_retry_s = STATUS_RETRY_S
        self.reply_s = REPLY_S
        self._reader = threading.Thread(target=self._read_loop, name=f"link {name}",
                                        daemon=True)

    # ---- opening ------------------------------------------------------------------
    @classmethod
    def open(cls, port: str | None = None, baud: int = DEFAULT_BAUD,
             config: MachineConfig | None = None, config_path=None,
             profile: MachineConfig | None = None) -> "MachineLink":
        """Open `port` (None: find one, else `sim://`) and greet the firmware;
        `config_path` (the profile of `config`) is what `sim://` simulates."""
        from galileo_cnc.transport.discovery import find_port

        name = with_sim_config(port or find_port(baud), config_path)
        try:
            handle = open_port(name, baud, timeout=0.1)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise LinkError(f"cannot open {name}: {port_error_text(exc)}") from None
        return cls.attach(handle, name, baud, config, config_path, profile)

    @classmethod
    def attach(cls, handle: serial.SerialBase, name: str, baud: int = DEFAULT_BAUD,
               config: MachineConfig | None = None, config_path=None,
               profile: MachineConfig | None = None, booted: bool = False) -> "MachineLink":
        """Greet the machine over an already open pyserial port; `booted`: it has
        answered on this port already (discovery.open_identified read its banner),
        so there is no reset to wait out."""
        handle.timeout = 0.1
        link = cls(handle, name, baud, config or MachineConfig(), config_path, profile)
        link._reader.start()
        try:
            link._greet(booted)
            link._compare_config()
        except BaseException:
            link.close()
            raise
        return link

    def _greet(self, booted: bool = False) -> None:
        """Wait out a board's reset, note its status, then `N0 V` (restarts the count).

        A board that kept power while the cable was out may still be running lines
        of the last session: wait until its queue has run (so that its status `N`
        counts every line it will ever accept from that session, which resuming
        needs), and skip the replies it still owed, which arrive before ours.
        """
        deadline = time.monotonic() + (0.3 if self.simulated or booted else BANNER_WAIT_S)
        while self.banner is None and time.monotonic() < deadline:
            time.sleep(0.02)
        try:
            status = self.status(timeout_s=SILENT_S)
        except PortGone:
            raise PortGone(f"{self.port_name}: no answer from a galileo-cnc machine "
                           f"(is the firmware flashed, and the baud rate {self.baud}?)") from None
        while status.state in ("run", "homing"):
            time.sleep(0.05)
            status = self.status()
        self.initial_status = status
        self.seq = -1                       # so that the greeting goes out as N0
        seq, line = self.frame(P.QueryVersion())
        self.write(line)
        deadline = time.monotonic() + GREETING_S
        sends = 1
        while True:
            # replies the machine still owed the last session come first; ours (N0 is
            # always accepted) is the one with the banner
            reply = self.next_reply(self.reply_s)
            if reply is not None and reply.kind == "ok" and reply.seq == seq \
                    and reply.banner is not None:
                break
            if reply is None or reply.kind == "rs":     # lost or garbled: ask again
                if time.monotonic() > deadline or sends >= MAX_SENDS:
                    raise PortGone(f"{self.port_name}: no reply to "
                                   f"{line.decode().strip()!r}")
                self.write(line)
                sends += 1
        self.banner = P.check_banner(reply.banner)
        self._alarm = None

    def _compare_config(self) -> None:
        """Note what differs between the build (its banner's digest, then its `C` list)
        and the profile the host plans with; `check_config` refuses jobs then."""
        if self.banner.config_digest == self.profile.firmware_digest():
            self.config_differences = ()
            return
        reply = self.send_protocol(P.QueryConfig())
        flashed = dict(pair.split("=", 1) for pair in reply.text.split()[1:] if "=" in pair)
        self.config_differences = tuple(
            (name, flashed.get(name, "missing"), value)
            for name, value, _ in self.profile.firmware_values()
            if flashed.get(name) != str(value))

    def check_config(self) -> None:
        """ConfigMismatch, naming the fields, when the firmware was built for another machine."""
        if not self.config_differences:
            return
        fields = "; ".join(f"{name} {fw} in the firmware, {ours} in the profile"
                           for name, fw, ours in self.config_differences)
        profile = str(self.config_path) if self.config_path else "the default machine"
        raise ConfigMismatch(
            f"the firmware on {self.port_name} was built for another machine than "
            f"{profile} ({fields}). Regenerate its config with `python -m "
            f"galileo_cnc.firmware_headers --config {self.config_path or 'PROFILE.toml'}` "
            f"and reflash (`make -C firmware upload` in a galileo-cnc checkout), or plan with "
            f"the profile it was built for.")

    def describe(self) -> str:
        """The console's connection line."""
        if self.simulated:
            what = f"{self.port_name} (built-in simulated machine)"
        elif self.port_name.startswith(SIMAVR_URL):
            what = f"{self.port_name} (the firmware running in simavr)"
        else:
            what = self.port_name
        fw = f"firmware {self.banner.firmware_version}" if self.banner else "no banner"
        line = f"connected to {what}, {fw}, protocol {P.PROTOCOL_VERSION}, {self.baud} baud"
        if self.config_differences:
            names = ", ".join(name for name, _, _ in self.config_differences)
            verb = "differs" if len(self.config_differences) == 1 else "differ"
            line += (f"\nwarning: the firmware was built for another machine ({names} {verb} "
                     f"from the profile); jobs are refused until it is reflashed")
        return line

    @property
    def handle(self) -> serial.SerialBase:
        """The pyserial port (sim:// has `.machine`, simavr:// `.board`)."""
        return self._port

    def close(self) -> None:
        self._closed = True
        try:
            self._port.close()
        except (serial.SerialException, OSError):
            pass

    # ---- the reader thread ----------------------------------------------------------
    def _read_loop(self) -> None:
        buffer = b""
        while not self._closed:
            try:
                data = self._port.readline()
            except (serial.SerialException, OSError, TypeError, AttributeError) as exc:
                if not self._closed:
                    self._fail(PortGone(f"{self.port_name}: the port went away "
                                        f"({port_error_text(exc)})"))
                return
            if not data:
                continue
            buffer += data
            if not buffer.endswith(b"\n"):
                continue
            line, buffer = buffer, b""
            self._dispatch(line)

    def _fail(self, error: Exception) -> None:
        self._failure = error
        self._replies.put(error)
        with self._status_cond:
            self._status_cond.notify_all()

    def _dispatch(self, raw: bytes) -> None:
        try:
            reply = P.parse_reply(raw)
        except P.ProtocolError:
            # a garbled line is dropped, never believed; if it was the status being
            # waited for, `status()` asks again at once
            with self._status_cond:
                self._garbled_count += 1
                self._status_cond.notify_all()
            text = raw.decode("ascii", "replace").strip()
            if text:
                self._message(f"ignored from the machine: {text!r}")
            return
        if reply.kind in ("ok", "error", "rs"):
            self._replies.put(reply)
        elif reply.kind == "status":
            with self._status_cond:
                self._status = reply.status
                self._status_count += 1
                self._status_cond.notify_all()
        elif reply.kind == "banner":
            if self.banner is not None:
                self.resets += 1
            self.banner = reply.banner
        else:                                       # alarm:, msg:
            if reply.kind == "alarm":
                self._alarm = reply
                if self._aborting and reply.code == P.ERROR_BY_NAME["ABORTED"].code:
                    return
            self._message(f"{reply.kind}:{reply.code} {reply.text}".rstrip())

    def _message(self, text: str) -> None:
        if self.on_message is not None:
            self.on_message(text)

    # ---- writing ------------------------------------------------------------------------
    def write(self, data: bytes) -> None:
        if self._failure is not None:
            raise self._failure
        try:
            with self._write_lock:
                self._port.write(data)
        except (serial.SerialException, OSError) as exc:
            error = PortGone(f"{self.port_name}: cannot write, the port went away "
                             f"({port_error_text(exc)})")
            self._fail(error)
            raise error from None

    def next_seq(self) -> int:
        return 0 if self.seq < 0 else P.next_seq(self.seq)

    def frame(self, command: object) -> tuple[int, bytes]:
        """Take the next sequence number and frame `command` with it."""
        self.seq = self.next_seq()
        return self.seq, P.encode_command(command, self.seq)

    # ---- replies --------------------------------------------------------------------------
    def take_alarm(self) -> P.Reply | None:
        """The alarm raised since the last call, if any."""
        alarm, self._alarm = self._alarm, None
        return alarm

    def next_reply(self, timeout_s: float | None = None) -> P.Reply | None:
        """The next line reply; None after `timeout_s`. Raises PortGone when the port
        died or stays silent to the status query (asked every POLL_S while waiting)."""
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        while True:
            wait = POLL_S if deadline is None else min(POLL_S, deadline - time.monotonic())
            if wait <= 0:
                return None
            try:
                item = self._replies.get(timeout=wait)
            except queue.Empty:
                if deadline is not None and time.monotonic() >= deadline:
                    return None
                self.status()                       # raises PortGone if silent
                continue
            if isinstance(item, Exception):
                self._replies.put(item)             # every later wait fails the same way
                raise item
            return item

    def send_protocol(self, command: object, timeout_s: float | None = None) -> P.Reply:
        """Send one line and wait for its reply; LinkError on `error` (the machine did
        not count the line: its number is used again), PortGone after `timeout_s`.

        A reply may be lost or garbled: after `reply_s` without one the status says
        what became of the line. Its `N` is ours: accepted (a motion line's `ok` was
        lost; a query is asked again, its answer is in the `ok`). Not ours and the
        machine stands still with nothing queued: the line never arrived (or its
        `error` was lost), it is sent again. Otherwise it waits for queue room.
        """
        seq, line = self.frame(command)
        payload = isinstance(command, _PAYLOAD)
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        sends = 0

        def send_again(renumber: bool) -> None:
            nonlocal seq, line, sends
            sends += 1
            if sends >= MAX_SENDS:
                raise LinkError(f"{self.port_name}: line {line!r} not accepted after "
                                f"{MAX_SENDS} tries (a very noisy cable?)")
            if renumber:
                seq, line = self.frame(command)
            self.write(line)

        self.write(line)
        while True:
            reply = self.next_reply(self.reply_s)
            if reply is None and deadline is not None and time.monotonic() > deadline:
                raise PortGone(f"{self.port_name}: no reply to {line.decode().strip()!r}")
            stray_rs = reply is not None and reply.kind == "rs" \
                and reply.seq not in (seq, P.next_seq(seq))
            if reply is None or stray_rs:
                # no reply, or `rs` for another number: a late one to lines a job had in
                # flight, or the machine's count was reset. Never renumber from the `rs`
                # itself (a late `ok` to that old number would pass for ours): the
                # status says what became of the line and which number comes next.
                status = self.status()
                if status.last_seq == seq:
                    if not payload:
                        return P.Reply("ok", seq)           # accepted, its `ok` was lost
                    send_again(renumber=True)
                elif stray_rs and status.last_seq != previous_seq(seq):
                    self.seq = status.last_seq              # the count was reset
                    send_again(renumber=True)
                elif status.queue_blocks == 0 and status.state != "run":
                    send_again(renumber=False)              # lost on the way, or refused
                continue
            if reply.kind == "ok":
                if reply.seq == seq:
                    return reply
                continue                                    # late, to a line sent before
            if reply.kind == "error":
                if reply.seq is None:                       # garbled past the checksum
                    send_again(renumber=False)
                    continue
                if reply.seq != seq:
                    continue                                # late, to a line sent before
                self.seq = previous_seq(seq)               # expected again
                raise LinkError(self.refusal_text(command, reply), reply)
            if reply.kind == "rs":
                if reply.seq == seq:
                    send_again(renumber=False)              # our line was garbled
                else:
                    # a copy of a line the machine had accepted: ours went through
                    if not payload:
                        return P.Reply("ok", seq)
                    send_again(renumber=True)

    def send(self, command: Command, timeout_s: float | None = None) -> P.Reply:
        """One machine command (jog, origin, feed, home...): waits for its `ok`."""
        return self.send_protocol(command, timeout_s)

    # ---- real-time ----------------------------------------------------------------------
    def refusal_text(self, command: Command, reply: P.Reply) -> str:
        """A refused command as the user reads it: in mm, the wire's line in brackets
        (a soft limit, which the machine says in steps, in mm of machine coordinates)."""
        detail = reply.text
        limit = P.parse_soft_limit(reply.text) \
            if reply.code == P.ERROR_BY_NAME["SOFT_LIMIT"].code else None
        if limit is not None:
            detail = (f"soft limit: {self.config.travel_refusal(*limit)} (machine coordinates)"
                      f"{self._work_travel_text(command, *limit)}")
        return (f"the machine refused {command_text(command, self.config.steps_per_mm)} "
                f"[{P.command_text(command)}]: error:{reply.code} {detail}")

    def _work_travel_text(self, command: Command, axis: str, value: int, limit: int) -> str:
        """Where the travel ends in the command's own (work) coordinates, when an origin
        set away from the machine's zero moved it: a move to its target is checked at
        that target, so the origin is the difference."""
        target = getattr(command, f"{axis.lower()}_steps", None) \
            if isinstance(command, (J.Rapid, J.LineTo)) else None
        if target is None or value == target:
            return ""
        spm = self.config.steps_per_mm
        origin = value - target
        end = "ends" if value > limit else "starts"
        return (f"; the origin was set at {axis} {origin / spm:.3f} mm on the machine, so "
                f"in work coordinates the travel {end} at {axis} {(limit - origin) / spm:.3f} mm")

    def status(self, timeout_s: float | None = None) -> P.Status:
        """A fresh status (real-time status byte, asked again after `status_retry_s`,
        then twice as long each time up to STATUS_RETRY_S, or as soon as a garbled
        line arrives: a garbled or lost status line ends nothing); PortGone when none
        comes in `timeout_s` (SILENT_S, read when called)."""
        with self._status_cond:
            count = self._status_count
        timeout_s = SILENT_S if timeout_s is None else timeout_s
        deadline = time.monotonic() + timeout_s
        retry_s = self.status_retry_s
        while True:
            self.write(P.RT_STATUS)
            ask_again = time.monotonic() + retry_s
            with self._status_cond:
                garbled = self._garbled_count
                while self._status_count == count:
                    if self._failure is not None:
                        raise self._failure
                    now = time.monotonic()
                    if now >= deadline:
                        raise PortGone(f"{self.port_name}: no status reply for "
                                       f"{timeout_s:g} s")
                    if self._garbled_count != garbled:
                        break                   # answered, garbled: ask again now
                    if now >= ask_again:
                        # no answer: a slow line must not fill up with status lines
                        retry_s = min(2 * retry_s, STATUS_RETRY_S)
                        break
                    self._status_cond.wait(min(deadline, ask_again) - now)
                else:
                    return self._status

    def wait_idle(self, timeout_s: float | None = None, poll_s: float = 0.05) -> P.Status:
        """Poll until the queue is empty and the machine stands still. Not endless:
        a machine in alarm, or held without our asking, raises (`standing`); one that
        runs gets there (the queue holds at most QUEUE_BLOCKS blocks)."""
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        while True:
            status = self.status()
            if self.standing(status):
                return status
            if deadline is not None and time.monotonic() > deadline:
                raise LinkError(f"machine still busy after {timeout_s:g} s: {status.text()}")
            time.sleep(poll_s)

    def standing(self, status: P.Status) -> bool:
        """Idle with an empty queue; MachineAlarm if the machine is in alarm,
        MachineStopped if it stopped on its own (a hold or abort we did not send)."""
        if status.state == "alarm":
            alarm = self.take_alarm()
            if (alarm is None or alarm.code == _ABORTED) and not self._aborting:
                said = f"alarm:{alarm.code} {alarm.text}" if alarm else "its alarm line was lost"
                raise MachineStopped(
                    f"{self.port_name}: the machine stopped in alarm ({said}) although the "
                    f"host did not ask: noise on the cable?")
            raise MachineAlarm(f"machine alarm: {alarm.code} {alarm.text}" if alarm
                               else "machine in alarm state (send U)")
        if status.state == "hold" and not self.held:
            raise MachineStopped(f"{self.port_name}: the machine went into feed hold "
                                 f"although the host did not ask: noise on the cable?")
        return status.state == "idle" and status.queue_blocks == 0

    def hold(self) -> None:
        self.held = True
        self.write(P.RT_HOLD)

    def resume(self) -> None:
        self.held = False
        self.write(P.RT_RESUME)

    def abort(self, timeout_s: float = 30.0) -> P.Status:
        """Ramp down and drop the queue (`alarm:14`), then unlock; the position stays known."""
        self._aborting = True
        try:
            self.write(P.RT_ABORT)
            deadline = time.monotonic() + timeout_s
            while True:
                status = self.status()
                if status.state == "alarm" and status.queue_blocks == 0:
                    break
                if time.monotonic() > deadline:
                    raise LinkError(f"machine did not stop within {timeout_s:g} s: "
                                    f"{status.text()}")
                time.sleep(0.02)
            self.drain_replies()
            self.send_protocol(P.Unlock())
            self.take_alarm()
            self.held = False
        finally:
            self._aborting = False
        return self.status()

    def drain_replies(self, quiet_s: float = 0.1) -> list[P.Reply]:
        """Collect line replies still on their way (after an abort) until quiet."""
        replies = []
        while (reply := self.next_reply(quiet_s)) is not None:
            replies.append(reply)
        return replies


def previous_seq(seq: int) -> int:
    """The number sent before `seq` (so that `next_seq` gives `seq` again)."""
    return P.SEQ_MAX if seq == 1 else seq - 1
