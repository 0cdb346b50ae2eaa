"""Streaming G-code to GRBL with character counting (interface.md).

GRBL's serial RX ring holds `rx_buffer_bytes - 1` bytes. The host keeps the
byte count of every line sent but not yet answered; a line goes out only when
it fits beside them, so the ring never overfills and GRBL always has the next
lines ready. Each `ok`/`error:N` answers the oldest line in flight: GRBL
replies in order, one reply per line. Real-time `?` bytes never enter the ring.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from galileo_cnc.grbl.gcode import GcodeLine
from galileo_cnc.grbl.link import STATUS_QUERY, GrblLink, Reply
from galileo_cnc.grbl.reports import GrblError, error_text
from galileo_cnc.grbl.travel import applies, check_travel


@dataclass(frozen=True, slots=True)
class LineError:
    index: int              # in the streamed lines
    line: GcodeLine
    code: int
    where: str              # "board.gbr:123", or "" when unknown

    def __str__(self) -> str:
        place = f"{self.where}: " if self.where else ""
        return f"{place}{error_text(self.code)} in G-code line {self.index + 1} {self.line.text!r}"


class GrblStreamError(GrblError):
    """Streaming stopped: a refused line or an alarm; `errors` lists every refusal."""

    def __init__(self, message: str, errors: list[LineError], acked: int, **kwargs):
        self.errors = errors
        self.acked = acked
        super().__init__(message, **kwargs)


@dataclass(slots=True)
class StreamResult:
    lines: int = 0
    acked: int = 0                          # lines GRBL answered (ok or error)
    errors: list[LineError] = field(default_factory=list)
    max_in_flight_bytes: int = 0            # never above rx_buffer_bytes - 1
    bytes_sent: int = 0
    statuses: int = 0


def stream(link: GrblLink, lines: Sequence[GcodeLine], *,
           where: Callable[[int], str] = lambda command: "",
           stop_on_error: bool = True, status_every_s: float | None = None,
           on_ack: Callable[[int, Reply], None] | None = None,
           wait_idle: bool = True, travel_check: bool = True) -> StreamResult:
    """Sends `lines` with character counting; returns once every line is answered
    (and, with `wait_idle`, the machine has stopped). `where(command)` names the
    source file line of a job command for error messages. With `travel_check`,
    on a homed machine ($20 or $22) a job leaving the travel is refused
    (TravelError) before its first byte, from the position GRBL reports now."""
    if travel_check and link.settings is not None and applies(link.settings):
        now = link.status()
        check_travel(lines, link.settings, link.tracker.wco_nm, now.mpos_nm, where=where)
    budget = link.rx_buffer_bytes - 1
    in_flight: deque[tuple[int, int]] = deque()      # (line index, bytes)
    used = 0
    result = StreamResult(lines=len(lines))
    next_line = 0
    stopping = False
    last_status = time.monotonic()
    encoded = [(line.text + "\n").encode("ascii") for line in lines]
    for index, data in enumerate(encoded):
        if len(data) > budget:
            raise GrblError(f"G-code line {index + 1} is {len(data)} bytes, more than "
                            f"GRBL's RX buffer of {budget}: {lines[index].text!r}")
    while in_flight or (next_line < len(lines) and not stopping):
        while not stopping and next_line < len(lines) and \
                used + len(encoded[next_line]) <= budget:
            link.port.write(encoded[next_line])
            in_flight.append((next_line, len(encoded[next_line])))
            used += len(encoded[next_line])
            result.bytes_sent += len(encoded[next_line])
            next_line += 1
        result.max_in_flight_bytes = max(result.max_in_flight_bytes, used)
        if status_every_s is not None and time.monotonic() - last_status >= status_every_s:
            link.realtime(STATUS_QUERY)
            last_status = time.monotonic()
        line = link.read_line()
        if line is None:
            raise GrblStreamError(f"GRBL gave no reply within {link.reply_timeout_s:g} s "
                                  f"({len(in_flight)} lines in flight)", result.errors,
                                  result.acked)
        try:
            reply = link.classify(line)
        except GrblError as alarm:
            index = in_flight[0][0] if in_flight else next_line - 1
            raise GrblStreamError(
                f"{_place(where, lines, index)}{alarm} (at G-code line {index + 1} "
                f"{lines[index].text!r})", result.errors, result.acked,
                code=alarm.code, alarm=True) from None
        if line.startswith("<"):
            result.statuses += 1
        if not isinstance(reply, Reply):
            continue
        if not in_flight:
            raise GrblError(f"GRBL replied {line!r} to no line")
        index, size = in_flight.popleft()
        used -= size
        result.acked += 1
        if on_ack is not None:
            on_ack(index, reply)
        if not reply.ok:
            result.errors.append(LineError(index, lines[index], reply.code,
                                           where(lines[index].command)))
            stopping = stopping or stop_on_error
    if result.errors and stop_on_error:
        raise GrblStreamError("GRBL refused a line: " + str(result.errors[0]), result.errors,
                              result.acked, code=result.errors[0].code)
    if wait_idle:
        link.wait_idle()
    return result


def _place(where, lines, index) -> str:
    place = where(lines[index].command) if 0 <= index < len(lines) else ""
    return f"{place}: " if place else ""
