"""The firmware in simavr: step rate, cycles per step event, lines per second.

    python bench/bench_firmware.py [--quick]

Everything is measured in simulated cycles (16 MHz) with galileo-simavr's pin
trace (docs/harness.md); nothing here is asserted by a test.

(a) Step rate. The stock configuration caps the path feed at 40 000 steps/s,
    so a diagonal (two-axis) line runs at most 40 000 / sqrt(2) = 28 284 events
    per second. To drive two-axis events faster and to keep ramps short, the
    bench builds a variant of the firmware in a temporary copy of firmware/
    (same code, config.h regenerated from MachineConfig with
    min_step_period_ticks = 34 and accel_mm_s2 = 25 000: F_MAX = 58 823 steps/s,
    so diagonals reach 41 600 events/s, and ramps of < 2 000 events; the copy's
    planner computes R = ceil(2 F^2 / A) in 64 bits, as 2 F^2 passes 2^32 above
    46 340 steps/s). Each feed runs one line on a fresh board; it
    passes when the firmware's step trace equals the reference machine's (same
    config) within 2 ticks and no `msg:13` (overrun) came back. The bench
    prints the highest passing feed as an event rate.

    Cycles per step event come from the variant's PROFILE=1 build: Uno pin A0
    (14) is high while the interrupt computes an event. Per event:
    entry (interrupt response + vector jmp + stub up to the step edge, 11
    cycles, a constant) + step edge -> A0 rise (measured: stub rest, jmp,
    prologue) + A0 high (measured) + A0 fall -> reti (counted in the ELF's
    disassembly: epilogue).

(b) Lines per second at 115 200 baud, GRBL-style: short moves (`L 1 0` /
    `L 0 0`) at a feed (STREAM_FEED) where each move, ramp included, executes
    in less time than its line takes on the wire and with block changes far
    above the interrupt's cost, so the rate measured is the streaming path's
    (UART, checks, parse, planner, reply), not motion time and not overrun
    reports. (At F 40 000 a one-step move lasts 50 ticks = 400 cycles, less
    than the interrupt's block change: every move overran and its 46-byte
    `msg:13` on the polled TX line throttled the stream to ~190 lines/s.)
    Wire limit = 11 765 bytes/s (UBRR0 16 with U2X: 1360 cycles a byte) /
    average line bytes.

    Two measurements: (1) the harness runs in real time (--realtime) for two
    durations (--max-seconds) while the host streams with character counting;
    the replies' difference over the duration difference is the rate (it
    cancels start-up). (2) Cycle-accurate, from the PROFILE=1 build of the
    stock firmware: Uno pin A1 is high while the main loop handles one line
    (checks, parse, planner, reply queued) and A2 while the planner runs; the
    pin trace gives the main loop's cycles per line (interrupts included)
    and the steady-state cycles between lines, against 1360 x line bytes.
"""

from __future__ import annotations

import argparse
import math
import re
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "tests"))

import numpy as np  # noqa: E402

from galileo_cnc import protocol as P  # noqa: E402
from galileo_cnc.config.machine import MachineConfig  # noqa: E402
from galileo_cnc.job import LineTo, SetFeed
from galileo_cnc.machine import simulate  # noqa: E402
from galileo_cnc.simavr.board import SimulatedBoard, harness_available, step_trace  # noqa: E402

F_CPU = 16_000_000
WIRE_BYTES_PER_S = F_CPU / 1360          # 11 765: docs/harness.md
TARGET_2AXIS_HZ = 40_000
TARGET_WIRE_FRACTION = 0.95
GRBL_2AXIS_HZ = 37_500
A0 = 14
A1, A2 = 15, 16                         # PROFILE=1: line handling, planner (commands.cpp)
STREAM_FEED = 10_000                    # (b): a 1-step move executes in 590 ticks
ENTRY_BEFORE_EDGE = 4 + 3 + 2 + 2       # IRQ response, vector jmp, push r24, lds
VARIANT = dict(min_step_period_ticks=34, accel_mm_s2=25_000.0)


