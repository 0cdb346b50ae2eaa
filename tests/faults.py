"""Faults a user meets: a pyserial port with a noisy cable or a pulled USB plug, and a
Ctrl-C pressed while a job runs."""

from __future__ import annotations

import _thread
import threading
import time
from typing import Callable

import serial


def ctrl_c_when(ready: Callable[[], bool], timeout_s: float, poll_s: float) -> threading.Thread:
    """Ctrl-C (KeyboardInterrupt in the main thread, where `plot` runs) as soon as
    `ready()` holds, asked every `poll_s` for at most `timeout_s`."""
    def watch() -> None:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if ready():
                _thread.interrupt_main()
                return
            time.sleep(poll_s)
    thread = threading.Thread(target=watch, daemon=True)
    thread.start()
    return thread


class FaultyPort:
    """A pyserial port passed through, with faults on chosen lines.

    corrupt_line / drop_line: the n-th line written (1-based) has a byte flipped /
    never arrives; drop_reply: the n-th `ok` read never arrives; garbage_after:
    a line of noise is read after the n-th reply; die_after: the port vanishes
    after n lines written (writes and reads raise SerialException).
    """

    def __init__(self, port, *, corrupt_line=0, drop_line=0, drop_reply=0, garbage_after=0,
                 die_after=0):
        self.port = port
        self.corrupt_line, self.drop_line, self.drop_reply = corrupt_line, drop_line, drop_reply
        self.garbage_after, self.die_after = garbage_after, die_after
        self.lines_written = self.oks_read = self.replies_read = 0
        self.max_unanswered_bytes = 0
        self._unanswered: list[int] = []
        self.dead = False
        self._pending_noise = b""

    def write(self, data: bytes) -> int:
        if self.dead:
            raise serial.SerialException("device disconnected")
        if data.endswith(b"\n"):
            self.lines_written += 1
            n = self.lines_written
            if n == self.die_after:
                self.dead = True
                raise serial.SerialException("device disconnected")
            if n == self.drop_line:
                return len(data)
            if n == self.corrupt_line:
                data = data[:3] + bytes([data[3] ^ 0x01]) + data[4:]
            self._unanswered.append(len(data))
            self.max_unanswered_bytes = max(self.max_unanswered_bytes, sum(self._unanswered))
        return self.port.write(data)

    def readline(self) -> bytes:
        if self.dead:
            raise serial.SerialException("device disconnected")
        if self._pending_noise:
            noise, self._pending_noise = self._pending_noise, b""
            return noise
        line = self.port.readline()
        kind = line.split(b":")[0].split(b" ")[0]
        if kind in (b"ok", b"rs") or line.startswith(b"error:"):
            self.replies_read += 1
            if self._unanswered:
                self._unanswered.pop(0)
            if self.replies_read == self.garbage_after:
                self._pending_noise = b"\x00\xff#garbage on the line\n"
            if kind == b"ok":
                self.oks_read += 1
                if self.oks_read == self.drop_reply:
                    return b""
        return line

    def close(self) -> None:
        self.port.close()

    def __getattr__(self, name):
        return getattr(self.port, name)
