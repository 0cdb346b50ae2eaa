"""Lines per second streamed to stock GRBL 1.1h in simavr: character counting
against plain send-response and against the wire limit, in the same run.

The job is N short G1 moves (chords of a circle, so GRBL's junctions barely slow
it) at a feed whose motion outruns any stream: the time from the first step
pulse to the last, in simulated cycles from the pin trace, is how fast the
lines arrived and were planned. The board runs paced to the wall clock
(--max-speed 1), so the host's latency costs what it costs on a real Uno.

    python3 bench/bench_grbl.py                 # 600 lines, both ways
    python3 bench/bench_grbl.py --lines 300 --feed 6000
    python3 bench/bench_grbl.py --estimate-only # the time estimate on a corpus board

The time estimate (grbl/estimate.py, a model of GRBL's planner) is compared with
GRBL in simavr, first step to last step from the pins, on a corpus board
streamed as the tests stream it (tests/grbl: 160 steps/mm, $12=0.0005).

The wire limit is 115200 baud 8N1: 11 765 bytes/s (docs/harness.md), divided by
the mean bytes of a line (its text and "\\n"). GRBL's own ceiling is what character
counting reaches when the wire is not the limit: its parser and planner per line.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import serial

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from galileo_cnc.grbl import firmware  # noqa: E402
from galileo_cnc.grbl.estimate import Machine, estimate  # noqa: E402
from galileo_cnc.grbl.gcode import GcodeLine  # noqa: E402
from galileo_cnc.grbl.link import GrblLink  # noqa: E402
from galileo_cnc.grbl.stream import stream  # noqa: E402

F_CPU = 16_000_000
WIRE_BYTES_PER_S = F_CPU / 1360           # one 8N1 frame at "115200" is 1360 cycles
SETTINGS = {100: "160", 101: "160", 102: "160", 110: "12000", 111: "12000",
            120: "3000", 121: "3000", 11: "0.02"}


def job_lines(count: int, feed: int) -> list[GcodeLine]:
    radius = 40.0
    lines = [GcodeLine(f"G1 X{radius:.3f} Y0 F{feed}", 0)]
    for k in range(1, count):
        a = 2 * math.pi * k / count
        lines.append(GcodeLine(f"G1 X{radius * math.cos(a):.3f} Y{radius * math.sin(a):.3f}", k))
    return lines


def run(lines: list[GcodeLine], character_counting: bool, speed: float = 1.0) -> dict:
    board = firmware.grbl_board(extra_args=("--max-speed", str(speed)))
    with board:
        port = serial.Serial(board.port, 115200, timeout=0.2)
        link = GrblLink.connect(port)
        for number, value in SETTINGS.items():
            link.command_checked(f"${number}={value}")
        start = time.monotonic()
        if character_counting:
            result = stream(link, lines, wait_idle=False)
            assert not result.errors
        else:
            for line in lines:
                link.command_checked(line.text)
        wall_s = time.monotonic() - start
        link.wait_idle()
        port.close()
        board.stop()
    cycle, pin, level = board.trace()
    steps = cycle[(level == 1) & ((pin == 2) | (pin == 3))]
    seconds = (int(steps[-1]) - int(steps[0])) / F_CPU
    return {"lines_per_s": (len(lines) - 1) / seconds, "sim_s": seconds, "wall_s": wall_s,
            "overruns": board.summary.get("overruns")}


def estimate_vs_simavr(board_path: str) -> None:
    """Estimate against GRBL in simavr on one corpus board (centre mode)."""
    sys.path[:0] = [str(Path(__file__).resolve().parents[1] / "tests" / d) for d in ("", "grbl")]
    from corpus import CORPUS
    from grbl_support import CONFIG, SCALE, grbl_machine

    from galileo_cnc.grbl.gcode import job_to_gcode, pen_from_config
    from galileo_cnc.plan.pipeline import PlanOptions, plan_file
    planned = plan_file(CORPUS / board_path, CONFIG, options=PlanOptions(mode="centre"))
    lines = job_to_gcode(planned.job, SCALE, pen_from_config(CONFIG),
                         feed_steps_per_s=CONFIG.feed_steps_per_s,
                         flash_dwell_ms=CONFIG.flash_dwell_ms)
    with grbl_machine() as (board, link):
        model = estimate(lines, Machine.from_settings(link.settings, link.build.planner_blocks))
        result = stream(link, lines)
        board.stop()
    assert not result.errors
    cycle, pin, level = board.trace()
    steps = cycle[(level == 1) & (pin <= 4)]
    sim = (int(steps[-1]) - int(steps[0])) / F_CPU
    print(f"{board_path}: {len(lines)} lines, {model.blocks} blocks, {model.stops} stops; "
          f"estimate {model.motion_span_s:.3f} s, simavr {sim:.3f} s, "
          f"ratio {model.motion_span_s / sim:.3f}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lines", type=int, default=600)
    parser.add_argument("--feed", type=int, default=9000, help="mm/min")
    parser.add_argument("--board", default="kicad/flashpads-nox2noap/Flashpads-B_Cu.gbr",
                        help="corpus board for the time estimate")
    parser.add_argument("--estimate-only", action="store_true")
    args = parser.parse_args()
    if args.estimate_only:
        estimate_vs_simavr(args.board)
        return 0
    lines = job_lines(args.lines, args.feed)
    mean_bytes = sum(len(line.text) + 1 for line in lines) / len(lines)
    wire = WIRE_BYTES_PER_S / mean_bytes
    chord_mm = 2 * 40.0 * math.sin(math.pi / args.lines)
    motion = args.feed / 60 / chord_mm
    print(f"{args.lines} lines of {mean_bytes:.1f} bytes, chords {chord_mm:.3f} mm at "
          f"F{args.feed}: motion alone allows {motion:.0f} lines/s; wire limit {wire:.0f} lines/s")
    counted = run(lines, True)
    plain = run(lines, False)
    # the AVR at a quarter of real time: the host's latency shrinks 4x in
    # simulated time, so what remains is GRBL's own parsing and planning
    ceiling = run(lines, True, speed=0.25)
    for name, r in (("character counting", counted), ("send-response", plain),
                    ("GRBL's ceiling", ceiling)):
        print(f"{name:>19}: {r['lines_per_s']:6.0f} lines/s = {r['lines_per_s'] / wire:6.1%} of "
              f"the wire limit  ({r['sim_s']:.3f} s simulated, overruns={r['overruns']})")
    print(f"character counting / send-response: {counted['lines_per_s'] / plain['lines_per_s']:.2f}x;"
          f" / GRBL's ceiling: {counted['lines_per_s'] / ceiling['lines_per_s']:.1%}")
    estimate_vs_simavr(args.board)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