def log(msg: str) -> None:
    print(msg, flush=True)


# -- builds -------------------------------------------------------------------

def build_variant(workdir: Path) -> tuple[Path, Path, MachineConfig]:
    """firmware/ copied with the bench's config.h; (elf, profile elf, config)."""
    config = MachineConfig().replace(**VARIANT)
    fw = workdir / "firmware"
    fw.mkdir()
    shutil.copy(REPO / "firmware" / "Makefile", fw / "Makefile")
    shutil.copytree(REPO / "firmware" / "galileo", fw / "galileo")
    toml = workdir / "bench.toml"
    toml.write_text(config.to_toml())
    subprocess.run([sys.executable, "-m", "galileo_cnc.firmware_headers", "--out",
                    str(fw / "galileo"), "--config", str(toml)],
                   cwd=REPO, check=True, stdout=subprocess.DEVNULL)
    for extra in ([], ["PROFILE=1"]):
        result = subprocess.run(["make", "-j4", "-C", str(fw)] + extra,
                                capture_output=True, text=True)
        if result.returncode:
            sys.exit(result.stdout[-2000:] + result.stderr[-2000:])
    return fw / "build-uno" / "galileo.elf", fw / "build-uno-profile" / "galileo.elf", config


# -- (a) step rate --------------------------------------------------------------

def run_line(elf: Path, commands, pins=None):
    from firmware_support import FirmwareLink
    with SimulatedBoard(elf, pins=pins) as board:
        link = FirmwareLink(board.port)
        try:
            replies = link.stream(commands)
            link.wait_idle()
            unsolicited = list(link.unsolicited)
        finally:
            link.close()
        board.stop()
        edges = board.trace()
    return edges, replies, unsolicited


def rate_point(elf: Path, config: MachineConfig, feed: int, n: int, diagonal: bool):
    target = LineTo(n, n) if diagonal else LineTo(n, 0)
    commands = [SetFeed(feed), target]
    ref = simulate(commands, config)
    edges, replies, unsolicited = run_line(elf, commands)
    tick, axis, direction = step_trace(edges)
    overrun = any(u.kind == "msg" for u in unsolicited) or any(r.kind != "ok" for r in replies)
    same = (len(tick) == len(ref.tick) and np.array_equal(axis, ref.axis)
            and np.array_equal(direction, ref.dir))
    spread = int(np.ptp(tick - ref.tick)) if same and len(tick) else -1
    x_ref = np.diff(ref.tick[ref.axis == 0])
    x_fw = np.diff(tick[axis == 0])
    commanded = int(x_ref.min()) if len(x_ref) else 0
    traced = int(x_fw.min()) if len(x_fw) else 0
    ok = same and 0 <= spread <= 2 and not overrun
    return ok, commanded, traced, spread, overrun


def sweep(elf: Path, config: MachineConfig, diagonal: bool, rates, n: int):
    best = None
    for rate in rates:
        feed = round(rate * math.sqrt(2)) if diagonal else rate
        if feed > config.max_feed_steps_per_s:
            continue
        ok, commanded, traced, spread, overrun = rate_point(elf, config, feed, n, diagonal)
        ev_hz = 2_000_000 / commanded if commanded else 0
        log(f"  feed {feed:6d} steps/s: events {ev_hz:8.0f}/s, min interval commanded "
            f"{commanded} ticks, traced {traced}; spread {spread} ticks"
            f"{', msg:13' if overrun else ''} -> {'ok' if ok else 'CLAMPED'}")
        if ok:
            best = ev_hz
        else:
            break
    return best


