"""The simavr harness (firmware/harness) against its own test firmware.

Real components only: `make -C firmware/harness` builds galileo-simavr and
testfw.elf, the harness runs the ELF in simavr, and the tests talk to it with
pyserial over the pseudo-terminal. testfw's modes are described at the top of
firmware/harness/testfw/testfw.c.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import serial

from galileo_cnc.simavr import board as simavr
from galileo_cnc.simavr.board import SimulatedBoard, step_trace
from galileo_cnc.simavr.build_lock import build_lock

from firmware_support import REPO

HARNESS_DIR = REPO / "firmware" / "harness"
TESTFW = HARNESS_DIR / "build" / "testfw" / "testfw.elf"
BAUD = 115200
# The Arduino core's 115200 setting: U2X with UBRR 16, i.e. 136 cycles a bit.
FRAME_CYCLES = 10 * 136           # 1360: 117 647 baud on the wire
NOMINAL_FRAME_CYCLES = 10 * 16e6 / BAUD  # 1388.9 at exactly 115 200 baud
SIMAVR_FRAME_CYCLES = 11 * 136    # 1496: simavr 1.6 counts a parity bit
TOGGLES, TOGGLE_CYCLES = 20, 1000


@pytest.fixture(scope="session")
def built():
    missing = simavr.missing_debian_packages(simavr.HARNESS_PACKAGES + simavr.TESTFW_PACKAGES)
    if missing:
        message = f"missing Debian packages: {' '.join(missing)}"
        if os.environ.get("CI"):
            pytest.fail(message)
        pytest.skip(message)
    with build_lock(HARNESS_DIR):       # pytest-xdist: another worker may be building
        result = subprocess.run(["make", "-C", str(HARNESS_DIR)], capture_output=True,
                                text=True)
    assert result.returncode == 0, result.stdout + result.stderr
    assert simavr.harness_available()
    return TESTFW


def open_port(board: SimulatedBoard) -> serial.Serial:
    # Generous: reads return as soon as the bytes are there; only a failure waits.
    port = serial.Serial(board.port, BAUD, timeout=30)
    assert port.readline() == b"testfw\n"
    return port


def read_exactly(port: serial.Serial, count: int) -> bytes:
    data = port.read(count)
    assert len(data) == count, f"got {len(data)} of {count} bytes"
    return data


# -- the UART bridge ---------------------------------------------------------

def test_echo_round_trip_loses_nothing(built):
    rng = np.random.default_rng(4)
    burst = rng.integers(0, 256, 1500, dtype=np.uint8).tobytes()  # >> 64-byte RX buffers
    with SimulatedBoard(built) as board:
        with open_port(board) as port:
            port.write(b"E")
            every_value = bytes(range(256))
            port.write(every_value)
            assert read_exactly(port, 256) == every_value
            port.write(burst)
            assert read_exactly(port, len(burst)) == burst
            lines = (b"G1 X10 Y20*71\n", b"\r\n", b"M2\r")  # no CR/LF rewriting
            for line in lines:
                port.write(line)
                assert read_exactly(port, len(line)) == line
        board.stop()
    assert int(board.summary["rx"]) == 1 + 256 + len(burst) + sum(map(len, lines))
    assert board.summary["overruns"] == "0"


def test_busy_firmware_gets_every_byte_and_the_overruns_are_reported(built):
    """testfw ignores the UART for 200 frame times: the bytes wait in the
    harness (none lost), and the summary counts what a real 328p would have
    dropped."""
    data = bytes(range(32, 127)) * 3
    with SimulatedBoard(built) as board:
        with open_port(board) as port:
            port.write(b"B" + data)
            assert read_exactly(port, len(data)) == data
        board.stop()
    assert int(board.summary["overruns"]) > 0


def test_byte_timing_tx_and_rx(built):
    """One frame per 1360 cycles both ways, as on the wire; simavr's own
    timing (--simavr-uart-timing) gives 1496, 10 % slow."""
    measured = {}
    for extra, frame in (((), FRAME_CYCLES), (("--simavr-uart-timing",), SIMAVR_FRAME_CYCLES)):
        with SimulatedBoard(built, pins=[12], extra_args=extra) as board:
            with open_port(board) as port:
                port.write(b"T")  # 32 bytes from the UDRE interrupt, pin 12 at each
                assert port.readline() == b"U" * 32 + b"\n"
            board.stop()
        cycle, pin, _ = board.trace()
        tx_gaps = np.diff(cycle)
        assert len(tx_gaps) == 31 and (tx_gaps[1:] == frame).all(), tx_gaps

        with SimulatedBoard(built, pins=[12], extra_args=extra) as board:
            with open_port(board) as port:
                data = bytes(range(200))
                port.write(b"R" + data)  # RX interrupt toggles pin 12, echoes
                assert read_exactly(port, len(data)) == data
            board.stop()
        assert int(board.summary["frame"]) == frame
        cycle, _, _ = board.trace()
        rx_gaps = np.diff(cycle)
        assert len(rx_gaps) == 199
        # The host's bytes are fed one per frame; the ISR's latency varies by
        # a few cycles with the instruction it interrupts.
        assert np.median(rx_gaps) == frame
        assert abs(rx_gaps.mean() - frame) < 0.25 and rx_gaps.min() > frame - 40
        measured[frame] = rx_gaps.mean()
    effective_baud = 10 * simavr.F_CPU_HZ / measured[FRAME_CYCLES]
    assert abs(effective_baud - 117_647) < 50          # what a real Uno sends
    assert abs(FRAME_CYCLES / NOMINAL_FRAME_CYCLES - 1) < 0.025
    assert measured[SIMAVR_FRAME_CYCLES] / measured[FRAME_CYCLES] == pytest.approx(1.1, abs=0.001)


def test_stdio_bridge(built):
    result = subprocess.run(
        [str(simavr.harness_path()), "--stdio", "--max-seconds", "0.05", str(built)],
        input=b"Ehello\x00\xff\n", capture_output=True, timeout=20)
    assert result.returncode == 0, result.stderr
    assert result.stdout == b"testfw\nhello\x00\xff\n"
    assert b"stop: max-seconds" in result.stderr


def test_realtime_never_runs_ahead_of_the_wall_clock(built):
    started = time.monotonic()
    result = subprocess.run(
        [str(simavr.harness_path()), "--stdio", "--realtime", "--max-seconds", "0.2", str(built)],
        input=b"E", capture_output=True, timeout=20)
    assert result.returncode == 0 and b"stop: max-seconds" in result.stderr
    assert time.monotonic() - started >= 0.19  # a lower bound only: never faster


# -- the pin trace -------------------------------------------------------------

def test_trace_records_timer_toggles_at_exact_cycles(built):
    with SimulatedBoard(built) as board:
        open_port(board).close()
        board.stop()
    cycle, pin, level = board.trace()
    assert cycle.dtype == np.int64 and pin.dtype == np.int8 and level.dtype == np.int8
    assert (pin == 13).all() and len(pin) == TOGGLES
    assert (level == np.arange(1, TOGGLES + 1) % 2).all()   # low at reset, then toggles
    assert (np.diff(cycle) == TOGGLE_CYCLES).all()           # Timer1 CTC, OCR1A = 999, clk/1
    assert 0 < cycle[0] < 5 * TOGGLE_CYCLES


def test_traced_pins_can_be_chosen(built):
    with SimulatedBoard(built, pins=[12, 11]) as board:
        open_port(board).close()
        board.stop()
    assert len(board.trace()[0]) == 0  # the boot toggles are on pin 13 only


# -- end-stops -----------------------------------------------------------------

def steps_report(board: SimulatedBoard) -> bytes:
    with open_port(board) as port:
        port.write(b"S")
        return port.readline()


def test_endstops_follow_the_step_count(built):
    """X home (pin 7) trips at <= -5 steps, Y home (pin 6) at <= 3 steps.
    testfw: X 8 steps down then 8 up, Y 5 steps up, reading the home pin
    after every step."""
    with SimulatedBoard(built, endstops=[("X", 7, -5), "Y:6:3"]) as board:
        report = steps_report(board)
        board.stop()
    #                  X0  X at -1..-8   X at -7..0   Y0 Y at 1..5
    assert report == b"S" b"1" b"11110000" b"00011111" b"|" b"0" b"00011" b"\n"

    # Pin 13 is Z step too; testfw's boot toggles on it are not X/Y steps.
    tick, axis, direction = board.step_trace(simavr.DEFAULT_AXIS_PINS[:2])
    assert axis.tolist() == [0] * 16 + [1] * 5
    assert direction.tolist() == [-1] * 8 + [1] * 8 + [1] * 5
    assert (np.diff(tick) > 0).all()


def test_reset_restarts_the_firmware_with_the_head_where_it_stood(built):
    """SimulatedBoard.reset (the reset button): testfw boots again, the end-stops go on
    counting from where the head stood (Y at 5 after the first report), an open
    switch reads open at once after the reset, and the trace keeps one clock with a
    mark at the reset."""
    with SimulatedBoard(built, endstops=[("X", 7, -5), "Y:6:7"]) as board:
        with open_port(board) as port:
            port.write(b"S")
            first = port.readline()
            board.reset()
            assert port.readline() == b"testfw\n"
            port.write(b"S")
            second = port.readline()
        board.stop()
    #                  X0  X at -1..-8   X at -7..0   Y0 Y at 1..5 (closed up to 7)
    assert first == b"S" b"1" b"11110000" b"00011111" b"|" b"0" b"00000" b"\n"
    #                                                 Y0 Y at 6..10
    assert second == b"S" b"1" b"11110000" b"00011111" b"|" b"0" b"00111" b"\n"
    assert "resets=1" in board.log
    cycle, pin, level = board.trace()
    assert (np.diff(cycle) >= 0).all()
    mark = simavr.reset_cycles((cycle, pin, level))
    assert len(mark) == 1
    assert ((pin == 13) & (cycle < mark[0])).sum() >= TOGGLES        # boot toggles, then steps
    assert ((pin == 13) & (cycle > mark[0])).sum() >= TOGGLES        # and again after it


def test_a_board_whose_host_process_dies_stops_by_itself(built):
    """A killed test run (or console) must not leave a harness simulating on, a core
    busy for hours: SimulatedBoard passes --exit-with-parent."""
    host = subprocess.Popen(
        [sys.executable, "-c",
         "import sys, time\n"
         "from galileo_cnc.simavr.board import SimulatedBoard\n"
         f"board = SimulatedBoard({str(built)!r}, trace=False).start()\n"
         "print(board._process.pid, flush=True)\n"
         "time.sleep(120)\n"],
        stdout=subprocess.PIPE, text=True)
    harness = int(host.stdout.readline())
    assert running(harness)
    host.kill()
    host.wait()
    deadline = time.monotonic() + 10
    while running(harness) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not running(harness)


def running(pid: int) -> bool:
    """Alive and not a zombie (an orphan's zombie may wait for a reaper that never comes)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (FileNotFoundError, ProcessLookupError):
        return False


def test_home_pins_read_their_pull_ups_without_endstops(built):
    with SimulatedBoard(built) as board:
        report = steps_report(board)
    assert report == b"S1" + b"1" * 16 + b"|1" + b"1" * 5 + b"\n"


def test_step_trace_from_edges():
    # cycle, pin, level: X dir high written with the step in one instruction,
    # Y steps with its dir still low from reset, X/Y/Z stepping in one tick.
    edges = (np.array([10, 10, 20, 800, 801, 803, 805, 900], np.int64),
             np.array([10, 11, 11, 13, 9, 11, 12, 9], np.int8),
             np.array([1, 1, 0, 1, 1, 1, 1, 0], np.int8))
    tick, axis, direction = step_trace(edges)
    assert tick.tolist() == [1, 100, 100, 100]
    assert axis.tolist() == [0, 0, 1, 2]          # X, Y, Z within a tick
    assert direction.tolist() == [1, 1, -1, -1]   # Z's dir went high after its step


# -- Timer1 rules the firmware must follow (docs/harness.md) ---------------------

def test_timer1_quirks_of_simavr(built):
    with SimulatedBoard(built) as board:
        with open_port(board) as port:
            port.write(b"Q")
            fields = dict(item.split("=") for item in port.readline().decode().split()[1:])
    values = {key: int(value) for key, value in fields.items()}
    assert values["stopped"] == 404          # TCNT1 = 50000 while stopped: ignored
    assert 50_390 <= values["running"] <= 50_410
    assert values["ctc0"] == 0               # CTC, OCR1A = 0, clk/1: never fires
    assert values["ctc1"] > 500 and values["ctc0_8"] > 500


# -- how the harness stops --------------------------------------------------------

@pytest.mark.parametrize("mode, reason, code", [
    (b"H", "sleeping with interrupts off", 0),
    (b"X", "crashed", 3),
])
def test_firmware_end_is_reported(built, mode, reason, code):
    with SimulatedBoard(built) as board:
        with open_port(board) as port:
            port.write(mode)
            assert board.wait(timeout=10) == code
    assert board.summary["reason"] == reason
    assert "pc=" in board.log


def test_max_seconds_of_simulated_time(built):
    with SimulatedBoard(built, max_seconds=0.25) as board:
        serial.Serial(board.port, BAUD).close()  # the AVR leaves reset when the port opens
        assert board.wait(timeout=20) == 0
    assert board.summary["reason"] == "max-seconds"
    assert 4_000_000 <= int(board.summary["cycle"]) <= 4_000_000 + 4  # one instruction


# -- the stack's high-water mark ---------------------------------------------------

def test_stack_report(built):
    # testfw does not paint its SRAM, but simavr powers up with SRAM cleared:
    # 0x00 stands in for the paint (the plotter firmware's own, 0xC5, is
    # measured by tests/test_firmware_build.py).
    with SimulatedBoard(built, stack_paint=0x00) as board:
        with open_port(board) as port:
            port.write(b"T")                  # 32 bytes from the UDRE interrupt
            assert read_exactly(port, 33).endswith(b"\n")
        board.stop()
    stack = board.stack
    end = int(subprocess.run(["avr-nm", str(built)], capture_output=True, text=True,
                             check=True).stdout.split(" N _end")[0].split()[-1], 16) & 0xFFFF
    assert (stack["pattern"], stack["ram_start"], stack["ramend"]) == (0, 0x100, 0x8FF)
    assert stack["end"] == end and stack["static"] == end - 0x100
    # main's frame plus an interrupt's: a few dozen bytes, nothing below them written
    assert 4 < stack["peak"] <= stack["sp_peak"] < 64, stack
    assert stack["clobbered"] == 0
    assert stack["free"] == stack["lowest"] - stack["end"] == 0x900 - stack["peak"] - end
    assert board.stack_peak_bytes == stack["peak"]
    assert board.stack_free_bytes == stack["free"]


def test_bad_arguments_are_named(built):
    result = subprocess.run([str(simavr.harness_path()), "--endstop", "W:7:1", str(built)],
                            capture_output=True, text=True, timeout=10)
    assert result.returncode == 1 and "--endstop" in result.stderr
    result = subprocess.run([str(simavr.harness_path()), "--stack-paint", "0x1C5", str(built)],
                            capture_output=True, text=True, timeout=10)
    assert result.returncode == 1 and "--stack-paint" in result.stderr
    with pytest.raises(simavr.SimulatedBoardError, match="not found"):
        SimulatedBoard(HARNESS_DIR / "no-such.elf").start()


def test_missing_debian_packages_names_them(monkeypatch):
    monkeypatch.setitem(simavr._DEBIAN_MARKERS, "libsimavr-dev", "/nonexistent/sim_avr.h")
    assert "libsimavr-dev" in simavr.missing_debian_packages()
    assert simavr.missing_debian_packages(["libsimavr-dev", "make"]) in (
        ["libsimavr-dev"], ["libsimavr-dev", "make"])
