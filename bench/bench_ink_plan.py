"""Time the ink planner alone (read, then ink_program) on a few copper layers.

    python3 bench/bench_ink_plan.py                       # the biggest corpus layers
    python3 bench/bench_ink_plan.py FILE [FILE ...] --pens 0.3,0.8
    python3 bench/bench_ink_plan.py --stages              # and where the time goes

Prints, per file: read seconds, ink seconds (wall clock, and the CPU seconds of this
process and of the fill's forked helper, plan/ink/background.py: other work on the
machine inflates the wall clock, not the CPU seconds), rows of the
ink program, the share of the copper inked (exact geometry, not the steps:
bench_ink.py measures the steps), pen lifts, narrow features and bridges avoided.
`--stages` adds the CPU seconds of each stage (the planner's functions are wrapped
with timers for the run; nested stages are also counted in the stage around them).
`--digest` adds a hash of the ink program's rows: equal hashes before and after a
speed change mean the planner's output did not change, row for row. `--whole` times
the whole plan instead (`plan_file`: the ink, then path order, the steps and the
travel check, on a machine with 2 m of travel as bench_ink.py's), with its stages.
Numbers are printed, never asserted.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import time
from pathlib import Path

from galileo_cnc.plan import pipeline, planner
from galileo_cnc.plan.ink import clip, fill, inking
from galileo_cnc.plan.ink.inking import ink_program
from galileo_cnc.readers import read_file

CORPUS = Path(__file__).resolve().parents[2] / "shared" / "corpus" / "gerber"
BIGGEST = ["geda-pcb/hellboard/hellboard.group1.gbr", "altium/limesdr-qpcie/LimeSDR-QPCIe_1v2.GTL",
           "allegro/minnowmax-reva1/MinnowMax_lyr1_GAF.art", "eagle/pcb-tools-example/copper.GTL",
           "allegro/tracespace-371/l1_primary.art"]

#: (label, module, function name): the stages `--stages` times, outermost first.
STAGES = [
    ("ink (ink_program)", pipeline, "ink_program"),
    ("steps (plan_program)", pipeline, "plan_program"),
    ("  path order (plotting_order)", planner, "plotting_order"),
    ("  travel check (check_job)", planner, "check_job"),
    ("copper (dark_geometry)", inking, "dark_geometry"),
    ("fill (fill_region)", inking, "fill_region"),
    ("  fill: rings (_concentric)", fill, "_concentric"),
    ("  fill: gaps (_gaps)", fill, "_gaps"),
    ("  fill: joins and walks (_tours)", fill, "_tours"),
    ("narrow features (find_narrow)", inking, "find_narrow"),
    ("bridges (keep_islands_apart)", inking, "keep_islands_apart"),
    ("rows (_rows)", inking, "_rows"),
    ("  rows: arcs (fit_arcs)", inking, "fit_arcs"),
    ("  rows: arcs (fit_paths)", inking, "fit_paths"),
    ("all clip.offset", clip, "offset"),
    ("all clip.boolean", clip, "boolean"),
]


def timed_stages() -> dict[str, float]:
    """Wrap every function in STAGES with a CPU timer; the dict fills as they run."""
    spent: dict[str, float] = {}
    for label, module, name in STAGES:
        original = getattr(module, name, None)
        if original is None:
            continue

        def wrapper(*args, _original=original, _label=label, **kwargs):
            began = time.process_time()
            try:
                return _original(*args, **kwargs)
            finally:
                spent[_label] = spent.get(_label, 0.0) + time.process_time() - began

        setattr(module, name, wrapper)
    return spent


def children_cpu_s() -> float:
    """CPU seconds of the children that ended (the fill's forked gap tests)."""
    t = os.times()
    return t.children_user + t.children_system


def whole_plan(path: Path, pens: tuple[int, ...]):
    """plan_file in ink mode as bench_ink.py runs it; its InkPlan."""
    import dataclasses

    from galileo_cnc.config.machine import MachineConfig
    from galileo_cnc.plan.pipeline import PlanOptions, plan_file

    config = dataclasses.replace(MachineConfig(), x_travel_mm=2000.0, y_travel_mm=2000.0)
    return plan_file(path, config, "auto", options=PlanOptions(mode="ink", pens_nm=pens)).ink


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="*", help="Gerber files (default: the biggest layers)")
    parser.add_argument("--pens", default="0.3", help="pen widths in mm, e.g. 0.3,0.8")
    parser.add_argument("--stages", action="store_true", help="CPU seconds per stage")
    parser.add_argument("--digest", action="store_true", help="hash of the ink program's rows")
    parser.add_argument("--whole", action="store_true",
                        help="time the whole plan (plan_file), not the ink alone")
    args = parser.parse_args()
    pens = tuple(round(float(w) * 1_000_000) for w in args.pens.split(","))
    files = [Path(f) for f in args.files] or [CORPUS / f for f in BIGGEST]
    spent = timed_stages() if args.stages else {}
    for path in files:
        began = time.perf_counter()
        program = read_file(path)
        read_s = time.perf_counter() - began
        spent.clear()
        wall, cpu, children = time.perf_counter(), time.process_time(), children_cpu_s()
        if args.whole:
            plan = whole_plan(path, pens)
        else:
            plan = ink_program(program, pens)
        _ = plan.inked_nm2          # plot prints it before streaming: part of the wait
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        children = children_cpu_s() - children
        share = 100 * plan.inked_nm2 / plan.copper_nm2 if plan.copper_nm2 else 100.0
        print(f"{path.name}: read {read_s:.2f} s, {'whole plan' if args.whole else 'ink'} "
              f"{wall:.2f} s wall, {cpu:.2f} s CPU (+ {children:.2f} s in its forked helper), "
              f"{len(plan.program)} rows, {share:.2f} % inked, "
              f"{plan.pen_lifts} pen lifts, {len(plan.narrow)} narrow, "
              f"{len(plan.bridges)} bridges avoided", flush=True)
        if args.digest:
            rows = plan.program.table.astype("<i8", copy=False).tobytes()
            print(f"    rows sha1 {hashlib.sha1(rows).hexdigest()}", flush=True)
        for label, _module, _name in STAGES:
            if label in spent:
                print(f"    {label:34s} {spent[label]:6.2f} s CPU "
                      f"{100 * spent[label] / cpu if cpu else 0:5.1f} %", flush=True)


if __name__ == "__main__":
    main()