def exit_cycles(elf: Path) -> int:
    """Cycles from the `cbi PORTC,0` (A0 low) of the line-event body to its reti:
    stepper_fast_isr where the firmware has one, else stepper_event_isr."""
    dis = subprocess.run(["avr-objdump", "-d", str(elf)], capture_output=True, text=True).stdout
    name = "<stepper_fast_isr>:" if "<stepper_fast_isr>:" in dis else "<stepper_event_isr>:"
    body = dis.split(name, 1)[1]
    body = body.split("reti", 1)[0] + "reti"
    lines = [ln for ln in body.splitlines() if re.match(r"\s+[0-9a-f]+:\t", ln)]
    ops = [ln.split("\t")[2].split()[0] if len(ln.split("\t")) > 2 else "" for ln in lines]
    cbi = max(i for i, ln in enumerate(lines) if "cbi\t0x08, 0" in ln)
    cost = {"pop": 2, "push": 2, "reti": 4, "lds": 2, "sts": 2, "ld": 2, "st": 2, "rjmp": 2}
    total = 0
    for op in ops[cbi:]:
        total += cost.get(op, 1)
        if op == "reti":
            break
    return total


def isr_cycles(profile_elf: Path, feed: int, n: int, diagonal: bool):
    target = LineTo(n, n) if diagonal else LineTo(n, 0)
    edges, _, _ = run_line(profile_elf, [SetFeed(feed), target], pins=[8, 9, 10, 11, 12, 13, A0])
    cycle, pin, level = edges
    step = cycle[((pin == 11) | (pin == 9)) & (level == 1)]
    rise = cycle[(pin == A0) & (level == 1)]
    fall = cycle[(pin == A0) & (level == 0)]
    k = min(len(rise), len(fall))
    rise, fall = rise[:k], fall[:k]
    high = fall - rise
    # the step edge of the same interrupt: the last one before the A0 rise
    idx = np.searchsorted(step, rise) - 1
    valid = idx >= 0
    entry = rise[valid] - step[idx[valid]]
    entry = entry[entry < 200]           # events that stepped
    # skip the run's first and last events (start/end of block paths)
    core = high[2:-2]
    return core, entry


# -- (b) lines per second ---------------------------------------------------------

def stream_for(elf: Path, lines: list[bytes], seconds: float, pins=None):
    """Replies (and unsolicited `msg:` lines) received while the board runs
    `seconds` of simulated time in real time; with `pins`, also the pin trace."""
    import serial
    board = SimulatedBoard(elf, trace=pins is not None, pins=pins, max_seconds=seconds,
                           realtime=True)
    board.start()
    try:
        port = serial.Serial(board.port, 115200, timeout=0.5)
        assert P.parse_reply(port.readline()).kind == "banner"
        count = [0]
        msgs = [0]
        in_flight: list[int] = []
        lock = threading.Lock()
        done = threading.Event()

        def reader():
            buf = b""
            while not done.is_set():
                try:
                    chunk = port.read(port.in_waiting or 1)
                except Exception:
                    break
                if not chunk:
                    if not board.running:
                        break
                    continue
                buf += chunk
                while b"\n" in buf:
                    line, buf = buf.split(b"\n", 1)
                    if line.startswith((b"ok", b"error", b"rs")):
                        with lock:
                            count[0] += 1
                            if in_flight:
                                in_flight.pop(0)
                    elif line.startswith(b"msg:"):
                        msgs[0] += 1

        thread = threading.Thread(target=reader, daemon=True)
        thread.start()
        i = 0
        while board.running and i < len(lines):
            with lock:
                room = P.RX_BUFFER_BYTES - sum(in_flight)
                if len(lines[i]) <= room:
                    in_flight.append(len(lines[i]))
                    send = lines[i]
                    i += 1
                else:
                    send = None
            if send is None:
                time.sleep(0.0002)
                continue
            try:
                port.write(send)
            except Exception:
                break
        board.wait(timeout=seconds + 30)
        done.set()
        thread.join(timeout=2)
        port.close()
        edges = board.trace() if pins is not None else None
        return count[0], msgs[0], edges
    finally:
        board.close()


