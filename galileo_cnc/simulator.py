"""The built-in simulated machine: the reference machine behind the wire protocol.

`SimulatedMachine` takes the bytes a host writes and produces the bytes the
firmware would answer (docs/protocol.md): the banner, exactly one reply per
line (`ok N<seq>`, `error:CODE ...`, `rs N<expected>`), the real-time bytes
(`?` status, `!` hold, `~` resume, 0x18 abort) picked off wherever they arrive,
and `alarm:` lines. Line checks follow the firmware's `handle_line`
(firmware/galileo/commands.cpp) step by step, so a bad line gets the same reply
from `sim://` as from the board: the sequence number is consumed before the
mnemonic and the arguments are checked, exactly as there.

Accepted motion is planned on a `ReferenceMachine` (soft limits, feeds, arcs)
and executed at once on its virtual clock: the accumulated step trace
(`trace()`) is what the firmware would step, without real-time pacing. While
a feed hold is in force, planned blocks wait in a queue of QUEUE_BLOCKS (a line
that does not fit waits unanswered, the firmware's flow control) and run on
resume; an abort drops them. The pyserial side is `galileo_cnc.protocol_sim`.
"""

from __future__ import annotations

import re
import threading
from collections import deque
from typing import Callable

import numpy as np

from . import protocol as P
from .config import MachineConfig
from .machine import MachineError, ReferenceMachine, SetOrigin, Trace
from .machine import vector

_PROTOCOL_ONLY = (P.QueryStatus, P.QueryVersion, P.Unlock)
_LIMIT_RE = re.compile(r"([XYZ]) would reach (-?\d+) steps, (below|beyond)")


def _blocks_needed(mnemonic: str, home_axes: int) -> int:
    """The firmware's `planner_blocks_needed`: queue room a command reserves."""
    if mnemonic == "R":
        return 2
    if mnemonic == "FL":
        return 3
    if mnemonic == "H":
        return 3 * home_axes
    if mnemonic in ("L", "CW", "CCW", "PU", "PD", "DW", "J", "O", "E"):
        return 1
    return 0


