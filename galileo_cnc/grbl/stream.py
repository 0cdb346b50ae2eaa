"""Streaming G-code to GRBL with character counting (interface.md).

GRBL's serial RX ring holds `rx_buffer_bytes - 1` bytes. The host keeps the
byte count of every line sent but not yet answered; a line goes out only when
it fits beside them, so the ring never overfills and GRBL always has the next
lines ready. Each `ok`/`error:N` answers the oldest line in flight: GRBL
replies in order, one reply per line. Real-time `?` bytes never enter the ring.

Liveness (link.StatusWatch): a line's `ok` may take as long as the moves ahead of
it (GRBL withholds it while its planner is full), so silence on the lines says
nothing. `?` is asked a few times a second and the board is alive while it answers;
no report for a few seconds stops the stream with GrblSilentError, whose `acked`
counts the lines GRBL confirmed, so a journal resumes after the last of them.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from galileo_cnc.grbl.gcode import GcodeLine
from galileo_cnc.grbl.link import STATUS_EVERY_S, GrblLink, Reply, StatusWatch
from galileo_cnc.grbl.reports import GrblError, Status, error_text
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


class GrblSilentError(GrblStreamError):
    """GRBL stopped answering status queries mid-job (powered off, cable out, a
    hung board): `silent_s` from its last report to the stop, `status` that report."""

    def __init__(self, message: str, errors: list[LineError], acked: int, *,
                 silent_s: float, status: Status | None):
        self.silent_s = silent_s
        self.status = status
        super().__init__(message, errors, acked)


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
           stop_on_error: bool = True, status_every_s: float | None = STATUS_EVERY_S,
           on_ack: Callable[[int, Reply], None] | None = None,
           wait_idle: bool = True, travel_check: bool = True,
           on_status: Callable[[Status], None] | None = None) -> StreamResult:
    """Sends `lines` with character counting; returns once every line is answered
    (and, with `wait_idle`, the machine has stopped). `where(command)` names the
    source file line of a job command for error messages. With `travel_check`,
    on a homed machine ($20 or $22) a job leaving the travel is refused
    (TravelError) before its first byte, from the position GRBL reports now.
    `?` is asked every `status_every_s` and each report handed to `on_status`
    (position, progress, ETA for a front end); a board that stops answering raises
    GrblSilentError. `status_every_s=None` asks nothing and gives up after the
    link's reply_timeout_s without a reply, as before the watch."""
    if travel_check and link.settings is not None and applies(link.settings):
        now = link.status()
        check_travel(lines, link.settings, link.tracker.wco_nm, now.mpos_nm, where=where)
    budget = link.rx_buffer_bytes - 1
    in_flight: deque[tuple[int, int]] = deque()      # (line index, bytes)
    used = 0
    result = StreamResult(lines=len(lines))
    next_line = 0
    stopping = False
    watch = StatusWatch(link, status_every_s, on_status) if status_every_s is not None \
        else None
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
        line = link.read_line() if watch is None else watch.read_line()
        if line is None:
            if watch is None:
                raise GrblStreamError(f"GRBL gave no reply within {link.reply_timeout_s:g} "
                                      f"s ({len(in_flight)} lines in flight)", result.errors,
                                      result.acked)
            fault = watch.fault(lines[in_flight[0][0]].text)
            if fault is not None:
                raise GrblSilentError(f"{fault}{_confirmed(where, lines, result.acked)}. "
                                      f"Once the board answers and stands still, "
                                      f"resume continues the job", result.errors,
                                      result.acked, silent_s=watch.silent_s(),
                                      status=watch.last)
            continue
        try:
            reply = link.classify(line) if watch is None else watch.classify(line)
        except GrblError as alarm:
            index = in_flight[0][0] if in_flight else next_line - 1
            raise GrblStreamError(
                f"{_place(where, lines, index)}{alarm} (at G-code line {index + 1} "
                f"{lines[index].text!r})", result.errors, result.acked,
                code=alarm.code, alarm=True) from None
        if line.startswith("<") and reply is not None:
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
        link.wait_idle(on_status)
    return result


def _place(where, lines, index) -> str:
    place = where(lines[index].command) if 0 <= index < len(lines) else ""
    return f"{place}: " if place else ""


def _confirmed(where, lines, acked: int) -> str:
    """`; the last line GRBL confirmed came from board.gbr:123` (a job's pieces are
    streamed one by one, so the file line names it, not a count), or ""."""
    place = where(lines[acked - 1].command) if acked > 0 else ""
    return f"; the last line GRBL confirmed came from {place}" if place else ""
