"""A real board streamed by our host to the firmware in simavr: does the queue stay full?

    python bench/bench_stream.py [CORPUS_PATH]   (default: an arc-heavy KiCad paste layer)

Plans a corpus file with the proposed offset, streams it with `JobStreamer` over a
pseudo-terminal to the firmware running in simavr, and compares the firmware's step
trace with the reference's: the steps must be equal, and between the planned stops
(pen changes) every edge must keep one offset to the reference tick, within the
firmware's 2-tick latency bound. A larger spread means the host or the firmware's
per-move set-up let the queue run dry. Prints machine time against wall time (simavr
runs the AVR faster than real time) and the worst spread.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

import numpy as np  # noqa: E402

from corpus import CORPUS  # noqa: E402
from firmware_support import ELF  # noqa: E402
from galileo_cnc.job import ArcTo
from galileo_cnc.machine import simulate  # noqa: E402
from galileo_cnc.plan.offsets import proposed_offset  # noqa: E402
from galileo_cnc.plan.planner import plan_program  # noqa: E402
from galileo_cnc.readers import read_file  # noqa: E402
from galileo_cnc.simavr.board import SimulatedBoard, step_trace  # noqa: E402
from galileo_cnc.stream.streamer import JobStreamer  # noqa: E402
from galileo_cnc.transport.link import MachineLink  # noqa: E402

DEFAULT = "kicad/flashpads-nox2noap/Flashpads-F_Paste.gbr"
LATENCY_JITTER_TICKS = 2


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("path", nargs="?", default=DEFAULT, help="file in the shared corpus")
    args = parser.parse_args(argv)
    if not ELF.exists():
        print("build the firmware and the harness first: make -C firmware && "
              "make -C firmware/harness", file=sys.stderr)
        return 2
    program = read_file(CORPUS / args.path)
    job = plan_program(program, None, proposed_offset(program))
    ref = simulate(job.commands)
    arcs = sum(isinstance(c, ArcTo) for c in job.commands)
    print(f"{args.path}: {len(job)} commands ({arcs} arcs), {len(ref)} steps, "
          f"{ref.seconds:.0f} s of machine time")
    began = time.monotonic()
    with SimulatedBoard(ELF) as board:
        link = MachineLink.open(board.port)
        messages: list[str] = []
        link.on_message = messages.append
        result = JobStreamer(link, job, program).run()
        link.close()
        board.stop()
        tick, axis, direction = step_trace(board.trace())
    wall = time.monotonic() - began
    same = (len(tick) == len(ref) and np.array_equal(axis, ref.axis)
            and np.array_equal(direction, ref.dir))
    cuts = sorted({0, len(ref)} | {len(simulate(job.commands[:k])) for k in job.pen_changes})
    worst = 0
    if same:
        delay = tick - ref.tick
        for lo, hi in zip(cuts, cuts[1:]):
            if hi > lo:
                worst = max(worst, int(delay[lo:hi].max() - delay[lo:hi].min()))
    print(f"completed {result.completed}, machine messages {messages[:3] or 'none'}")
    print(f"simavr ran {ref.seconds:.0f} s of machine time in {wall:.0f} s of wall time "
          f"({ref.seconds / wall:.1f}x real time)")
    print(f"steps equal to the reference: {same}; worst spread between pen changes: "
          f"{worst} ticks ({'queue kept full' if same and worst <= LATENCY_JITTER_TICKS else 'GAPS'})")
    return 0 if same and worst <= LATENCY_JITTER_TICKS else 1


if __name__ == "__main__":
    raise SystemExit(main())
