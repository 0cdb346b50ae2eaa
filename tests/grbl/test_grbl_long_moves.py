"""Liveness on stock GRBL 1.1h in simavr: a line's `ok` may take as long as the moves
ahead of it, so the stream asks `?` a few times a second and judges the board by
those answers (link.StatusWatch).

- A move longer than any fixed timeout (180 mm at 5 mm/s: 36 s) then 40 short lines,
  plotted with `galileo-cnc plot` over `simavr://?firmware=grbl` in real time, runs
  to its last line and ends exactly on its last point (GRBL's status, its pins).
- A board frozen mid-job (SIGSTOP to the simulator: the pty stays open, nothing
  answers) is reported within 5 s of its last status answer, and `plot --resume`
  finishes the job on its last point.
- The rule itself, on short moves (paced to the wall clock: free-running simavr is
  faster than a board, or slower on a loaded host): `?` goes out while a line's `ok`
  is held back behind a long move, and a frozen board stops the stream with `acked`
  equal to the lines GRBL confirmed."""

from __future__ import annotations

import re
import threading
import time

import serial

from galileo_cnc.cli import main as cli
from galileo_cnc.config.profile import load_profile
from galileo_cnc.config.userdirs import data_dir
from galileo_cnc.grbl.gcode import GcodeLine, expected_end_steps, job_to_gcode, pen_from_config
from galileo_cnc.grbl.link import STATUS_QUERY, STATUS_SILENCE_S, GrblLink, position_mm
from galileo_cnc.grbl.stream import GrblSilentError, stream
from galileo_cnc.machine.trace import Trace
from galileo_cnc.plan.pipeline import PlanOptions, plan_file
from galileo_cnc.stream.journal import FAILED, FINISHED, Journal

from grbl_support import (PROFILE, SCALE, SETTINGS, check_trace, grbl_elf, grbl_machine,
                          wait_until_still)

MM = 1_000_000          # nm
STEP_NM = 6250          # 160 steps/mm
#: the product's rule: a board that stops answering is reported within this
REPORTED_WITHIN_S = 5.0


class CountingPort:
    """The link's pyserial port, passed through, counting the `?` bytes written."""

    def __init__(self, port):
        self.port = port
        self.queries = 0

    def write(self, data: bytes) -> int:
        self.queries += data.count(STATUS_QUERY)
        return self.port.write(data)

    def __getattr__(self, name):
        return getattr(self.port, name)


def back_and_forth(start_mm: float, end_mm: float, feed: int, short: int) -> list[GcodeLine]:
    """One long line at `feed` mm/min, then `short` lines of 0.05 mm zig-zag."""
    step = 0.05 if end_mm < start_mm else -0.05
    texts = ["G21 G90 G94", f"G1 X{start_mm:g} Y0 F{feed}", f"G1 X{end_mm:g}"]
    texts += [f"G1 X{end_mm + step * (i + 1):.2f} Y{0.05 * ((i + 1) % 2):.2f}"
              for i in range(short)]
    return [GcodeLine(text, i) for i, text in enumerate(texts)]


def test_status_is_asked_while_an_ok_waits_and_a_silent_board_is_named():
    with grbl_machine(realtime=True) as (board, link):
        port = CountingPort(link.port)
        link.port = port
        # alive: the long line's successors wait for the planner; `?` keeps coming
        lines = back_and_forth(0, 20, 600, 30)     # 2 s, then 30 short
        acks: list[int] = []
        seen: list[tuple[int, str, int]] = []      # (lines acked, state, x nm)
        result = stream(link, lines, travel_check=False,
                        on_ack=lambda index, reply: acks.append(index),
                        on_status=lambda s: seen.append((len(acks), s.state, s.mpos_nm[0])))
        assert result.acked == len(lines) and acks == list(range(len(lines)))
        assert link.tracker.last.mpos_nm[:2] == (18_500_000, 0)     # 20 - 30 * 0.05
        # one ok held back over many status rounds, GRBL running the long line meanwhile
        waits = {}
        for acked, state, x in seen:
            waits.setdefault(acked, []).append((state, x))
        held, during = max(waits.items(), key=lambda item: len(item[1]))
        assert 2 < held < len(lines) and len(during) >= 5, waits
        running = [x for state, x in during if state == "Run"]
        assert len(running) >= 3 and running == sorted(running) and running[0] < running[-1]
        assert port.queries >= len(seen) >= result.statuses >= 5

        # silent: frozen in the middle of the way back
        acks.clear()
        frozen: list[float] = []

        def freeze_half_way(status) -> None:
            if not frozen and status.state == "Run" and status.mpos_nm[0] < 12 * MM:
                board.freeze()
                frozen.append(time.monotonic())

        back = back_and_forth(20, 0, 600, 30)
        try:
            stream(link, back, travel_check=False,
                   on_ack=lambda index, reply: acks.append(index), on_status=freeze_half_way)
        except GrblSilentError as silent:
            stopped = silent
        else:
            raise AssertionError("a frozen board was not noticed")
        took = time.monotonic() - frozen[0]
        board.thaw()
        board.stop()
    print(f"silent board reported {stopped.silent_s:.2f} s after its last status answer, "
          f"{took:.2f} s after the freeze")
    assert stopped.acked == len(acks) < len(back) and not stopped.alarm
    assert STATUS_SILENCE_S <= stopped.silent_s <= REPORTED_WITHIN_S
    assert stopped.status.state == "Run" and 0 < stopped.status.mpos_nm[0] < 12 * MM
    text = str(stopped)
    assert text.startswith(f"GRBL gave no answer to status queries for {stopped.silent_s:.1f} s")
    assert f"last reported at {position_mm(stopped.status)}" in text
    assert f"{len(acks)} of {len(back)} lines confirmed" in text and "resume continues" in text
