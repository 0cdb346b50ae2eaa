"""Steps simulated per second: vectorised reference vs the per-step loop (same run).

    python bench/bench_machine.py [--moves 3000] [--loop-steps 400000]

The job is a long synthetic plot (random lines across the table at a high feed,
and full circles/arcs), planned once; both step generators run the same planned
moves. The per-step loop runs on a prefix of the job (it is ~40x slower) and its
rate is measured on that prefix; the outputs of the prefix are compared.
"""

from __future__ import annotations

import argparse
import random
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from galileo_cnc.config.machine import MachineConfig  # noqa: E402
from galileo_cnc.job import ArcTo, Jog, LineTo, SetFeed, SetOrigin  # noqa: E402
from galileo_cnc.machine import stepper as loop, vector  # noqa: E402
from galileo_cnc.machine.blocks import Pause  # noqa: E402
from galileo_cnc.machine.planner import ReferenceMachine  # noqa: E402


def long_job(moves: int, seed: int = 1):
    rng = random.Random(seed)
    cmds = [Jog(16000, 16000, 0), SetOrigin(), SetFeed(4000)]
    for _ in range(moves):
        if rng.random() < 0.8:
            cmds.append(LineTo(rng.randint(-15000, 15000), rng.randint(-15000, 15000)))
        else:
            cmds.append(LineTo(0, 0))
            cmds.append(ArcTo(rng.randint(-3000, 3000), rng.randint(-3000, 3000),
                              rng.randint(-3000, 3000), rng.randint(-3000, 3000), rng.random() < 0.5))
    return cmds


def prefix(items, max_events):
    out, events = [], 0
    for it in items:
        out.append(it)
        if not isinstance(it, Pause):
            events += it.n
            if events >= max_events:
                break
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--moves", type=int, default=3000)
    ap.add_argument("--loop-steps", type=int, default=400_000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)

    cmds = long_job(args.moves)
    machine = ReferenceMachine(MachineConfig())
    t = time.perf_counter()
    items = machine.plan(cmds)
    plan_s = time.perf_counter() - t

    best = float("inf")
    for _ in range(args.repeat):
        t = time.perf_counter()
        tick, axis, direction, end, _ab = vector.execute(items)
        best = min(best, time.perf_counter() - t)
    steps = len(tick)
    vec_rate = steps / (best + plan_s)

    part = prefix(items, args.loop_steps)
    t = time.perf_counter()
    ltick, laxis, ldir, _lend, _ = loop.execute(part)
    loop_s = time.perf_counter() - t
    loop_rate = len(ltick) / loop_s
    same = (np.array_equal(ltick, tick[:len(ltick)]) and np.array_equal(laxis, axis[:len(ltick)])
            and np.array_equal(ldir, direction[:len(ltick)]))

    print(f"job: {len(cmds)} commands, {len(items)} moves, {steps:,} steps, "
          f"{end / 2e6:,.0f} s of machine time")
    print(f"vectorised reference: {vec_rate / 1e6:6.1f} M steps/s "
          f"(plan {plan_s:.2f} s + step {best:.2f} s, best of {args.repeat})")
    print(f"per-step loop:        {loop_rate / 1e6:6.2f} M steps/s "
          f"({len(ltick):,} steps in {loop_s:.2f} s; traces equal: {same})")
    print(f"ratio vectorised / loop: {vec_rate / loop_rate:.0f}x   target >= 20 M steps/s: "
          f"{'met' if vec_rate >= 20e6 else 'NOT met'}")
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