class SimulatedMachine:
    """The firmware's serial behaviour over the reference machine (thread-safe)."""

    def __init__(self, config: MachineConfig | None = None,
                 output: Callable[[bytes], None] | None = None):
        self.config = config or MachineConfig()
        self._output = output or (lambda data: None)
        self._lock = threading.RLock()
        self.machine = ReferenceMachine(self.config)
        self._home_axes = sum(1 for pin in self.config.home_pins if pin != -1)
        self._expected_seq = 1
        self._last_seq = 0
        self._alarm = 0
        self._hold = False
        self._line = bytearray()
        self._too_long = False
        self._rx = bytearray()              # bytes waiting while a line is pending
        self.rx_overflows = 0
        self._pending: tuple[int, object, str] | None = None
        self._queue: deque = deque()        # (blocks, items, live state after them)
        self._live = self._snapshot()
        self._parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []

    # ---- host side ----------------------------------------------------------------
    def reset(self) -> None:
        """Power-on: fresh machine, banner."""
        with self._lock:
            output = self._output
            self.__init__(self.config, output)
            self._emit(P.Banner(P.FIRMWARE_VERSION, P.PROTOCOL_VERSION, P.RX_BUFFER_BYTES,
                                P.QUEUE_BLOCKS).text())

    def receive(self, data: bytes) -> None:
        """Bytes from the host, in order (real-time bytes act where they arrive)."""
        with self._lock:
            for byte in data:
                b = bytes((byte,))
                if b == P.RT_STATUS:
                    self._emit(self.status().text())
                elif b == P.RT_HOLD:
                    self._hold = True
                elif b == P.RT_RESUME:
                    self._hold = False
                    self._service()
                elif b == P.RT_ABORT:
                    self._abort()
                elif self._pending is not None:
                    if len(self._rx) < P.RX_BUFFER_BYTES:
                        self._rx.append(byte)
                    else:
                        self.rx_overflows += 1      # lost: the line's checksum will fail
                else:
                    self._assemble(byte)

    def status(self) -> P.Status:
        with self._lock:
            position, origin, _ = self._live
            queued = sum(entry[0] for entry in self._queue)
            if self._alarm:
                state = "alarm"
            elif self._hold:
                state = "hold"
            elif queued:
                state = "run"
            else:
                state = "idle"
            return P.Status(state, *(p - o for p, o in zip(position, origin)), queued,
                            self._last_seq)

    def trace(self) -> Trace:
        """Every step executed since power-on (ticks on the machine's virtual clock)."""
        with self._lock:
            if self._parts:
                tick, axis, direction = (np.concatenate([p[i] for p in self._parts])
                                         for i in range(3))
            else:
                tick = np.zeros(0, dtype=np.int64)
                axis = direction = np.zeros(0, dtype=np.int8)
            position, origin, _ = self._live
            work = tuple(p - o for p, o in zip(position, origin))
            return Trace(tick, axis, direction, work, self.machine.clock_ticks)

    # ---- internals ------------------------------------------------------------------
    def _emit(self, text: str) -> None:
        self._output(text.encode("ascii") + b"\n")

    def _snapshot(self) -> tuple:
        m = self.machine
        return (tuple(m.position), tuple(m.origin), tuple(m.phys_offset))

    def _assemble(self, byte: int) -> None:
        """The firmware's `serial_read_line`: '\\r' ignored, empty lines ignored."""
        if byte == 0x0D:
            return
        if byte == 0x0A:
            line, too_long = bytes(self._line), self._too_long
            self._line.clear()
            self._too_long = False
            if too_long:
                self._emit(P.format_error(2))
            elif line:
                self._handle_line(line)
            return
        if len(self._line) < P.MAX_LINE_BYTES - 1:
            self._line.append(byte)
        else:
            self._too_long = True

    def _resend(self) -> None:
        self._emit(f"rs N{self._expected_seq}")

    def _handle_line(self, s: bytes) -> None:
        """The firmware's `handle_line` (protocol.decode_line follows it check for check)."""
        try:
            seq, command, mnemonic = P.decode_line(s, self._expected_seq)
        except P.LineRejected as rejected:
            if rejected.seq is not None:
                self._accept_seq(rejected.seq)
            if rejected.resend:
                return self._resend()
            return self._emit(P.format_error(rejected.code, rejected.seq))
        self._accept_seq(seq)
        self._pending = (seq, command, mnemonic)
        self._service()

    def _accept_seq(self, seq: int) -> None:
        self._last_seq = seq
        self._expected_seq = P.next_seq(seq)

    def _service(self) -> None:
        """Run queued blocks (unless held), the pending line, then buffered bytes."""
        while True:
            if not self._hold:
                self._drain()
            if self._pending is not None and not self._execute_pending():
                return                      # waits for queue room (a hold is in force)
            if not self._rx:
                return
            data, self._rx = bytes(self._rx), bytearray()
            for i, byte in enumerate(data):
                if self._pending is not None:
                    self._rx.extend(data[i:])
                    break
                self._assemble(byte)

    def _execute_pending(self) -> bool:
        seq, cmd, mnemonic = self._pending
        protocol_only = isinstance(cmd, _PROTOCOL_ONLY)
        err, detail, alarm = 0, "", 0
        if not protocol_only and self._alarm:
            err = 9
        elif not protocol_only and self.machine.ended:
            err = 8
        if not err:
            used = sum(entry[0] for entry in self._queue)
            if P.QUEUE_BLOCKS - used < _blocks_needed(mnemonic, self._home_axes):
                return False
            if isinstance(cmd, P.Unlock):
                self._alarm = 0
                self.machine.ended = False
            elif not protocol_only:
                err, detail, alarm = self._plan(cmd)
        self._pending = None
        if err:
            self._emit(P.format_error(err, seq, detail))
            return True
        payload = ""
        if isinstance(cmd, P.QueryStatus):
            payload = " " + self.status().text()
        elif isinstance(cmd, P.QueryVersion):
            payload = " " + P.Banner(P.FIRMWARE_VERSION, P.PROTOCOL_VERSION,
                                     P.RX_BUFFER_BYTES, P.QUEUE_BLOCKS).text()
        self._emit(f"ok N{seq}{payload}")
        if alarm:                           # found "while the job runs" on the board
            self._enter_alarm(alarm)
        elif not self._hold:
            self._drain()
        return True

    def _plan(self, cmd) -> tuple[int, str, int]:
        """Plan one command; (error code, detail, alarm code)."""
        try:
            items = self.machine.plan([cmd])
        except MachineError as exc:
            text = str(exc)
            m = _LIMIT_RE.search(text)
            if m is not None:
                side = "above" if m.group(3) == "beyond" else "below"
                return 5, f"{m.group(1)} would reach {m.group(2)}, {side} {exc.limit}", 0
            if "arc radius too large" in text:
                return 7, "", 0
            if "feed" in text and "outside" in text:
                return 6, "", 0
            if "already active" in text:
                return 0, "", 10
            if "not found" in text:
                return 0, "", 11
            if "after the pull-off" in text:
                return 0, "", 12
            if "job has ended" in text:
                return 8, "", 0
            return 4, "", 0
        blocks = len(items) + (1 if isinstance(cmd, SetOrigin) else 0)  # the origin block
        if blocks:
            self._queue.append((blocks, items, self._snapshot()))
        return 0, "", 0

    def _drain(self) -> None:
        while self._queue:
            _blocks, items, live = self._queue.popleft()
            if items:
                tick, axis, direction, end, _ = vector.execute(items, self.machine.clock_ticks)
                self.machine.clock_ticks = end
                if len(tick):
                    self._parts.append((tick, axis, direction))
            self._live = live

    def _abort(self) -> None:
        """Stop, drop the queue, resynchronise the planner, `alarm:14`, locked."""
        self._queue.clear()
        self._hold = False
        self._enter_alarm(14)
        self._service()

    def _enter_alarm(self, code: int) -> None:
        self._alarm = code
        self._queue.clear()
        position, origin, phys = self._live
        self.machine.position = list(position)
        self.machine.origin = list(origin)
        self.machine.phys_offset = list(phys)
        self._emit(P.format_error(code))
