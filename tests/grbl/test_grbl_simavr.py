"""Stock GRBL 1.1h, built from ../shared/grbl-1.1h with its own Makefile, running
in our simavr harness: detected, settings read, jobs streamed with character
counting, every end point exact under GRBL's own mm->steps rounding (from the
pin trace), every step within one step of the path, errors named by file line."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from galileo_cnc import job as J
from galileo_cnc.grbl import firmware
from galileo_cnc.grbl.estimate import Machine
from galileo_cnc.grbl.gcode import GcodeLine, job_to_gcode, pen_from_config, source_of
from galileo_cnc.grbl.link import GrblLink
from galileo_cnc.grbl.reports import Status
from galileo_cnc.grbl.stream import GrblStreamError, StreamResult, stream
from galileo_cnc.plan.pipeline import PlanOptions, plan_file
from galileo_cnc.simavr.board import SimulatedBoard

from corpus import CORPUS
from grbl_support import (CONFIG, ESTIMATE_TOLERANCE, QUICK_ACCEL, SCALE, SETTINGS,
                          check_trace, estimate_and_pins, grbl_elf, grbl_machine, positions)

REPO = Path(__file__).resolve().parents[2]
CORPUS_BOARD = "kicad/flashpads-nox2noap/Flashpads-B_Cu.gbr"   # traces, pads, 32 arcs


def gcode_for(planned):
    return job_to_gcode(planned.job, SCALE, pen_from_config(CONFIG),
                        feed_steps_per_s=CONFIG.feed_steps_per_s,
                        flash_dwell_ms=CONFIG.flash_dwell_ms)


def run_and_check(lines, where=lambda command: "", run=None):
    """Streams `lines` to a fresh GRBL (or takes `run`, a GrblRun of them) and checks
    the pins: every end point exact, every step within one step of its path."""
    run = run or stream_to_grbl(lines, where)
    board, link, result, final = run.board, run.link, run.result, run.final
    assert result.errors == [] and link.alarms == []
    assert result.acked == len(lines)
    assert result.max_in_flight_bytes <= link.rx_buffer_bytes - 1
    assert board.summary["overruns"] == "0" and board.summary["dropped"] == "0"
    pos = positions(board)
    checked = check_trace(pos, lines)
    assert final.state == "Idle"
    # GRBL reports mm with 3 decimals: the pins' position, rounded to a micrometre
    assert all(abs(m - int(v) * 6250) <= 500 for m, v in zip(final.mpos_nm, pos[-1]))
    return result, checked


@dataclass
class GrblRun:
    """One job streamed to GRBL in simavr, for the tests that look at the same run."""
    board: SimulatedBoard
    link: GrblLink
    result: StreamResult
    final: Status           # GRBL's last status report, at rest after the job
    model: Machine          # the estimate's machine, from GRBL's $$ and $I


def stream_to_grbl(lines, where=lambda command: "") -> GrblRun:
    with grbl_machine() as (board, link):
        model = Machine.from_settings(link.settings, link.build.planner_blocks)
        result = stream(link, lines, where=where, status_every_s=0.05)
        final = link.tracker.last
        board.stop()
    return GrblRun(board, link, result, final, model)


def test_grbl_builds_boots_and_is_detected():
    elf = grbl_elf()
    size = (elf.parent / "size.txt").read_text().split()
    assert int(size[0]) + int(size[1]) <= 32 * 1024 - 512      # fits an Uno with its boot loader
    with grbl_machine() as (board, link):
        assert link.version == "1.1h"
        # simavr's EEPROM starts empty: GRBL says so and restores its defaults
        assert link.boot_lines[0] == "error:7" and "$100=250.000" in link.boot_lines
        assert link.build.version == "1.1h.20190830" and "V" in link.build.options
        assert (link.build.planner_blocks, link.rx_buffer_bytes) == (15, 128)
        s = link.settings
        assert [s.steps_per_mm_text(a) for a in range(3)] == ["160.000"] * 3
        assert s.max_rate_mm_min(0) == "8000.000" and s.accel_mm_s2(2) == "2000.000"
        assert not s.soft_limits and not s.homing
        assert [s.max_travel_nm(a) for a in range(3)] == [200_000_000] * 3
        status = link.status()
        assert status.state == "Idle" and status.mpos_nm == (0, 0, 0)
        assert status.wco_nm == (0, 0, 0)        # the first report after a reset has WCO
        board.stop()
    assert board.summary["reason"] == "Terminated"


def test_small_job_lands_on_every_step():
    job = J.Job(source="test", offset_nm=(0, 0))
    commands = [J.Rapid(800, 800), J.PenDown(), J.SetFeed(12000)]
    # lines in all eight octants, pure X and pure Y, both signs
    for dx, dy in [(803, 311), (311, 803), (-311, 803), (-803, 311), (-803, -311),
                   (-311, -803), (311, -803), (803, -311), (500, 0), (0, 500), (-500, 0),
                   (0, -500)]:
        commands.append(J.LineTo(800 + dx, 800 + dy))
        commands.append(J.LineTo(800, 800))
    commands += [J.ArcTo(1600, 800, 400, 0, cw=True), J.ArcTo(800, 800, -400, 0, cw=False),
                 J.ArcTo(800, 800, 317, -201, cw=True),          # a full circle
                 J.Flash(), J.Dwell(30), J.LineTo(900, 900, 40), J.EndJob()]
    for c in commands:
        job.add(c, J.NO_OP, 0)
    lines = job_to_gcode(job, SCALE, pen_from_config(CONFIG), feed_steps_per_s=8000,
                         flash_dwell_ms=20)
    result, checked = run_and_check(lines)
    assert checked["motions"] == sum(line.text.split()[0] in ("G0", "G1", "G2", "G3")
                                     for line in lines)
    assert checked["worst_axis_steps"] <= 1.0


@pytest.fixture(scope="module")
def corpus_board():
    """(lines, GrblRun): the corpus board streamed once (27 s of machine time) for the
    two tests that look at that run: its pins exact, and the time estimate."""
    planned = plan_file(CORPUS / CORPUS_BOARD, CONFIG, options=PlanOptions(mode="centre"))
    lines = gcode_for(planned)
    return lines, stream_to_grbl(lines, lambda c: source_of(planned.plotted, planned.job, c))


def test_corpus_board_streamed_exactly(corpus_board):
    lines, run = corpus_board
    assert sum(line.text.startswith(("G2 ", "G3 ")) for line in lines) >= 30
    result, checked = run_and_check(lines, run=run)
    assert checked["motions"] > 400
    # character counting kept the ring nearly full: GRBL was never starved by us
    assert result.max_in_flight_bytes >= 100


def test_estimate_matches_grbl_in_simavr_corpus_board(corpus_board):
    """The estimate within ESTIMATE_TOLERANCE of the corpus board's run, first step to last
    (test_grbl_estimate.py's small job is the other measure)."""
    lines, run = corpus_board
    assert run.result.errors == [] and run.link.alarms == []
    model, sim = estimate_and_pins(lines, run.model, run.board.trace())
    print(f"{CORPUS_BOARD}: estimate {model:.4f} s, simavr {sim:.4f} s, "
          f"ratio {model / sim:.4f}")
    assert abs(model / sim - 1) <= ESTIMATE_TOLERANCE


def test_error_named_with_grbl_text_and_file_line():
    planned = plan_file(REPO / "samples" / "led-blinker.gbr", CONFIG,
                        options=PlanOptions(mode="centre"))
    lines = gcode_for(planned)
    first = next(i for i, line in enumerate(lines) if line.text.startswith("G1 X"))
    # the preamble and pen lift, then from the travel before the first drawn line to 20
    # lines past it: more than GRBL's 128-byte buffer holds behind the bad line, without
    # the 40 lines of pads before it and the job's rest (6 s of machine time, two runs)
    lines = lines[:2] + lines[first - 3:first + 20]
    bad = next(i for i, line in enumerate(lines) if line.text.startswith("G1 X"))
    lines[bad] = GcodeLine("G5 " + lines[bad].text[3:], lines[bad].command)  # G5: not GRBL's
    place = source_of(planned.plotted, planned.job, lines[bad].command)
    assert place.startswith(str(REPO / "samples" / "led-blinker.gbr") + ":")
    where = lambda c: source_of(planned.plotted, planned.job, c)   # noqa: E731
    with grbl_machine({**SETTINGS, **QUICK_ACCEL}) as (board, link):
        with pytest.raises(GrblStreamError) as raised:
            stream(link, lines, where=where)
        # the lines already in GRBL's buffer were answered; then it stopped sending
        assert raised.value.acked < len(lines)
        [error] = raised.value.errors
        assert error.index == bad and error.code == 20
        message = str(raised.value)
        assert f"{place}: error:20: Unsupported command" in message
        assert f"G-code line {bad + 1} " in message
        # with stop_on_error=False every line is answered, the rest of the job runs
        link.command_checked("G0 X0 Y0 Z0")
        result = stream(link, lines, where=where, stop_on_error=False)
        assert result.acked == len(lines) and [e.index for e in result.errors] == [bad]
        board.stop()
    assert board.summary["overruns"] == "0"


def test_simavr_timer_quirks_are_what_the_harness_corrects():
    """Without --ocr1a-at-start GRBL never steps; without --replay-tcnt0 its step
    pulses last 256 Timer0 ticks instead of $0 = 10 us."""
    elf = grbl_elf()
    def pulse_widths(extra_args, stalls=False):
        with SimulatedBoard(elf, pins=firmware.TRACE_PINS, extra_args=extra_args) as board:
            import serial
            from galileo_cnc.grbl.link import GrblLink
            port = serial.Serial(board.port, 115200, timeout=0.2)
            link = GrblLink.connect(port)
            link.command_checked("G1 X2 F3000")
            if stalls:      # it never moves: ask a while, then look at the pins
                for _ in range(30):
                    assert link.status().mpos_nm == (0, 0, 0)
            else:
                link.wait_idle()
            port.close()
            board.stop()
        cycle, pin, level = board.trace()
        x = pin == firmware.AXIS_PINS[0][0]
        c, lv = cycle[x].astype(np.int64), level[x]
        rises = c[lv == 1]
        falls = c[lv == 0]
        return falls[:len(rises)] - rises[:len(falls)]
    stalled = pulse_widths(["--axis-pins", "X:2:5,Y:3:6,Z:4:7", "--replay-tcnt0"], stalls=True)
    assert len(stalled) == 0
    merged = pulse_widths(["--axis-pins", "X:2:5,Y:3:6,Z:4:7", "--ocr1a-at-start", "16"])
    fixed = pulse_widths(list(firmware.HARNESS_ARGS))
    assert len(fixed) == 2 * 250                 # 2 mm at GRBL's default 250 steps/mm
    # 256 ticks at clk/8 = 2048 cycles (+ latency): above 7.7 kHz that is longer
    # than the step period, and pulses merge (this slow move stays below it)
    assert 2048 <= np.median(merged) <= 2200
    assert 140 <= fixed.min() and fixed.max() <= 260     # 10 us = 160 cycles, + ISR latency


def test_grbl_homing_finds_each_switch_on_the_very_step_it_closes():
    """The harness's switches close on GRBL's trip step for every axis, so homing
    puts GRBL's machine zero exactly `trip - $27` from power-up on the pins. Until
    the harness gave every end-stop its --axis-pins before driving any home pin,
    X's switch (D9, our firmware's Y step pin) being set open at power-up counted as
    a Y step: Y's switch closed at 479, and the console's session found GRBL's Y one
    step off its pins after homing."""
    from galileo_cnc.grbl.jog import home
    limits = (("X", 320), ("Y", 480), ("Z", 160))       # switches at +2, +3, +1 mm
    # 20 ms of debounce ($26), not 250: waited after a switch closes, it moves nothing
    settings = {22: "1", 25: "1000", 24: "200", 26: "20", 130: "50", 131: "50", 132: "10"}
    with grbl_machine({**SETTINGS, **settings}, limits=limits) as (board, link):
        status = home(link)
        board.stop()
    assert status.mpos_nm == (-1_000_000,) * 3          # $27 = 1 mm off the switches
    pos = positions(board)
    # Z alone first, then X and Y together: each seek stops on its trip step
    # (positions() rows are one per step interrupt: a run ends where the axis turns)
    for axis, trip in enumerate(t for _, t in limits):
        moves = np.diff(pos[:, axis])
        moves = moves[moves != 0]
        turn = int(np.argmax(moves < 0))
        assert turn == trip, ("XYZ"[axis], turn, trip)
    # GRBL's machine position (-1 mm) is the pins' trip point less 1 mm, on every axis
    assert tuple(int(v) for v in pos[-1]) == tuple(t - 160 for _, t in limits)


class GarblingPort:
    """GRBL's port with its next `garble` status reports damaged in the MPos field (a
    byte lost on the cable), everything else passed through."""

    def __init__(self, port, garble: int):
        self.port, self.garble = port, garble

    def readline(self, *args) -> bytes:
        line = self.port.readline(*args)
        if self.garble and b"MPos:" in line:
            self.garble -= 1
            line = line.replace(b"MPos:", b"MPos:x", 1)
        return line

    def __getattr__(self, name):
        return getattr(self.port, name)


def test_one_garbled_status_report_is_asked_for_again_two_are_an_error():
    from galileo_cnc.grbl.reports import GrblError

    with grbl_machine() as (_board, link):
        link.port = GarblingPort(link.port, garble=1)
        status = link.status()
        assert status.state == "Idle" and status.mpos_nm == (0, 0, 0)
        link.port = GarblingPort(link.port.port, garble=2)
        with pytest.raises(GrblError, match="bad 'MPos' field"):
            link.status()