def encode_all(commands) -> list[bytes]:
    lines, seq = [], 0
    for cmd in commands:
        lines.append(P.encode_command(cmd, seq))
        seq = P.next_seq(seq)
    return lines


def lines_per_second(elf: Path, name: str, commands, t1: float, t2: float):
    lines = encode_all(commands)
    r1, m1, _ = stream_for(elf, lines, t1)
    r2, m2, _ = stream_for(elf, lines, t2)
    rate = (r2 - r1) / (t2 - t1)
    # the lines answered between the two durations (sequence numbers grow longer)
    avg = sum(map(len, lines[r1:r2])) / max(r2 - r1, 1)
    limit = WIRE_BYTES_PER_S / avg
    log(f"  {name}: {avg:.1f} bytes a line, {r1} replies in {t1} s, {r2} in {t2} s "
        f"-> {rate:.0f} lines/s; wire limit {limit:.0f} lines/s: {rate / limit:.1%} "
        f"(target >= {TARGET_WIRE_FRACTION:.0%}: {rate / limit / TARGET_WIRE_FRACTION:.2f}x)"
        f"; msg: lines {m2}")
    return rate / limit


def high_spans(edges, pin: int):
    cycle, pins, level = edges
    c, lv = cycle[pins == pin], level[pins == pin]
    rise = c[lv == 1]
    if not len(rise):
        return rise, rise
    fall = c[lv == 0]
    fall = fall[np.searchsorted(fall, rise[0]):]
    k = min(len(rise), len(fall))
    return rise[:k], fall[:k] - rise[:k]


def line_cycles(profile_elf: Path, name: str, commands, seconds: float) -> None:
    """Cycle-accurate main-loop cost per line (PROFILE=1: A1 line, A2 planner)."""
    lines = encode_all(commands)
    replies, msgs, edges = stream_for(profile_elf, lines, seconds, pins=[9, 11, 13, A1, A2])
    rise, line_high = high_spans(edges, A1)   # the k-th rise handles lines[k]
    _, plan_high = high_spans(edges, A2)
    skip = 3                                     # N0 F and the first moves
    line_high, plan_high, rise = line_high[skip:], plan_high[skip:], rise[skip:]
    avg = sum(map(len, lines[skip:skip + len(rise)])) / len(rise)
    wire = 1360 * avg
    gap = (rise[-1] - rise[0]) / (len(rise) - 1)   # mean, as avg is
    log(f"  {name}, cycle-accurate ({len(line_high)} lines, PROFILE=1 pin trace): main loop "
        f"per line median {np.median(line_high):.0f} / max {line_high.max()} cycles "
        f"(planner_execute {np.median(plan_high):.0f} / {plan_high.max()}), vs "
        f"{wire:.0f} cycles a line on the wire: {np.median(line_high) / wire:.0%} busy; "
        f"a line every {gap:.0f} cycles on average -> {F_CPU / gap:.0f} lines/s = "
        f"{wire / gap:.1%} of the wire limit; msg: lines {msgs}")


