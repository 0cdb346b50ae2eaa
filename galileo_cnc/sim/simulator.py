"""The built-in simulated machine: the reference machine behind the wire protocol.

`SimulatedMachine` takes the bytes a host writes and produces the bytes the
firmware would answer (docs/protocol.md): the banner, exactly one reply per
line (`ok N<seq>`, `error:CODE ...`, `rs N<expected>`), the real-time bytes
(P.RT_STATUS, RT_HOLD, RT_RESUME, RT_ABORT) picked off wherever they arrive,
and `alarm:` lines. Line checks follow the firmware's `handle_line`
(firmware/galileo/commands.cpp) step by step, so a bad line gets the same reply
from `sim://` as from the board: the sequence number is checked before the
mnemonic and the arguments, and counted only when the line is accepted, exactly
as there.

Accepted motion is planned at once on a `ReferenceMachine` (soft limits, feeds,
arcs) and put on a `Timeline`, which gives every step its tick with the
reference's own timing. A `SimClock` says how far the machine has got: it
follows wall time at `speed` (1.0 = real time), or is instant (speed 0: every
accepted move is done when its `ok` goes out). Blocks leave the queue of
QUEUE_BLOCKS when the clock passes their end, so a line that does not fit waits
unanswered (the firmware's flow control) until a background waker finds room.
docs/sim.md describes the design; the pyserial side is `galileo_cnc.protocol_sim`.
"""

from __future__ import annotations

import threading
from collections import deque
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from galileo_cnc import protocol as P
from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.job import MachineError, SetOrigin
from galileo_cnc.machine import ReferenceMachine, Trace
from galileo_cnc.machine.blocks import Pause
from galileo_cnc.sim.timeline import SimClock, Timeline

_ABORTED = P.ERROR_BY_NAME["ABORTED"].code


# ---- the machine behind the protocol ---------------------------------------------------
Snapshot = tuple[tuple[int, int, int], tuple[int, int, int], tuple[int, int, int]]


@dataclass(eq=False)
class _Block:
    """One queue entry: the blocks a command takes and when they are done.

    `first` (its first event) and `end` (tick) are None until it is scheduled (a command queued
    during a hold is scheduled on resume). `alarm` marks a command the machine
    finds impossible while running (homing): the alarm goes off when it is reached.
    """

    slots: int
    items: list
    after: Snapshot                     # machine position, origin, phys offset after it
    mnemonic: str
    alarm: int = 0
    first: int | None = None
    end: int | None = None