def move_ticks(config: MachineConfig, feed: int) -> int:
    """Reference ticks per `L 1 0` / `L 0 0` move, back to back, ramp included."""
    ref = simulate([SetFeed(feed)] + [LineTo(i % 2, 0) for i in range(1, 9)], config)
    return int(np.diff(ref.tick).max())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer feeds, shorter streams")
    args = ap.parse_args(argv)
    if not harness_available():
        sys.exit("build the harness first: make -C firmware/harness")
    stock = REPO / "firmware" / "build-uno" / "galileo.elf"
    subprocess.run(["make", "-C", str(REPO / "firmware")], check=True, capture_output=True)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="galileo-bench-") as tmp:
        elf, profile_elf, config = build_variant(Path(tmp))
        log(f"variant firmware built ({time.perf_counter() - t0:.1f} s): {VARIANT}")

        log("(a) step rate, variant config (trace == reference within 2 ticks, no msg:13)")
        rates_2 = [24000, 28000, 30000, 32000, 34000, 36000, 38000, 39000, 40000, 41000]
        rates_1 = [34000, 38000, 40000, 44000, 48000, 52000, 56000, 58823]
        if args.quick:
            rates_2, rates_1 = rates_2[::2], rates_1[::2]
        log(" two-axis (diagonal) lines:")
        best2 = sweep(elf, config, True, rates_2, 6000)
        log(" one-axis lines:")
        best1 = sweep(elf, config, False, rates_1, 8000)

        feed_2axis = 28000
        high, entry = isr_cycles(profile_elf, feed_2axis, 3000, diagonal=True)
        ex = exit_cycles(profile_elf)
        ent = int(np.median(entry)) if len(entry) else 0
        med, worst = int(np.median(high)), int(high.max())
        total_med = ENTRY_BEFORE_EDGE + ent + med + ex
        total_max = ENTRY_BEFORE_EDGE + ent + worst + ex
        high1, entry1 = isr_cycles(profile_elf, 30000, 3000, diagonal=False)
        total1 = ENTRY_BEFORE_EDGE + int(np.median(entry1)) + int(np.median(high1)) + ex
        log(f" ISR cycles per two-axis line event (PROFILE=1, {len(high)} events): entry "
            f"{ENTRY_BEFORE_EDGE}+{ent}, computation median {med} / max {worst}, exit {ex} "
            f"-> {total_med} median, {total_max} max")
        log(f" ISR cycles per one-axis line event: {total1} median")
        ceiling = F_CPU / total_max
        log(f" two-axis ceiling from the ISR cost: {F_CPU} / {total_max} = {ceiling:.0f} events/s")
        if best2:
            log(f" highest passing two-axis rate measured: {best2:.0f} events/s "
                f"(last sweep point {rates_2[-1]}; F_MAX = {config.max_feed_steps_per_s} "
                f"path steps/s); vs target {TARGET_2AXIS_HZ}: {best2 / TARGET_2AXIS_HZ:.2f}x, "
                f"vs GRBL 1.1h {GRBL_2AXIS_HZ}: {best2 / GRBL_2AXIS_HZ:.2f}x")
        if best1:
            log(f" highest passing one-axis rate measured: {best1:.0f} events/s")
        log(f" ceiling vs target {TARGET_2AXIS_HZ} Hz two-axis: {ceiling / TARGET_2AXIS_HZ:.2f}x; "
            f"vs GRBL 1.1h {GRBL_2AXIS_HZ} Hz: {ceiling / GRBL_2AXIS_HZ:.2f}x; cycles "
            f"{total_max} vs the 400-cycle budget of 40 kHz")

    log("(b) lines per second at 115200 baud (real-time simulation)")
    subprocess.run(["make", "-C", str(REPO / "firmware"), "PROFILE=1"], check=True,
                   capture_output=True)
    stock_profile = REPO / "firmware" / "build-uno-profile" / "galileo.elf"
    t1, t2 = (0.5, 1.0) if args.quick else (1.0, 2.0)
    moves = [SetFeed(STREAM_FEED)] + [LineTo(i % 2, 0) for i in range(4000)]
    avg = sum(map(len, encode_all(moves)[:800])) / 800
    ticks = move_ticks(MachineConfig(), STREAM_FEED)
    log(f"  F {STREAM_FEED}: a one-step move executes in {ticks} ticks = {ticks * 8} cycles "
        f"(reference, ramp included) vs {1360 * avg:.0f} cycles a line on the wire: "
        f"the queue never fills, the host never waits for it")
    name = f"short moves (L 1 0 / L 0 0 at F {STREAM_FEED})"
    lines_per_second(stock, name, moves, t1, t2)
    line_cycles(stock_profile, name, moves, t1)
    feeds = [SetFeed(1000 + i % 2) for i in range(4000)]
    lines_per_second(stock, "non-motion lines (F)", feeds, t1, t2)
    log(f"total {time.perf_counter() - t0:.0f} s wall")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