class SimulatedMachine:
    """The firmware's serial behaviour over the reference machine, in time (thread-safe).

    `speed` is the clock's speed (0: instant). A paced machine has a waker
    thread that answers waiting lines and raises alarms when their time comes;
    `close()` ends it.
    """

    def __init__(self, config: MachineConfig | None = None,
                 output: Callable[[bytes], None] | None = None, speed: float = 0.0):
        self.config = config or MachineConfig()
        self.speed = speed
        self._output = output or _discard
        self._lock = threading.RLock()
        self._wake = threading.Condition(self._lock)
        self._closed = False
        self._power_on()
        self._waker = None
        if not self._clock.instant:
            self._waker = threading.Thread(target=self._run_waker, daemon=True,
                                           name="sim-machine-waker")
            self._waker.start()

    def _power_on(self) -> None:
        self._clock = SimClock(self.speed)
        self.machine = ReferenceMachine(self.config)
        self._home_axes = sum(1 for pin in self.config.home_pins if pin != -1)
        self._expected_seq = 1
        self._last_seq = 0
        self._alarm = 0
        self._aborting = False
        self._line = bytearray()
        self._too_long = False
        self._rx = bytearray()              # bytes waiting while a line is pending
        self.rx_overflows = 0
        self._pending: tuple[int, object, str] | None = None
        self._queue: deque[_Block] = deque()
        self._timeline = Timeline()
        self._retired: Snapshot = self._snapshot()   # state after the last finished block

    # ---- host side ----------------------------------------------------------------
    def reset(self) -> Trace:
        """Power-on: fresh machine, banner. The head stays where it physically stands:
        its position restarts at 0 there, the end stops do not move (homing finds them).
        Returns the steps executed since the previous power-on (the trace it ends)."""
        with self._lock:
            self._service()
            now = self._clock.now()         # one instant for both: the clock runs on
            before = self._trace(now)
            position, _, phys = self._position(now)
            physical = tuple(p + o for p, o in zip(position, phys))
            self._power_on()
            self.machine.phys_offset = list(physical)
            self._retired = self._snapshot()
            self._emit(self._banner().text())
            self._wake.notify_all()
            return before

    def attach(self, output: Callable[[bytes], None]) -> bool:
        """Plug a host in (False if another one is); replies go to `output`."""
        with self._lock:
            if self._output is not _discard:
                return False
            self._output = output
            return True

    def detach(self) -> None:
        """Unplug the host: the machine keeps power and runs on; its replies are lost."""
        with self._lock:
            self._output = _discard

    def close(self) -> None:
        """Power off: stop the waker thread."""
        with self._lock:
            self._closed = True
            self._wake.notify_all()
        if self._waker is not None and self._waker is not threading.current_thread():
            self._waker.join(1.0)

    def receive(self, data: bytes) -> None:
        """Bytes from the host, in order (real-time bytes act where they arrive)."""
        with self._lock:
            for byte in data:
                b = bytes((byte,))
                if b == P.RT_STATUS:
                    self._service()
                    self._emit(self._status(self._clock.now()).text())
                elif b == P.RT_HOLD:
                    self._start_hold()
                elif b == P.RT_RESUME:
                    self._resume()
                    self._service()
                elif b == P.RT_ABORT:
                    self._start_hold()
                    self._aborting = True
                    self._service()
                elif self._pending is not None:
                    if len(self._rx) < P.RX_BUFFER_BYTES:
                        self._rx.append(byte)
                    else:
                        self.rx_overflows += 1      # lost: the line's checksum will fail
                else:
                    self._assemble(byte)
                    if self._pending is not None:
                        self._service()

    def status(self) -> P.Status:
        with self._lock:
            self._service()
            return self._status(self._clock.now())

    def physical_position(self) -> tuple[int, int, int]:
        """Where the head stands in the simulated world, in steps from the first
        power-on's position (what a reset keeps, and the end stops are placed in)."""
        with self._lock:
            position, _, phys = self._position(self._clock.now())
            return tuple(p + o for p, o in zip(position, phys))

    def move_by_hand(self, physical: tuple[int, int, int]) -> None:
        """The user turns the lead screws of the standing machine until the head is at
        `physical`: it does not know (its position stays), the world moved."""
        with self._lock:
            self._service()
            if self._queue:
                raise ValueError("the machine is moving")
            position, origin, _ = self._retired
            phys = tuple(p - q for p, q in zip(physical, position))
            self.machine.phys_offset = list(phys)
            self._retired = (position, origin, phys)

    def trace(self) -> Trace:
        """Every step executed since power-on, up to the machine's clock."""
        with self._lock:
            self._service()
            return self._trace(self._clock.now())

    def _trace(self, now: int | None) -> Trace:
        tick, axis, direction = self._timeline.steps(now)
        position, origin, _ = self._position(now)
        work = tuple(p - o for p, o in zip(position, origin))
        end = self._timeline.end if now is None else min(self._timeline.end, now)
        return Trace(tick, axis.astype(np.int8, copy=False),
                     direction.astype(np.int8, copy=False), work, end)

    # ---- time: the queue follows the clock ---------------------------------------------
    def _run_waker(self) -> None:
        """Answer a waiting line, retire blocks, raise due alarms when their time comes."""
        with self._lock:
            while not self._closed:
                self._service()
                due = self._next_due()
                if due is None:
                    self._wake.wait()
                else:   # a little late rather than early: no spinning on rounding
                    self._wake.wait(self._clock.seconds_until(due) + 1e-4)

    def _next_due(self) -> int | None:
        """The tick at which the machine next changes what it says."""
        if self._aborting:
            return self._timeline.stop
        if not self._queue or self._queue[0].end is None:
            return None
        end = self._queue[0].end
        if self._timeline.held and end > self._timeline.stop:
            return None                     # waits for the resume
        return end

    def _advance(self, now: int | None) -> None:
        """Retire the blocks finished by `now`; an abort ends when its stop is reached."""
        held = self._timeline.held
        while self._queue:
            block = self._queue[0]
            if block.end is None or (now is not None and block.end > now):
                break
            if held and block.end > self._timeline.stop:
                break
            self._queue.popleft()
            self._retired = block.after
            if block.alarm:
                self._stop_with_alarm(block.alarm, block.end)
                return
        if self._aborting and (now is None or now >= self._timeline.stop):
            self._stop_with_alarm(_ABORTED, None)
            return
        head = self._queue[0].first if self._queue else None
        self._timeline.trim(self._timeline.count if head is None else head)

    def _schedule(self, block: _Block, now: int | None) -> None:
        block.first, block.end = self._timeline.append(block.items, now)

    def _start_hold(self) -> None:
        """Hold (RT_HOLD): decelerate from the current clock and stop (docs/motion.md §6)."""
        now = self._clock.now()
        self._advance(now)
        if not self._timeline.held:
            self._timeline.hold(self._timeline.end if now is None else now)

    def _resume(self) -> None:
        """Resume (RT_RESUME): the rest of the move with a fresh ramp, then the blocks
        queued meanwhile."""
        if not self._timeline.held or self._aborting:
            return                          # the firmware ignores a resume during an abort
        now = self._clock.now()
        stop, shift = self._timeline.resume(now)
        for block in self._queue:
            if block.end is not None and block.end > stop:
                block.end += shift
        for block in self._queue:
            if block.end is None:
                self._schedule(block, now)

    def _stop_with_alarm(self, code: int, at: int | None) -> None:
        """Stop (decelerating), drop the queue, resynchronise the planner, lock."""
        if not self._timeline.held:
            self._timeline.hold(self._timeline.end if at is None else at)
        self._timeline.abort()
        self._retired = position, origin, phys = self._position(None)   # at the stop
        self.machine.position = list(position)
        self.machine.origin = list(origin)
        self.machine.phys_offset = list(phys)
        self._queue.clear()
        self._aborting = False
        self._alarm = code
        self._emit(P.format_error(code))

    def _position(self, now: int | None) -> Snapshot:
        """Live machine position at `now`: the last finished block plus the steps since."""
        position, origin, phys = self._retired
        count = self._timeline.count        # the queue's first scheduled event, if any
        head = min(count, self._queue[0].first if self._queue and self._queue[0].first
                   is not None else count)
        moved = self._timeline.displacement(head, max(head, self._timeline.executed(now)))
        return tuple(p + int(d) for p, d in zip(position, moved)), origin, phys

    def _status(self, now: int | None) -> P.Status:
        position, origin, _ = self._position(now)
        queued = sum(block.slots for block in self._queue)
        if self._alarm:
            state = "alarm"
        elif self._timeline.held:
            state = "hold"
        elif self._queue and self._queue[0].mnemonic == "H":
            state = "homing"
        elif queued:
            state = "run"
        else:
            state = "idle"
        return P.Status(state, *(p - o for p, o in zip(position, origin)), queued,
                        self._last_seq)

    # ---- lines --------------------------------------------------------------------------
    def _emit(self, text: str) -> None:
        """One line to the host, with the check the firmware's serial_end_line adds."""
        self._output(P.checked(text.encode("ascii")))

    def _snapshot(self) -> Snapshot:
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
            # a refused line is not counted (protocol 3): its number is expected again
            if rejected.resend:
                return self._resend()
            return self._emit(P.format_error(rejected.code, rejected.seq))
        self._pending = (seq, command, mnemonic)   # counted once accepted

    def _accept_seq(self, seq: int) -> None:
        self._last_seq = seq
        self._expected_seq = P.next_seq(seq)

    def _service(self) -> None:
        """Catch up with the clock, then the pending line, then buffered bytes."""
        while True:
            now = self._clock.now()
            self._advance(now)
            if self._pending is not None:
                if not self._execute_pending(now):
                    break                   # waits for queue room
                continue
            if not self._rx:
                break
            data, self._rx = bytes(self._rx), bytearray()
            for i, byte in enumerate(data):
                if self._pending is not None:
                    self._rx[:0] = data[i:]
                    break
                self._assemble(byte)
        self._wake.notify_all()             # the waker recomputes when to look again

    def _execute_pending(self, now: int | None) -> bool:
        seq, cmd, mnemonic = self._pending
        spec = P.BY_MNEMONIC[mnemonic]
        protocol_only = spec.name in P.PROTOCOL_ONLY
        err, detail = 0, ""
        if not protocol_only and self._alarm:
            err = 9
        elif not protocol_only and self.machine.ended:
            err = 8
        if not err:
            used = sum(block.slots for block in self._queue)
            needed = P.blocks_needed(spec, self._home_axes)
            if P.QUEUE_BLOCKS - used < needed:
                return False
            if isinstance(cmd, P.Unlock):
                self._alarm = 0
                self.machine.ended = False
            elif not protocol_only:
                err, detail = self._plan(cmd, mnemonic, needed, now)
        self._pending = None
        if err:
            self._emit(P.format_error(err, seq, detail))
            return True
        self._accept_seq(seq)
        payload = ""
        if isinstance(cmd, P.QueryStatus):
            payload = " " + self._status(now).text()
        elif isinstance(cmd, P.QueryVersion):
            payload = " " + self._banner().text()
        elif isinstance(cmd, P.QueryConfig):
            payload = " config " + self.config.firmware_text()
        self._emit(f"ok N{seq}{payload}")
        return True

    def _banner(self) -> P.Banner:
        """The banner of a board built for this machine's config."""
        return P.Banner(P.FIRMWARE_VERSION, P.PROTOCOL_VERSION, P.RX_BUFFER_BYTES,
                        P.QUEUE_BLOCKS, self.config.firmware_digest())

    def _plan(self, cmd, mnemonic: str, needed: int, now: int | None) -> tuple[int, str]:
        """Plan one command and queue its blocks; (error code, detail)."""
        try:
            items = self.machine.plan([cmd])
        except MachineError as exc:
            text = str(exc)
            if exc.value is not None:
                return 5, P.soft_limit_detail(exc.axis, exc.value, exc.limit)
            if "arc radius too large" in text:
                return 7, ""
            if "feed" in text and "outside" in text:
                return 6, ""
            for code, words in ((10, "already active"), (11, "not found"),
                                (12, "after the pull-off")):
                if words in text:           # found "while the job runs" on the board
                    # a seek that finds no switch runs to its end first, as the board's
                    moves = getattr(exc, "moves_until_alarm", [])
                    after = getattr(exc, "state_at_alarm", self._snapshot())
                    self._queue_block(_Block(needed, moves, after, mnemonic, code), now)
                    return 0, ""
            if "job has ended" in text:
                return 8, ""
            return 4, ""
        exit_index = getattr(cmd, "exit_index", None)
        moves = [i for i, it in enumerate(items) if not isinstance(it, Pause) and it.n]
        if exit_index and moves:            # the firmware caps it at the ramp (§5.7)
            last = items[moves[-1]]
            items[moves[-1]] = replace(last, exit=min(exit_index, last.ramp))
        blocks = len(items) + (1 if isinstance(cmd, SetOrigin) else 0)  # the origin block
        if blocks:
            self._queue_block(_Block(blocks, items, self._snapshot(), mnemonic), now)
        return 0, ""

    def _queue_block(self, block: _Block, now: int | None) -> None:
        self._queue.append(block)
        if not self._timeline.held:         # during a hold: scheduled on resume
            self._schedule(block, now)


def _discard(data: bytes) -> None:
    """Where replies go while no host is plugged in."""


# ---- named machines: boards that keep power while the port is closed ----------------------
_named: dict[str, SimulatedMachine] = {}
_named_lock = threading.Lock()


def open_named_machine(name: str, config: MachineConfig, speed: float
                       ) -> tuple[SimulatedMachine, bool]:
    """The machine `sim://NAME`, powered on at its first open; (machine, powered on now)."""
    with _named_lock:
        machine = _named.get(name)
        if machine is not None:
            if machine.config != config or machine.speed != speed:
                raise ValueError(f"sim://{name} is already running with another "
                                 f"configuration or speed")
            return machine, False
        machine = _named[name] = SimulatedMachine(config, speed=speed)
        return machine, True


def named_machine(name: str) -> SimulatedMachine:
    """The running machine `sim://NAME` (KeyError if it was never opened)."""
    with _named_lock:
        return _named[name]


def forget_named_machines() -> None:
    """Power every named machine off (test isolation)."""
    with _named_lock:
        machines = list(_named.values())
        _named.clear()
    for machine in machines:
        machine.close()
